"""Scripted one-step (Twister-mode) sequences from the JSON files of this folder.

Each file names a character, a scene, where it stands (``stand_at``, facing ``yaw``) and a
list of actions (create or break a limb's contact, near a ``target``). Every step must
succeed with the invariants of the one-step mode: a valid state one contact away, keyframes
holding the stance within 1 cm and inside the joint limits, the COM curve inside the
kinematic polytopes, no colliding keyframe, a quasi-static transition; the same seed gives
the same states.
"""

from __future__ import annotations

import json
from functools import cache
from math import comb
from pathlib import Path

import numpy as np
import pytest

from planner.character import get_character
from planner.contact.checks import (
    check_state,
    hold_error,
    kinematics_of,
    scene_collisions,
    self_collides,
    within_limits,
)
from planner.contact.context import ContactContext, make_context
from planner.contact.one_step import StepAction, StepResult, twister_step
from planner.contact.standing import standing_state
from planner.contact.state import ContactState
from planner.offline import load_offline_data
from planner.scene import load_builtin_scene
from tests.paths import gecko_cache_dir

HERE = Path(__file__).parent
SPECS = {p.stem: json.loads(p.read_text()) for p in sorted(HERE.glob("*.json"))}


@cache
def _played(name: str) -> tuple[ContactContext, ContactState, tuple[StepResult, ...]]:
    spec = SPECS[name]
    scene = load_builtin_scene(spec["scene"], gecko_cache_dir())
    character = get_character(spec["character"])
    data = load_offline_data(character, gecko_cache_dir())
    rng = np.random.default_rng(int(spec["seed"]))
    standing = standing_state(
        scene, character, data, np.asarray(spec["stand_at"]), rng=rng, yaw=float(spec["yaw"])
    )
    assert standing.value is not None, standing.message
    ctx = make_context(scene, character, data)
    state = standing.value
    results = []
    for action in spec["actions"]:
        target = action.get("target")
        step = StepAction(
            action["kind"], action["limb"], None, None if target is None else np.asarray(target)
        )
        result = twister_step(ctx, state, step, rng=rng)
        results.append(result)
        if not result.ok:
            break
        state = result.state
    return ctx, standing.value, tuple(results)


def _com_at(result: StepResult, t: float) -> np.ndarray:
    for seg in result.com:
        if seg.t0 - 1e-9 <= t <= seg.t1 + 1e-9:
            s = (t - seg.t0) / (seg.t1 - seg.t0)
            n = len(seg.control_points) - 1
            w = np.array([comb(n, k) * s**k * (1 - s) ** (n - k) for k in range(n + 1)])
            return np.asarray(w @ seg.control_points)
    raise AssertionError(f"no COM segment at t={t}")


@pytest.mark.parametrize("name", sorted(SPECS))
def test_every_step_succeeds_with_its_invariants(name: str) -> None:
    ctx, start, results = _played(name)
    assert len(results) == len(SPECS[name]["actions"])
    before = start
    for action, r in zip(SPECS[name]["actions"], results, strict=True):
        assert r.ok, (action, r.failure)
        assert r.limb == action["limb"]
        assert (r.state.contact(action["limb"]) is not None) == (action["kind"] == "create")
        assert check_state(ctx, r.state).valid
        assert r.state.differs_by_one(before)
        np.testing.assert_array_equal(r.keyframes[0].q, before.q)
        np.testing.assert_array_equal(r.keyframes[-1].q, r.state.q)
        for kf in r.keyframes:
            phase = r.phases[0] if kf.t < r.phases[0].t1 else r.phases[1]
            assert hold_error(ctx, kf.q, phase.contacts) <= 0.01
            assert within_limits(ctx, kf.q)
        for phase in r.phases:
            kin = kinematics_of(ctx, phase.contacts)
            for t in np.linspace(phase.t0, phase.t1, 7):
                assert kin.violation(_com_at(r, float(t))) <= 1e-3
        assert r.report["colliding_keyframes"] == 0
        assert r.report["quasi_static_feasible"]
        for kf in r.keyframes[1:-1]:
            phase = r.phases[0] if kf.t < r.phases[0].t1 else r.phases[1]
            assert not scene_collisions(ctx, kf.q, contacts=phase.contacts)
            assert not self_collides(ctx, kf.q)
        before = r.state


def _seat_surface(ctx: ContactContext) -> int:
    """The chair's seat: the support surface whose top is 0.45 m high."""
    return next(s.id for s in ctx.scene.surfaces if abs(float(s.centroid[2]) - 0.45) < 1e-3)


def test_sitting_rests_on_the_seat_and_standing_up_leaves_it() -> None:
    ctx, start, results = _played("chair_humanoid")
    sitting = results[SPECS["chair_humanoid"]["sitting_after"] - 1].state
    seat = _seat_surface(ctx)
    for limb in ("left_seat", "right_seat"):
        contact = sitting.contact(limb)
        assert contact is not None and contact.surface == seat
    feet = [c for c in sitting.contacts if c.limb.endswith("_foot")]
    assert len(feet) == 2  # both feet stay on the floor
    assert sitting.q[2] < start.q[2] - 0.3  # the pelvis came down onto the seat
    standing = results[-1].state
    assert sorted(standing.limbs) == sorted(start.limbs)
    assert standing.q[2] > start.q[2] - 0.45


def test_same_seed_same_steps() -> None:
    first = _played.__wrapped__("chair_humanoid")  # type: ignore[attr-defined]
    again = _played("chair_humanoid")
    for a, b in zip(first[2], again[2], strict=True):
        np.testing.assert_array_equal(a.state.q, b.state.q)
