"""Game-engine client: ask for a walk/climb plan or a jump sequence and save the answer.

Usage::

    python -m clients.game_engine plan --character humanoid --scene flat \\
        --start 0,0,0 --goal 1.5,0,0 --out walk.json
    python -m clients.game_engine jump --character quadruped --scene gaps \\
        --start 0.75,0,0.6 --goal 8.25,0,1.0 --out jumps.json --glb jumps.glb

``--start`` and ``--goal`` are points on the scene to stand at. The saved JSON is the
service's answer (phases, COM Bezier segments, keyframes); ``--glb`` also saves the motion
as glTF 2.0 binary (y up, metres: the character's links as nodes, one animation;
``--with-scene`` adds the scene mesh). A summary and the viewer's link are printed.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import httpx

from clients.http import GeckoClient, GeckoError


def _point(text: str) -> list[float]:
    values = [float(v) for v in text.split(",")]
    if len(values) != 3:
        raise argparse.ArgumentTypeError("a point is x,y,z")
    return values


def build_request(args: argparse.Namespace) -> dict[str, Any]:
    """The JSON request of a ``plan`` or ``jump`` command."""
    request: dict[str, Any] = {
        "character": args.character,
        "scene": args.scene,
        "start": {"stand_at": args.start},
        "goal": {"stand_at": args.goal},
        "time_budget_s": args.budget,
    }
    if args.seed is not None:
        request["seed"] = args.seed
    return request


def summary(kind: str, answer: dict[str, Any]) -> str:
    """One line about an answer: status, seed, sizes, duration."""
    frames = answer.get("keyframes", [])
    duration = frames[-1]["t"] if frames else 0.0
    parts = [f"{kind}: {answer['status']}", f"seed {answer['seed']}"]
    if kind == "plan":
        parts.append(f"{len(answer['phases'])} phases")
    else:
        parts.append(f"{len(answer['jumps'])} jumps")
    parts += [f"{len(frames)} keyframes", f"{duration:.2f} s of motion"]
    if answer.get("message"):
        parts.append(answer["message"])
    return ", ".join(parts)


async def run(args: argparse.Namespace, http: httpx.AsyncClient) -> dict[str, Any]:
    """Send the request and return the answer."""
    client = GeckoClient(http)
    request = build_request(args)
    if args.command == "plan":
        return await client.plan(request, timeout=args.budget * 2 + 30)
    return await client.jumps(request, timeout=args.budget * 2 + 30)


async def fetch_glb(
    http: httpx.AsyncClient, command: str, answer: dict[str, Any], *, with_scene: bool
) -> bytes:
    """The answer's motion as GLB (from the service's stored result)."""
    kind = "plan" if command == "plan" else "jump"
    return await GeckoClient(http).result_glb(kind, answer["id"], scene=with_scene)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", choices=["plan", "jump"])
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    parser.add_argument("--character", required=True)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--start", type=_point, required=True)
    parser.add_argument("--goal", type=_point, required=True)
    parser.add_argument("--seed", type=int)
    parser.add_argument("--budget", type=float, default=10.0, help="seconds, at most 60")
    parser.add_argument("--out", type=Path, help="write the answer's JSON here")
    parser.add_argument("--glb", type=Path, help="write the motion as glTF 2.0 binary here")
    parser.add_argument("--with-scene", action="store_true", help="put the scene in the GLB")
    args = parser.parse_args(argv)

    async def go() -> tuple[dict[str, Any], bytes | None]:
        async with httpx.AsyncClient(base_url=args.url) as http:
            answer = await run(args, http)
            glb = None
            if args.glb and answer.get("keyframes"):
                glb = await fetch_glb(http, args.command, answer, with_scene=args.with_scene)
            return answer, glb

    try:
        answer, glb = asyncio.run(go())
    except (GeckoError, httpx.HTTPError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.out:
        args.out.write_text(json.dumps(answer))
    print(summary(args.command, answer))
    if args.glb:
        if glb is None:
            print("no keyframes: no GLB written", file=sys.stderr)
        else:
            args.glb.write_bytes(glb)
            print(f"GLB: {args.glb} ({len(glb)} bytes)")
    if answer.get("id"):
        kind = "plan" if args.command == "plan" else "jump"
        print(f"view: {args.url.rstrip('/')}/viewer?{kind}={answer['id']}")
    return 0 if answer["status"] in ("SOLVED", "APPROXIMATE") else 1


if __name__ == "__main__":
    raise SystemExit(main())
