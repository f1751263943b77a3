"""The game-engine and Twister clients against the real app (in process)."""

from __future__ import annotations

import argparse
import asyncio
import json
from pathlib import Path

import httpx
import pytest

from clients.game_engine import main, run, summary
from clients.http import GeckoClient
from clients.twister import Game, describe, parse, play

pytestmark = pytest.mark.anyio


async def test_game_engine_plan(client: httpx.AsyncClient) -> None:
    args = argparse.Namespace(
        command="plan",
        character="humanoid",
        scene="flat",
        start=[0.0, 0.0, 0.0],
        goal=[0.6, 0.0, 0.0],
        seed=4,
        budget=20.0,
    )
    answer = await run(args, client)
    assert answer["seed"] == 4
    assert answer["status"] in {"SOLVED", "APPROXIMATE"}
    line = summary("plan", answer)
    assert line.startswith(f"plan: {answer['status']}") and "keyframes" in line


def test_twister_prompt_parsing() -> None:
    assert parse("create lf_foot 3") == {"kind": "create", "limb": "lf_foot", "surface": 3}
    assert parse("break rh_foot") == {"kind": "break", "limb": "rh_foot"}
    assert parse("auto") == {"kind": "auto"}
    assert parse("undo") == "undo"
    assert parse("") == "help"


async def test_twister_game_session(client: httpx.AsyncClient) -> None:
    game = Game(GeckoClient(client), "quadruped", "twister", seed=11)
    lines = iter(["break lf_foot", "create lf_foot", "state", "undo", "quit"])
    said: list[str] = []
    await play(game, lambda: next(lines), said.append, [0.0, 0.0, 0.0])
    assert said[0].startswith("ok: break lf_foot"), said
    assert said[1].startswith("ok: create lf_foot"), said
    assert "after 1 moves" in said[2] or "after 2 moves" in said[2]
    assert "lf_foot" not in said[3]
    assert describe({"status": "INFEASIBLE", "failure": {"reason": "R", "message": "m"}}, game)


def test_game_engine_saves_json_and_glb(gecko_url: str, tmp_path: Path) -> None:
    out, glb = tmp_path / "walk.json", tmp_path / "walk.glb"
    code = main(
        [
            "plan", "--url", gecko_url, "--character", "humanoid", "--scene", "flat",
            "--start", "0,0,0", "--goal", "0.5,0,0", "--seed", "1",
            "--out", str(out), "--glb", str(glb),
        ]
    )  # fmt: skip
    assert code == 0
    answer = json.loads(out.read_text())
    data = glb.read_bytes()
    assert data[:4] == b"glTF" and len(data) > 1000
    again = asyncio.run(_glb(gecko_url, answer["id"]))
    assert again == data, "the client's GLB is the stored result's"


async def _glb(url: str, rid: str) -> bytes:
    async with httpx.AsyncClient(base_url=url) as http:
        return await GeckoClient(http).result_glb("plan", rid)
