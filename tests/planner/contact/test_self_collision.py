"""A contact state's self-collision is judged on the shapes the keyframe checker tests: the
URDF's own collision shapes (Talos: convex hulls of its meshes), not only the planner's
capsules, within ``STATE_SELF_PENETRATION``."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.contact.body import self_collides
from planner.motion import tuning
from tests.planner.contact.contact_helpers import character_and_data


@cache
def _talos() -> Any:
    return character_and_data("talos")[0]


def _knees_in(roll: float, bend: float) -> np.ndarray:
    """Talos's reference posture with both hips rolled ``roll`` rad inward and the knees
    bent ``bend`` rad (hips and ankles compensating)."""
    character = _talos()
    model = character.model
    q = np.array(character.q_ref)
    for side, sign in (("left", -1.0), ("right", 1.0)):

        def at(joint: int, side: str = side) -> int:
            return int(model.joints[model.getJointId(f"leg_{side}_{joint}_joint")].idx_q)

        q[at(2)] = sign * roll
        q[at(3)] -= 0.5 * bend
        q[at(4)] += bend
        q[at(5)] -= 0.5 * bend
    return q


def _hull_depth(q: np.ndarray) -> float:
    """m, the deepest overlap of two URDF collision shapes of a declared pair (signed
    distances from coal, computed here pair by pair)."""
    character = _talos()
    model, geometry = character.model, character.motion_geometry
    data, geometry_data = model.createData(), pin.GeometryData(geometry)
    for request in geometry_data.distanceRequests:
        request.enable_signed_distance = True
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, geometry, geometry_data)
    deepest = 0.0
    for k in range(len(geometry.collisionPairs)):
        pin.computeDistance(geometry, geometry_data, k)
        deepest = max(deepest, -float(geometry_data.distanceResults[k].min_distance))
    return deepest


def _capsules_touch(q: np.ndarray) -> bool:
    character = _talos()
    model = character.model
    return bool(
        pin.computeCollisions(
            model,
            model.createData(),
            character.geometry,
            pin.GeometryData(character.geometry),
            q,
            True,
        )
    )


def _judged(q: np.ndarray) -> bool:
    character = _talos()
    return self_collides(
        character, q, character.model.createData(), pin.GeometryData(character.geometry)
    )


@settings(max_examples=25, deadline=None)
@given(roll=st.floats(0.0, 0.05), bend=st.floats(0.0, 1.2))
def test_a_state_self_collides_when_capsules_touch_or_hulls_overlap(
    roll: float, bend: float
) -> None:
    q = _knees_in(roll, bend)
    depth = _hull_depth(q)
    if abs(depth - tuning.STATE_SELF_PENETRATION) < 2e-4:
        return  # on the threshold itself the two computations may round differently
    expected = _capsules_touch(q) or depth > tuning.STATE_SELF_PENETRATION
    assert _judged(q) is expected


def test_overlapping_hulls_decide_where_the_capsules_are_apart() -> None:
    """Knees rolled 25 mrad inward: the capsules are apart and the knee hulls overlap by
    about 4 mm, which the keyframe checker would call a collision-in-waiting."""
    q = _knees_in(0.025, 0.0)
    assert not _capsules_touch(q)
    assert _hull_depth(q) > tuning.STATE_SELF_PENETRATION
    assert _judged(q)
    assert not _judged(_knees_in(0.0, 0.0))


def _every_pair_judged(q: np.ndarray) -> bool:
    """The judgement with every declared pair of the URDF shapes tested (no broad phase)."""
    character = _talos()
    model, geometry = character.model, character.motion_geometry
    data, geometry_data = model.createData(), pin.GeometryData(geometry)
    for request in geometry_data.collisionRequests:
        request.security_margin = -tuning.STATE_SELF_PENETRATION
    pin.updateGeometryPlacements(model, data, geometry, geometry_data, q)
    return _capsules_touch(q) or bool(pin.computeCollisions(geometry, geometry_data, True))


def test_the_pairs_left_out_never_change_a_judgement() -> None:
    """Only the pairs whose bounding capsules overlap are tested, and the broad phase
    remembers the gaps of earlier queries: over postures that drift joint by joint and
    jump across the joint ranges, in colliding and free postures alike, every judgement is
    the one of every pair tested."""
    character = _talos()
    model = character.model
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    rng = np.random.default_rng(3)
    q = np.array(character.q_ref)
    judged = []
    for step in range(80):
        if step % 20 == 19:  # a jump anywhere in the ranges
            q[7:] = rng.uniform(lower, upper)
        else:
            q[7:] = np.clip(q[7:] + rng.normal(0.0, 0.08, q.size - 7), lower, upper)
        expected = _every_pair_judged(q)
        assert _judged(q) is expected
        judged.append(expected)
    assert any(judged) and not all(judged)
