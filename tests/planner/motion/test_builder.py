"""The one motion builder on motions made to fail: a COM driven into the floor, a posture
that would fold the body. Constraints hold whatever the tasks ask: joint speeds within
limits, no shape sinking into the scene, stance contacts held."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner.contact.body import contact_placement
from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.contact.state import ContactState
from planner.kinematics import com_position
from planner.motion import builder, tuning
from planner.motion.builder import build_motion
from planner.motion.checker import KeyframeChecker
from planner.motion.jump import JumpLeg, build_jumps
from planner.motion.spec import MotionPhase, MotionSpec, Swing
from planner.motion.tracker import WholeBodyTracker, speed_limits
from planner.scene.builtin import STAIRS_RISE
from planner.termination import never
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


def test_a_motion_with_an_end_configuration_ends_exactly_there() -> None:
    """``q_end``: the last keyframe is that configuration, bit for bit; the blend into it is
    checked like every keyframe and holds the stance (a squat ending crouched)."""
    ctx, spec = _squat_spec(drop=0.1, duration=1.0)
    model = ctx.character.model  # type: ignore[attr-defined]
    tracked = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    character = ctx.character  # type: ignore[attr-defined]
    legs = np.concatenate([character.limb(x).idx_q for x in ("left_foot", "right_foot")])
    free = np.setdiff1d(np.arange(7, model.nq), legs)
    end = np.array(tracked.end)
    end[free] = 0.5 * (
        end[free]
        + np.clip(end[free] + 0.3, model.lowerPositionLimit[free], model.upperPositionLimit[free])
    )  # arms and torso elsewhere
    motion = build_motion(
        ctx.character,  # type: ignore[attr-defined]
        ctx.scene.collision.bvh,  # type: ignore[attr-defined]
        dataclasses.replace(spec, q_end=end),
    )
    np.testing.assert_array_equal(motion.keyframes[-1].q, end)
    np.testing.assert_array_equal(motion.end, end)
    assert motion.report.colliding_keyframes == 0
    assert motion.report.max_hold_error <= 0.01  # the blend of two held postures
    early = [k for k in motion.keyframes if k.t < 1.0 - tuning.END_BLEND_S - 1e-9]
    for a, b in zip(early, tracked.keyframes, strict=False):
        np.testing.assert_array_equal(a.q, b.q)  # only the last END_BLEND_S seconds change


def test_the_root_moves_no_faster_than_its_bound() -> None:
    """A COM asked to dart 0.4 m sideways in 0.2 s (2 m/s): outside jumps the root moves at
    most ``ROOT_LINEAR_SPEED`` along each axis of its own frame, so the COM lags its curve
    instead of the pelvis being thrown."""
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    q = np.array(character.q_ref)
    feet = tuple(make_contact(ctx, name, q, 0) for name in ("left_foot", "right_foot"))
    c0 = com_position(character.model, q)
    c1 = c0 + np.array([0.0, 0.4, 0.0])
    curve = PiecewiseBezier((BezierCurve(np.stack([c0, c0, c1, c1]), 0.0, 0.2),))
    spec = MotionSpec(q, (MotionPhase(0.0, 0.2, feet, q),), curve, 30.0)
    motion = build_motion(character, ctx.scene.collision.bvh, spec)
    model = character.model
    fastest = max(
        float(np.abs(np.asarray(pin.difference(model, a.q, b.q))[:3]).max()) / (b.t - a.t)
        for a, b in itertools.pairwise(motion.keyframes)
    )  # along an axis of the root's frame, m/s
    assert fastest <= tuning.ROOT_LINEAR_SPEED * 1.02
    assert fastest >= tuning.ROOT_LINEAR_SPEED * 0.95  # the bound, not the tasks, decided
    assert motion.report.com_error_max > 0.1  # the COM lagged its curve
    free = speed_limits(model)
    bounded = speed_limits(model, root_bounded=True)
    assert np.all(np.isinf(free[:6])) and np.all(np.isfinite(bounded[:6]))
    np.testing.assert_array_equal(free[6:], bounded[6:])


def _slipping_spec(offset: float) -> tuple[object, MotionSpec]:
    """Three squatting phases; from the second on, the right foot's contact lies ``offset``
    m beside the foot (a contact the body cannot hold without sliding its foot)."""
    ctx, spec = _squat_spec(drop=0.05, duration=0.9)
    first = spec.phases[0]
    moved = first.stance[1].placement.copy()
    moved[1, 3] -= offset
    shifted = (first.stance[0], dataclasses.replace(first.stance[1], placement=moved))
    phases = (
        dataclasses.replace(first, t1=0.3),
        dataclasses.replace(first, t0=0.3, t1=0.6, stance=shifted),
        dataclasses.replace(first, t0=0.6, t1=0.9, stance=shifted),
    )
    return ctx, dataclasses.replace(spec, phases=phases)


def test_a_trial_build_is_abandoned_at_its_first_unclean_phase() -> None:
    """``abandon_unclean``: the build stops after the first phase a caller would refuse
    (here a contact it cannot hold), says so, and costs no more keyframes; without it every
    phase is animated and the slip is reported."""
    ctx, spec = _slipping_spec(offset=0.3)
    bvh = ctx.scene.collision.bvh  # type: ignore[attr-defined]
    whole = build_motion(ctx.character, bvh, spec)  # type: ignore[attr-defined]
    assert whole.report.phases_animated == 3 and not whole.report.abandoned
    assert whole.report.max_hold_error > tuning.HOLD_TOLERANCE
    trial = build_motion(ctx.character, bvh, spec, abandon_unclean=True)  # type: ignore[attr-defined]
    assert trial.report.abandoned and not trial.report.cut_short
    assert trial.report.phases_animated == 1 and trial.report.abandoned_phase == 1
    assert trial.keyframes[-1].t <= 0.6 + 1e-9
    shortfall = trial.report.shortfall()
    assert shortfall is not None and "abandoned" in shortfall and "slips" in shortfall
    clean = build_motion(ctx.character, bvh, _squat_spec(0.05, 0.9)[1], abandon_unclean=True)  # type: ignore[attr-defined]
    assert not clean.report.abandoned and clean.report.complete


def test_a_build_resumed_from_an_earlier_one_keeps_its_keyframes_and_goes_on() -> None:
    """``resume=(earlier, 2)``: the earlier build's keyframes before phase 2 are kept bit for
    bit (checks and COM errors with them), and tracking goes on from the last of them as the
    whole build did (the same spec gives the same keyframes after it)."""
    ctx, spec = _slipping_spec(offset=0.0)
    bvh = ctx.scene.collision.bvh  # type: ignore[attr-defined]
    whole = build_motion(ctx.character, bvh, spec)  # type: ignore[attr-defined]
    resumed = build_motion(ctx.character, bvh, spec, resume=(whole, 2))  # type: ignore[attr-defined]
    kept = [k for k in whole.keyframes if k.t < 0.6 - 1e-9]
    assert len(kept) >= 10
    for a, b in zip(kept, resumed.keyframes, strict=False):
        assert a.t == b.t and np.array_equal(a.q, b.q)
    assert resumed.checks[: len(kept)] == whole.checks[: len(kept)]
    assert len(resumed.keyframes) == len(whole.keyframes)
    for a, b in zip(whole.keyframes, resumed.keyframes, strict=True):
        assert abs(a.t - b.t) < 1e-9
        np.testing.assert_allclose(a.q, b.q, atol=1e-6)
    assert resumed.report.complete and resumed.report.phases_animated == 3


def test_a_flight_that_turns_keeps_the_legs_apart() -> None:
    """A jump whose landing faces 150 degrees away from its takeoff: the carried feet's
    offsets from the COM turn with the trunk (``MotionPhase.turn_from``), so the legs do not
    sweep through each other mid-flight (blending the offsets in the world frame brings
    both feet to the middle at once)."""
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    model = character.model
    q0 = np.array(character.q_ref)
    yaw = np.deg2rad(150.0)
    q1 = q0.copy()
    q1[:2] += [0.6, 0.0]
    q1[3:7] = [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)]
    feet = ("left_foot", "right_foot")
    stances = [
        ContactState(q, tuple(make_contact(ctx, name, q, 0) for name in feet)) for q in (q0, q1)
    ]
    c0, c1 = com_position(model, q0), com_position(model, q1)
    duration, g = 0.5, 9.81
    v0 = (c1 - c0 - 0.5 * np.array([0.0, 0.0, -g]) * duration**2) / duration
    leg = JumpLeg(c0, v0, duration, g, np.zeros(3), 1.0, np.zeros(3), 1.0)
    motion, (timing,) = build_jumps(character, ctx.scene.collision.bvh, stances, [leg])
    assert motion.report.worst_self_depth <= tuning.SELF_PENETRATION_TOLERANCE
    data_ = model.createData()
    left, right = (character.limb(name).frame_id for name in feet)
    gaps = []
    for key in motion.keyframes:
        if timing.takeoff < key.t < timing.touchdown:
            pin.framesForwardKinematics(model, data_, key.q)
            gaps.append(np.linalg.norm(data_.oMf[left].translation - data_.oMf[right].translation))
    assert len(gaps) >= 10
    assert min(gaps) > 0.1  # about the stance width all along; world blending gives ~0.02


def test_a_foot_stepping_down_beside_a_riser_crosses_low() -> None:
    """The box-shaped swing path (the builder's last resort after its arcs) of a humanoid's
    foot stepping down two treads, landing 1 cm from the riser of the tread between: its
    descent passes that tread's nosing as close at every top (the dampers' margin along the
    normal), so the crossing is as low as it can be, not the highest (which folded the leg
    to its joint limits and leaned the chest 58 degrees)."""
    character, _ = character_and_data("humanoid")
    stairs = scene("stairs")
    q = np.array(character.q_ref)

    def foot(yaw: float, position: list[float]) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("z", yaw).as_matrix()
        pose[:3, 3] = position
        return pose

    # measured on the stairs scene: from the landing at 0.9 m down to the 0.6 m tread, the
    # other foot on the 0.75 m tread between
    swing = Swing(
        "left_foot",
        foot(3.1301, [2.729, -0.105, 0.901]),
        foot(-3.0630, [2.077, -0.116, 0.601]),
        0.08,
    )
    c0 = com_position(character.model, q)
    curve = PiecewiseBezier((BezierCurve(np.stack([c0, c0]), 0.0, 0.6),))
    spec = MotionSpec(q, (MotionPhase(0.0, 0.6, (), q, swing=swing),), curve, 30.0)
    checker = KeyframeChecker(character, stairs.collision.bvh)
    top = builder._clearing_top(builder._Targets(character, spec), checker, 0)
    assert top == tuning.CLEARING_HEIGHTS[0]


def test_a_swing_is_at_fault_when_its_limb_is_in_the_scene_or_in_another_body_part() -> None:
    """A higher arc is tried when the swinging limb's shape is the deepest in the scene, or
    is one of the deepest self-colliding pair (a foot brushing the stance foot); not when the
    collision is between other parts, nor below the tolerances."""
    from planner.motion.checker import KeyframeCheck

    feet = frozenset({"r_foot_0", "r_shin_0"})
    deep = tuning.SELF_PENETRATION_TOLERANCE + 0.002

    def segment(*checks: KeyframeCheck) -> builder._Segment:
        return builder._Segment([], list(checks), [], np.zeros(1), 0.0)

    brushing = KeyframeCheck(0.0, None, deep, 0.0, ("l_foot_0", "r_foot_0"))
    elsewhere = KeyframeCheck(0.0, None, deep, 0.0, ("r_thigh_0", "r_hand_0"))
    shallow = KeyframeCheck(0.0, None, 0.001, 0.0, ("l_foot_0", "r_foot_0"))
    scraping = KeyframeCheck(tuning.PENETRATION_TOLERANCE + 0.002, "r_shin_0", 0.0, 0.0)
    assert builder._swing_at_fault(segment(brushing), feet)
    assert builder._swing_at_fault(segment(scraping), feet)
    assert not builder._swing_at_fault(segment(elsewhere), feet)
    assert not builder._swing_at_fault(segment(shallow), feet)
    assert not builder._swing_at_fault(segment(), feet)


def _step_up_spec(end_x: float, rise: float) -> tuple[object, MotionSpec]:
    """A humanoid standing on the floor 0.3 m before the stairs' first riser (x = 1 m) on
    its right foot, its left foot swinging along a flat path (lift 0) to ``end_x`` m, ``rise``
    m up, in 0.8 s; the COM still."""
    character, data = character_and_data("humanoid")
    stairs = scene("stairs")
    ctx = make_context(stairs, character, data)
    q = np.array(character.q_ref)
    q[0] = 0.7
    floor = next(
        i
        for i, s in enumerate(stairs.surfaces)
        if s.normal[2] > 0.99 and bool(s.contains_projection(np.array([[0.7, 0.1, 0.0]]))[0])
    )
    right = make_contact(ctx, "right_foot", q, floor)
    start = contact_placement(character, "left_foot", q, ctx.pin_data)
    end = start.copy()
    end[0, 3], end[2, 3] = end_x, start[2, 3] + rise
    c0 = com_position(character.model, q)
    curve = PiecewiseBezier((BezierCurve(np.stack([c0, c0]), 0.0, 0.8),))
    swing = Swing("left_foot", start, end, 0.0)
    return ctx, MotionSpec(q, (MotionPhase(0.0, 0.8, (right,), q, swing=swing),), curve, 30.0)


def _tracking(ctx: object, spec: MotionSpec) -> tuple[object, object, object, list[float]]:
    character = ctx.character  # type: ignore[attr-defined]
    bvh = ctx.scene.collision.bvh  # type: ignore[attr-defined]
    tracker = WholeBodyTracker(character, bvh)
    checker = KeyframeChecker(character, bvh, (), tracker)
    targets = builder._Targets(character, spec)
    times = builder.phase_keyframe_times(0.0, 0.8, spec.rate, targets.break_list).tolist()
    return tracker, checker, targets, times


def test_a_swing_attempt_that_will_be_retried_stops_where_its_limb_collides() -> None:
    """A foot stepping up onto the first tread along a flat path runs into the riser: tracked
    with ``stop_at`` (the foot's shapes) the attempt stops at the first keyframe the foot
    collides in, the keyframes before it clean, instead of tracking the whole phase it will
    be tried again for; the build then keeps a higher arc that comes clean, tracked whole."""
    ctx, spec = _step_up_spec(1.12, STAIRS_RISE)
    tracker, checker, targets, times = _tracking(ctx, spec)
    shapes = frozenset({"l_foot_0"})
    q = np.array(spec.q_start)
    stopped = builder._track_segment(tracker, checker, targets, q, times, None, never, shapes)  # type: ignore[arg-type]
    assert stopped.stopped and 1 < len(stopped.keyframes) < len(times)
    assert builder._collides_at(stopped.checks[-1], shapes)
    assert not any(c.colliding for c in stopped.checks[:-1])
    tracker.reset()  # type: ignore[attr-defined]
    whole = builder._track_segment(tracker, checker, targets, q, times, None, never)  # type: ignore[arg-type]
    assert not whole.stopped and len(whole.keyframes) == len(times)
    assert whole.score[0] >= 1  # the whole attempt collides too: it would be retried
    built = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    assert built.report.complete and built.report.swings_raised >= 1
    assert built.swing_lifts[0] > 0.0
    assert len(built.keyframes) == len(times)


def test_when_no_swing_attempt_comes_clean_the_stopped_ones_are_tracked_whole() -> None:
    """A foot landing with its toe in the first riser collides on every attempt: the ones
    stopped early are tracked again whole (unless what they collided in already rules them
    out), the best of all is kept (here the last, the unguarded arc, which collides the
    least), every keyframe of the phase there, and the report says the motion collides and
    how many times the swing was raised."""
    ctx, spec = _step_up_spec(0.98, 0.0)
    calls: list[tuple[bool, int]] = []
    real = builder._track_segment

    def counting(*args: object, **kwargs: object) -> builder._Segment:
        segment = real(*args, **kwargs)  # type: ignore[arg-type]
        calls.append((segment.stopped, len(segment.keyframes)))
        return segment

    with pytest.MonkeyPatch.context() as patched:
        patched.setattr(builder, "_track_segment", counting)
        built = build_motion(ctx.character, ctx.scene.collision.bvh, spec)  # type: ignore[attr-defined]
    attempts = len(tuning.SWING_LIFTS) + 3  # lift 0, the lifts, clearing path, unguarded
    assert built.report.swings_raised == attempts - 1
    stopped = [n for n, (was_stopped, _) in enumerate(calls) if was_stopped]
    assert stopped and attempts < len(calls) <= attempts + len(stopped)
    assert all(not was_stopped for was_stopped, _ in calls[attempts:])  # tracked whole
    assert not built.report.complete and built.report.colliding_keyframes > 0
    whole = {count for _, count in calls[attempts - 1 :]}
    assert whole == {len(built.keyframes)}


@given(
    keyframes=st.integers(min_value=1, max_value=2000),
    calm=st.floats(min_value=0.0, max_value=tuning.TRIAL_COM_TOLERANCE),
    lag=st.floats(min_value=tuning.TRIAL_COM_TOLERANCE, max_value=1.0, exclude_min=True),
)
def test_the_lagging_keyframes_a_plan_may_have_keep_its_99th_percentile_within_bounds(
    keyframes: int, calm: float, lag: float
) -> None:
    """``lagging_allowed``: that many keyframes lagging (by any amount), the rest within
    ``TRIAL_COM_TOLERANCE``, leave the plan's 99th percentile lag within it."""
    allowed = builder.lagging_allowed(keyframes)
    lags = np.full(keyframes, calm)
    lags[:allowed] = lag
    assert np.percentile(lags, 99) <= tuning.TRIAL_COM_TOLERANCE
    assert allowed >= (keyframes - 1) // 100  # a 1 % budget, not less


def test_a_short_phase_lagging_once_is_refused_only_past_the_plans_budget() -> None:
    """A phase of four keyframes, one lagging 21 mm (a quarter of them, over
    ``TRIAL_COM_LAG_SHARE``): refused when the plan has no lagging keyframe left to spend,
    played when it has one; a lag beyond ``TRIAL_COM_MAX_LAG`` is refused whatever is left,
    and a calm phase always plays."""
    q = np.zeros(3)
    lagging = builder._Segment([], [], [0.005, 0.004, 0.021, 0.006], q, 0.0)
    assert builder._unclean(lagging, None, lag_budget=0) is not None
    assert builder._unclean(lagging, None, lag_budget=1) is None
    far = builder._Segment([], [], [0.005, tuning.TRIAL_COM_MAX_LAG + 0.01], q, 0.0)
    assert builder._unclean(far, None, lag_budget=100) is not None
    calm = builder._Segment([], [], [0.005] * 4, q, 0.0)
    assert builder._unclean(calm, None, lag_budget=0) is None
