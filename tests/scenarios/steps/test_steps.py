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
from pathlib import Path

import numpy as np
import pytest

from planner.character import get_character
from planner.contact.context import ContactContext, make_context
from planner.contact.one_step import StepAction, StepResult, twister_step
from planner.contact.standing import standing_state
from planner.contact.state import ContactState
from planner.offline import load_offline_data
from planner.scene import load_builtin_scene
from tests.paths import gecko_cache_dir
from tests.planner.contact.step_checks import assert_valid_step

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


@pytest.mark.parametrize("name", sorted(SPECS))
def test_every_step_succeeds_with_its_invariants(name: str) -> None:
    ctx, start, results = _played(name)
    assert len(results) == len(SPECS[name]["actions"])
    before = start
    for action, r in zip(SPECS[name]["actions"], results, strict=True):
        assert r.ok, (action, r.failure)
        assert r.limb == action["limb"]
        assert (r.state.contact(action["limb"]) is not None) == (action["kind"] == "create")
        assert_valid_step(ctx, before, r)
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
