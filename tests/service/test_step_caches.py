"""A planning process keeps what it computed for one Twister step for the next (issue 15:
polytopes of contact sets, surfaces' boundary segments and footprints, the reachability
checker's sub-worlds, a character's tracker terms, idle pin.Data): the same request gives
the same answer whatever ran before it, caches cold or warm."""

from __future__ import annotations

import json
import threading
import time
from collections import OrderedDict
from typing import Any

import pytest

from planner.character import collision as character_collision
from planner.character import get_character
from planner.contact import context, reachability, standing
from planner.kinematics import borrowed_data, borrowed_geometry_data
from planner.kinematics import model as kinematics_model
from planner.motion import clearance, tracker
from planner.scene import affordance
from service import compute

FAR_CAP_S = 600.0  # s: a cap no step reaches (the clock never decides these answers)

FIRST = {
    "character": "quadruped",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "break", "limb": "lf_foot"},
    "seed": 3,
}
OTHER = {
    "character": "hexapod",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "auto"},
    "seed": 5,
}


def _answer(request: dict[str, Any]) -> dict[str, Any]:
    body = compute.run_twister_step(
        json.dumps(request), int(request["seed"]), deadline=time.monotonic() + FAR_CAP_S
    )
    return {k: v for k, v in body.items() if k != "timings"}


def _cold(monkeypatch: pytest.MonkeyPatch) -> None:
    """Empty every per-process cache the Twister step fills."""
    monkeypatch.setattr(context, "_SHARED", OrderedDict())
    monkeypatch.setattr(kinematics_model, "_POOL", threading.local())
    monkeypatch.setattr(reachability, "_SUB_WORLDS", OrderedDict())
    monkeypatch.setattr(standing, "_FOOTPRINTS", {})
    monkeypatch.setattr(affordance, "_SEGMENTS", {})
    monkeypatch.setattr(affordance, "_LOOP_EDGES", {})
    monkeypatch.setattr(tracker, "_TERMS", {})
    monkeypatch.setattr(clearance, "_PAIR_SHAPES", {})
    monkeypatch.setattr(clearance, "_PAIR_LISTS", {})
    monkeypatch.setattr(character_collision, "_BOUNDS", {})


@pytest.mark.usefixtures("in_process_worker")
def test_same_answers_in_either_order(monkeypatch: pytest.MonkeyPatch) -> None:
    _cold(monkeypatch)
    first = _answer(FIRST)
    assert first["status"] == "SOLVED", first["failure"]
    follow = {
        "character": "quadruped",
        "scene": "twister",
        "state": first["state"],
        "action": {"kind": "auto"},
        "seed": 7,
    }
    requests = [FIRST, OTHER, follow]
    forward = [first, _answer(OTHER), _answer(follow)]  # caches warm from the first on
    _cold(monkeypatch)
    backward = [_answer(r) for r in reversed(requests)]  # the follow-up now runs cold
    for ahead, behind in zip(forward, reversed(backward), strict=True):
        assert ahead == behind
    assert all(a["status"] == "SOLVED" for a in forward), [a["failure"] for a in forward]


def test_borrowed_data_is_the_blocks_alone() -> None:
    """Nested borrows get distinct pin.Data; one given back is lent again."""
    model = get_character("quadruped").model
    with borrowed_data(model) as outer:
        with borrowed_data(model) as inner:
            assert inner is not outer
        with borrowed_data(model) as again:
            assert again is inner


def test_borrowed_geometry_data_is_the_blocks_alone() -> None:
    """Nested borrows get distinct pin.GeometryData, distance requests signed; one given
    back is lent again."""
    geometry = get_character("quadruped").motion_geometry
    with borrowed_geometry_data(geometry) as outer:
        with borrowed_geometry_data(geometry) as inner:
            assert inner is not outer
        with borrowed_geometry_data(geometry) as again:
            assert again is inner
    assert all(r.enable_signed_distance for r in again.distanceRequests)


def test_shared_memory_drops_the_least_recently_used(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past its size the process-wide memory drops its least recently used value, not all
    of them: a value asked for again stays, the oldest other one is made anew."""
    monkeypatch.setattr(context, "_SHARED", OrderedDict())
    monkeypatch.setattr(context, "_SHARED_SIZE", 3)
    character = get_character("quadruped")
    ctx = context.ContactContext.__new__(context.ContactContext)
    object.__setattr__(ctx, "character", character)
    object.__setattr__(ctx, "data", object())
    made: list[str] = []

    def value(key: str) -> str:
        return str(ctx.shared(key, lambda: made.append(key) or key))

    for key in ("a", "b", "c"):
        value(key)
    value("a")  # used again: now the most recent
    value("d")  # past the size: "b" goes
    for key in ("a", "c", "d"):
        value(key)
    assert made == ["a", "b", "c", "d"]
    value("b")
    assert made == ["a", "b", "c", "d", "b"]
