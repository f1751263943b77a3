"""The one motion builder on motions made to fail: a COM driven into the floor, a posture
that would fold the body. Constraints hold whatever the tasks ask: joint speeds within
limits, no shape sinking into the scene, stance contacts held."""

from __future__ import annotations

import itertools

import numpy as np

from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.kinematics import com_position
from planner.motion import tuning
from planner.motion.builder import build_motion
from planner.motion.spec import MotionPhase, MotionSpec
from planner.motion.tracker import speed_limits
from tests.planner.contact.contact_helpers import character_and_data, scene
from trajectory import BezierCurve, PiecewiseBezier


def _squat_spec(drop: float, duration: float) -> tuple[object, MotionSpec]:
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    q = np.array(character.q_ref)
    feet = tuple(make_contact(ctx, name, q, 0) for name in ("left_foot", "right_foot"))
    c0 = com_position(character.model, q)
    c1 = c0 - np.array([0.0, 0.0, drop])
    curve = PiecewiseBezier((BezierCurve(np.stack([c0, c0, c0, c1, c1, c1]), 0.0, duration),))
    phase = MotionPhase(0.0, duration, feet, q)
    return ctx, MotionSpec(q, (phase,), curve, 30.0)


def test_a_com_driven_into_the_floor_stops_at_the_floor() -> None:
    ctx, spec = _squat_spec(drop=0.9, duration=1.0)
    motion = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    report = motion.report
    assert report.phases_animated == 1 and not report.cut_short
    assert report.worst_scene_depth <= tuning.PENETRATION_TOLERANCE
    assert report.worst_self_depth <= tuning.SELF_PENETRATION_TOLERANCE
    assert report.max_hold_error <= tuning.HOLD_TOLERANCE
    assert report.com_error_max > 0.2  # the floor, not the COM curve, had the last word


def test_joint_speeds_stay_within_their_limits() -> None:
    ctx, spec = _squat_spec(drop=0.4, duration=0.3)  # far faster than the legs may move
    model = ctx.character.model  # type: ignore[attr-defined]
    motion = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    limits = speed_limits(model)[6:]
    keys = motion.keyframes
    for a, b in itertools.pairwise(keys):
        speed = np.abs(b.q[7:] - a.q[7:]) / (b.t - a.t)
        assert np.all(speed <= limits * (1.0 + 1e-6))
    assert np.all(limits <= tuning.MAX_JOINT_SPEED)


def test_the_same_spec_gives_the_same_keyframes() -> None:
    ctx, spec = _squat_spec(drop=0.2, duration=0.5)
    a = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    b = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    assert [k.t for k in a.keyframes] == [k.t for k in b.keyframes]
    assert all(np.array_equal(x.q, y.q) for x, y in zip(a.keyframes, b.keyframes, strict=True))
