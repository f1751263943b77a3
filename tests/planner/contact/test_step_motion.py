"""The motion of one contact change: phases, COM segments and keyframes."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin

from planner.contact.checks import (
    check_state,
    com_of,
    hold_error,
    obstacle_normal,
    scene_collisions,
    within_limits,
)
from planner.contact.generation import break_contact, create_contact
from planner.contact.step_motion import step_motion
from planner.motion import tuning
from planner.motion.sequence import Timing
from planner.poses import pose_matrix
from planner.shapes import Box
from tests.planner.contact.twister_game import context, start_state

FEET = {"left_foot": (0.175, 0.175), "right_foot": (0.175, -0.175)}


def test_break_then_create_motion() -> None:
    ctx = context("humanoid", "twister")
    state = start_state(ctx, (0.175, 0.0), FEET)
    released = break_contact(ctx, state, "right_foot")
    assert released.ok
    placed = create_contact(ctx, released.state, "right_foot", rng=np.random.default_rng(2))
    assert placed.ok
    for before, after, swing_phase in (
        (state, released.state, 1),
        (released.state, placed.state, 0),
    ):
        motion = step_motion(ctx, before, after, "right_foot")
        p0, p1 = motion.phases
        assert p0.t0 == 0.0 and p0.t1 == p1.t0 and p1.t1 > p1.t0
        assert p0.contacts == before.contacts and p1.contacts == after.contacts
        swing = motion.phases[swing_phase].t1 - motion.phases[swing_phase].t0
        assert swing >= tuning.DYNAMIC_MIN_SWING_S - 1e-9
        segs = motion.com
        assert segs[0].t0 == 0.0 and abs(segs[-1].t1 - p1.t1) < 1e-9
        for a, b in itertools.pairwise(segs):
            assert abs(a.t1 - b.t0) < 1e-9
            np.testing.assert_allclose(a.control_points[-1], b.control_points[0], atol=1e-9)
        times = np.array([k.t for k in motion.keyframes])
        gaps = np.diff(times)  # an even grid at about the rate, never a sliver
        np.testing.assert_allclose(gaps, gaps[0], atol=1e-9)
        assert 0.5 / 30 <= gaps[0] <= 1.5 / 30
        np.testing.assert_array_equal(motion.keyframes[0].q, before.q)
        np.testing.assert_array_equal(motion.keyframes[-1].q, after.q)
        for k in motion.keyframes:
            phase = p0 if k.t < p0.t1 else p1
            assert hold_error(ctx, k.q, phase.contacts) <= 0.01
            assert within_limits(ctx, k.q)
        assert motion.report["colliding_keyframes"] == 0
        assert all(r["fraction_valid"] >= 0.0 for r in motion.report["phases"])
        faster = step_motion(ctx, before, after, "right_foot", rate=60.0)
        assert len(faster.keyframes) > 1.7 * len(motion.keyframes)


def test_transition_point_moves_off_an_obstacle() -> None:
    """2PAC 7.2: a block just in front of the head where the COM shift takes it is avoided by
    moving the transition point along the obstacle normal (back), the contacts unchanged."""
    ctx = context("humanoid", "twister")
    state = start_state(ctx, (0.175, 0.0), FEET)
    released = break_contact(ctx, state, "right_foot").state
    geometry = ctx.character.geometry
    head = [o.name for o in geometry.geometryObjects].index("head_0")
    pin.updateGeometryPlacements(ctx.model, ctx.pin_data, geometry, ctx.geom_data, released.q)
    centre = np.array(ctx.geom_data.oMg[head].translation)
    front = centre[0] + geometry.geometryObjects[head].geometry.radius - 0.01  # 1 cm into it
    block = (
        Box(np.array([0.05, 0.05, 0.05])),
        pose_matrix(centre + np.array([front - centre[0] + 0.05, 0.0, 0.0])),
    )
    blocked = ctx.with_obstacles([block])
    assert not scene_collisions(blocked, state.q, contacts=state.contacts)
    assert scene_collisions(blocked, released.q, contacts=released.contacts) == ["head_0"]
    normal = obstacle_normal(blocked, released.q, released.contacts)
    assert normal is not None and normal[0] < -0.9

    motion = step_motion(blocked, state, released, "right_foot")
    assert motion.report["colliding_keyframes"] == 0
    assert motion.report["transition_shift"] > 0.0
    assert motion.state.contacts == released.contacts
    assert check_state(blocked, motion.state).valid
    assert com_of(ctx, motion.state.q)[0] < com_of(ctx, released.q)[0] - 0.02
    np.testing.assert_array_equal(motion.keyframes[-1].q, motion.state.q)
    for k in motion.keyframes:
        phase = motion.phases[0] if k.t < motion.phases[0].t1 else motion.phases[1]
        assert hold_error(ctx, k.q, phase.contacts) <= 0.01


def test_step_timing_follows_the_speed_and_the_users_attractor() -> None:
    """A step is timed like a plan's brisk phases: the swing gets its distance at the swing
    speed (at least the shortest swing), ``speed`` divides the durations, the COM passes
    Eq. 1 where it is checked, and an attractor for transition 0 is honoured when balanced
    and reachable, refused with a reason otherwise."""
    ctx = context("humanoid", "twister")
    state = start_state(ctx, (0.175, 0.0), FEET)
    released = break_contact(ctx, state, "right_foot")
    assert released.ok
    placed = create_contact(ctx, released.state, "right_foot", rng=np.random.default_rng(2))
    assert placed.ok
    before, after = released.state, placed.state
    nominal = step_motion(ctx, before, after, "right_foot")
    fast = step_motion(ctx, before, after, "right_foot", timing=Timing(speed=2.0))
    swing = nominal.phases[0].t1 - nominal.phases[0].t0
    assert swing >= tuning.DYNAMIC_MIN_SWING_S - 1e-9
    fast_swing = fast.phases[0].t1 - fast.phases[0].t0
    assert fast_swing < swing and fast_swing >= tuning.DYNAMIC_MIN_SWING_S / 2.0 - 1e-9
    assert nominal.report["com_method"] == "rest_to_rest" and fast.report["speed"] == 2.0
    for motion in (nominal, fast):
        assert motion.report["colliding_keyframes"] == 0
        assert all(r["fraction_valid"] == 1.0 for r in motion.report["phases"])
    # the COM a little toward the standing foot is balanced on it and reachable for both
    c0, c1 = com_of(ctx, before.q), com_of(ctx, after.q)
    inside = 0.7 * c1 + 0.3 * c0
    honoured = step_motion(
        ctx, before, after, "right_foot", timing=Timing(attractors=((0, inside),))
    )
    assert honoured.report["attractors"] == [{"transition": 0, "honoured": True}]
    at_change = honoured.phases[0].t1
    curve_end = next(s for s in honoured.com if abs(s.t1 - at_change) < 1e-9)
    np.testing.assert_allclose(curve_end.control_points[-1], inside, atol=1e-9)
    far = c1 + np.array([0.0, -0.5, 0.0])  # over the lifted foot's side: not balanced
    refused = step_motion(ctx, before, after, "right_foot", timing=Timing(attractors=((0, far),)))
    (entry,) = refused.report["attractors"]
    assert entry["honoured"] is False and "equilibrium" in str(entry["reason"])
    np.testing.assert_allclose(
        next(s for s in refused.com if abs(s.t1 - refused.phases[0].t1) < 1e-9).control_points[-1],
        c1,
        atol=1e-9,
    )
    wrong = step_motion(ctx, before, after, "right_foot", timing=Timing(attractors=((1, c1),)))
    assert "0 to 0" in str(wrong.report["attractors"][0]["reason"])
