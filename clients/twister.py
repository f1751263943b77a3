"""Interactive Twister client: make or break one contact at a time, from the terminal.

Usage::

    python -m clients.twister --character humanoid --scene twister --stand-at 0,0,0

Commands at the prompt: ``create LIMB [SURFACE]``, ``break LIMB``, ``auto``, ``limbs``,
``state``, ``undo``, ``quit``. Each move prints whether it succeeded, why not otherwise, and
the limbs now in contact. ``--moves N`` plays N random moves without a prompt instead.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from collections.abc import Callable, Sequence
from typing import Any

import httpx

from clients.http import GeckoClient, GeckoError


class Game:
    """The Twister game state on the client side: the history of states, one per move."""

    def __init__(self, client: GeckoClient, character: str, scene: str, seed: int) -> None:
        self.client = client
        self.character = character
        self.scene = scene
        self.seed = seed
        self.history: list[dict[str, Any]] = []

    @property
    def state(self) -> dict[str, Any] | None:
        return self.history[-1] if self.history else None

    def contacts(self) -> list[str]:
        return [c["limb"] for c in self.state["contacts"]] if self.state else []

    async def move(
        self, action: dict[str, Any], stand_at: list[float] | None = None
    ) -> dict[str, Any]:
        """Play one move; on success the new state joins the history."""
        request: dict[str, Any] = {
            "character": self.character,
            "scene": self.scene,
            "action": action,
            "seed": self.seed + len(self.history),
        }
        if self.state is None:
            request["stand_at"] = stand_at or [0.0, 0.0, 0.0]
        else:
            request["state"] = self.state
        answer = await self.client.twister_step(request)
        if answer["status"] == "SOLVED" or self.state is None:
            # a failed first move still returns the standing state to start from
            self.history.append(answer["state"])
        return answer


def parse(line: str) -> dict[str, Any] | str:
    """A prompt line as a move action, or a meta command name."""
    words = line.split()
    if not words:
        return "help"
    head = words[0].lower()
    if head in ("create", "break") and len(words) >= 2:
        action: dict[str, Any] = {"kind": head, "limb": words[1]}
        if head == "create" and len(words) >= 3:
            action["surface"] = int(words[2])
        return action
    if head == "auto":
        return {"kind": "auto"}
    return head


def describe(answer: dict[str, Any], game: Game) -> str:
    if answer["status"] == "SOLVED":
        report = answer.get("report", {})
        return f"ok: {report.get('action')} {report.get('limb')}; contacts {game.contacts()}"
    failure = answer.get("failure") or {}
    return f"no: {failure.get('reason')} ({failure.get('message')}); contacts {game.contacts()}"


async def play(
    game: Game,
    lines: Callable[[], str],
    say: Callable[[str], None],
    stand_at: list[float],
) -> None:
    """The prompt loop: read commands until ``quit`` or end of input."""
    while True:
        try:
            line = lines()
        except EOFError:
            return
        command = parse(line)
        if command == "quit":
            return
        if command == "limbs":
            detail = await game.client.character(game.character)
            say(", ".join(limb["name"] for limb in detail["limbs"]))
        elif command == "state":
            say(f"contacts {game.contacts()} after {max(0, len(game.history) - 1)} moves")
        elif command == "undo":
            if len(game.history) > 1:
                game.history.pop()
            say(f"contacts {game.contacts()}")
        elif isinstance(command, dict):
            try:
                say(describe(await game.move(command, stand_at), game))
            except GeckoError as exc:
                say(f"error: {exc}")
        else:
            say(__doc__.split("Commands at the prompt: ")[1].split(".")[0])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    parser.add_argument("--character", default="humanoid")
    parser.add_argument("--scene", default="twister")
    parser.add_argument("--stand-at", default="0,0,0")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--moves", type=int, help="play this many random moves (at most 1000)")
    args = parser.parse_args(argv)
    stand_at = [float(v) for v in args.stand_at.split(",")]
    if args.moves is not None and not 0 < args.moves <= 1000:
        parser.error("--moves must be in [1, 1000]")

    async def go() -> None:
        async with httpx.AsyncClient(base_url=args.url) as http:
            game = Game(GeckoClient(http), args.character, args.scene, args.seed)
            if args.moves is not None:
                script = iter(["auto"] * args.moves)
                await play(game, lambda: next(script, "quit"), print, stand_at)
            else:
                await play(game, lambda: input("twister> "), print, stand_at)

    try:
        asyncio.run(go())
    except (httpx.HTTPError, GeckoError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
