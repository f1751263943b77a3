"""Shared helpers for the contact tests: contexts and Twister games from scenario files."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from planner.character import get_character
from planner.contact.generation import (
    ContactContext,
    ContactParams,
    character_obstacles,
    make_context,
    stand_state,
)
from planner.contact.one_step import StepAction, StepResult, twister_step
from planner.contact.state import ContactState
from planner.offline import load_offline_data
from planner.scene import Scene, load_builtin_scene
from planner.termination import Termination, never
from tests.paths import REPO_ROOT, gecko_cache_dir

SCENARIOS = REPO_ROOT / "tests" / "scenarios" / "twister"


@cache
def scene(scene_id: str) -> Scene:
    return load_builtin_scene(scene_id, gecko_cache_dir())


def discs(sc: Scene) -> dict[tuple[float, float], int]:
    """Twister disc surface ids by rounded (x, y) centre (every support but the ground)."""
    big = max(sc.surfaces, key=lambda s: s.area).id
    return {
        (round(float(s.centroid[0]), 3), round(float(s.centroid[1]), 3)): s.id
        for s in sc.surfaces
        if s.id != big
    }


def context(
    character_id: str, scene_id: str, twister: bool = True, **params: Any
) -> ContactContext:
    sc = scene(scene_id)
    ch = get_character(character_id)
    data = load_offline_data(ch, gecko_cache_dir())
    allowed = tuple(discs(sc).values()) if twister else None
    return make_context(sc, ch, data, ContactParams(allowed_surfaces=allowed, **params))


def start_state(ctx: ContactContext, root_xy: Any, contacts: dict[str, Any]) -> ContactState:
    table = discs(ctx.scene)
    q0 = np.array(ctx.character.q_ref)
    q0[:2] = root_xy
    surfaces = {limb: table[(round(xy[0], 3), round(xy[1], 3))] for limb, xy in contacts.items()}
    attempt = stand_state(ctx, q0, surfaces)
    assert attempt.ok, attempt.message
    return attempt.state


def _params(raw: dict[str, Any]) -> dict[str, Any]:
    """ContactParams overrides from a scenario (lists become tuples)."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in raw.items()}


@dataclass
class Move:
    player: int
    ctx: ContactContext  # with the other players as obstacles
    before: ContactState
    result: StepResult


def play(path: Path, cap: Termination = never) -> list[Move]:
    """The game of a scenario file, every move 'auto' (``cap``: each move's clock cap)."""
    spec = json.loads(path.read_text())
    ctxs = [
        context(p["character"], spec["scene"], **_params(p.get("params", {})))
        for p in spec["players"]
    ]
    states = [
        start_state(c, p["root_xy"], p["contacts"])
        for c, p in zip(ctxs, spec["players"], strict=True)
    ]
    rng = np.random.default_rng(spec["seed"])
    moves = []
    for m in range(spec["moves"]):
        i = m % len(ctxs)
        obstacles = [
            o
            for j in range(len(ctxs))
            if j != i
            for o in character_obstacles(ctxs[j].character, states[j].q)
        ]
        ctx = ctxs[i].with_obstacles(obstacles) if obstacles else ctxs[i]
        result = twister_step(ctx, states[i], StepAction("auto"), rng=rng, cap=cap)
        moves.append(Move(i, ctx, states[i], result))
        if result.ok:
            states[i] = result.state
    return moves
