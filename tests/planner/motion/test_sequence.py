"""Keyframes of a contact sequence through the one builder: stance contacts held, the COM on
its curve, keyframes evenly spaced and checked, the same answer twice."""

from __future__ import annotations

import bisect
from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import trajectory
from planner.contact.checks import hold_error, make_contact, within_limits
from planner.contact.context import ContactContext, make_context
from planner.contact.generation import hold_tasks, posture_task
from planner.contact.state import ContactState
from planner.kinematics import (
    ComTask,
    FramePositionTask,
    Priority,
    com_position,
    solve_ik,
)
from planner.motion import tuning
from planner.motion.builder import keyframe_grid, phase_keyframe_times
from planner.motion.sequence import (
    Timing,
    _blamed,
    _gaps_filled,
    _rest_point,
    _rest_window,
    _resting_where_blamed,
    _runs,
    contact_phase,
    dynamic_com,
    dynamic_durations,
    sequence_motion,
    swing_durations,
    timed_com,
)
from tests.planner.contact.contact_helpers import character_and_data, scene
from trajectory import is_static_equilibrium


@cache
def _hexapod_steps() -> tuple[ContactContext, tuple[ContactState, ...]]:
    """Three hexapod steps of 12 cm (release then creation), the COM shifted 4 cm each."""
    character, data = character_and_data("hexapod")
    ctx = make_context(scene("flat"), character, data)
    model = character.model
    q = np.array(character.q_ref)
    contacts = [make_contact(ctx, limb.name, q, 0) for limb in character.limbs]
    states = [ContactState(q, tuple(contacts))]
    for limb in ("l1_foot", "r2_foot", "l3_foot"):
        rest = tuple(c for c in contacts if c.limb != limb)
        states.append(ContactState(q, rest))
        old = next(c for c in contacts if c.limb == limb)
        foot = FramePositionTask(
            character.limb(limb).frame_id,
            old.position + np.array([0.12, 0.0, 0.0]),
            np.zeros(3),
            Priority.CONTACT,
        )
        com = ComTask(com_position(model, q) + np.array([0.04, 0.0, 0.0]), (True, True, False))
        result = solve_ik(model, q, [*hold_tasks(rest, ctx), foot, com, posture_task(ctx)])
        assert result.success
        q = np.array(result.q)
        contacts = [*rest, make_contact(ctx, limb, q, 0)]
        states.append(ContactState(q, tuple(contacts)))
    return ctx, tuple(states)


def _motion(ctx: ContactContext, states: tuple[ContactState, ...]):  # type: ignore[no-untyped-def]
    return sequence_motion(ctx.character, ctx.data, ctx.scene.collision.bvh, states)


def test_hexapod_keyframes_hold_stance_and_follow_the_com() -> None:
    ctx, states = _hexapod_steps()
    motion = _motion(ctx, states)
    assert motion.report["phases_animated"] == len(states)
    assert motion.quality.complete
    assert motion.quality.colliding_keyframes == 0
    assert motion.quality.com_error_max <= 0.01
    times = np.array([k.t for k in motion.keyframes])
    gaps = np.diff(times)
    assert gaps.min() >= 0.5 / 30.0 and gaps.max() <= 1.5 / 30.0
    for key in motion.keyframes:
        assert within_limits(ctx, np.asarray(key.q), tol=1e-6)
        phase = next(p for p in motion.phases if p.t0 - 1e-9 <= key.t <= p.t1 + 1e-9)
        held = [c for c in phase.contacts if c.limb in key.contacts]
        assert hold_error(ctx, np.asarray(key.q), held) <= 5e-3


def test_sequence_motion_is_deterministic() -> None:
    ctx, states = _hexapod_steps()
    a = _motion(ctx, states)
    b = _motion(ctx, states)
    assert len(a.keyframes) == len(b.keyframes)
    for ka, kb in zip(a.keyframes, b.keyframes, strict=True):
        assert ka.t == kb.t
        assert np.array_equal(ka.q, kb.q)


def test_keyframe_grid_is_even_and_ends_on_time() -> None:
    for t1 in (0.0, 0.01, 0.5, 1.0, 1.02, 3.3333):
        grid = keyframe_grid(0.0, t1, 30.0)
        assert grid[0] == 0.0 and grid[-1] == t1
        if len(grid) > 2:
            gaps = np.diff(grid)
            assert gaps.min() >= 0.5 / 30.0 and gaps.max() <= 1.5 / 30.0


def test_a_window_that_stops_joins_the_dynamic_curve_at_rest() -> None:
    """Where slowing cannot help, a window of phases stops between phases (a rest-to-rest
    quintic each, at the COM of the state with fewer contacts) and the dynamic phases on each
    side are found again to end and start at rest there: the curve stays C2 at every phase
    boundary, the window's phases go from stop to stop and last at least their swing time
    and as long as in 2PAC's curve, and the phases before the first one found again are the
    earlier curve's."""
    ctx, states = _hexapod_steps()
    character, data = ctx.character, ctx.data
    n = len(states)
    model = character.model
    reference, _ = timed_com(character, data, states, Timing(), swing_durations(character, states))
    whole = dynamic_com(character, data, states, reference)
    earlier, factors = whole.curve, whole.factors
    assert earlier is not None and not whole.stretched and whole.blamed == set()
    lo, hi = 2, 4
    stopped = _rest_window(character, data, states, reference, earlier, factors, (lo, hi))
    assert stopped is not None
    spliced, used, first = stopped
    assert first == lo - 1
    assert all(u >= f for u, f in zip(used, factors, strict=True))
    assert used[: lo - 1] == factors[: lo - 1] and used[hi + 1 :] == factors[hi + 1 :]
    segments = spliced.curve.segments
    times = spliced.phase_times
    assert len(segments) == n and len(times) == n + 1
    for seg, t0, t1 in zip(segments, times[:-1], times[1:], strict=True):
        assert seg.t0 == pytest.approx(t0) and seg.t1 == pytest.approx(t1)
    velocity, acceleration = spliced.curve.derivative(1), spliced.curve.derivative(2)
    for t in times[1:-1]:
        for curve in (spliced.curve, velocity, acceleration):
            np.testing.assert_allclose(curve(t - 1e-9), curve(t + 1e-9), atol=1e-5)
    minimum = np.maximum(swing_durations(character, states), np.diff(reference.phase_times))
    for j in range(lo, hi):
        start, end = segments[j].control_points[0], segments[j].control_points[-1]
        assert np.linalg.norm(velocity(times[j] + 1e-9)) < 1e-6
        assert np.linalg.norm(velocity(times[j + 1] - 1e-9)) < 1e-6
        np.testing.assert_allclose(end, _rest_point(model, states, j), atol=1e-9)
        np.testing.assert_allclose(start, _rest_point(model, states, j - 1), atol=1e-9)
        for k in (j, j + 1):  # the stop stands in both phases around it
            assert is_static_equilibrium(contact_phase(character, states[k]), end)
        assert times[j + 1] - times[j] >= minimum[j] - 1e-9
    for j in range(first):  # before the first phase found again: the earlier curve
        np.testing.assert_allclose(
            segments[j].control_points, earlier.curve.segments[j].control_points, atol=1e-12
        )


def test_phases_blamed_for_an_infeasible_plan_stop_and_the_rest_stays_dynamic() -> None:
    """The phases an infeasible whole-plan QP's certificate blames stop at rest between
    phases; every run of phases between them gets its own dynamic curve, at rest where it
    meets a stop: the curve is C2 at every phase boundary, still at both ends of each
    resting phase, through its rest points, and the dynamic phases pass Eq. 1 at their
    collocation times."""
    ctx, states = _hexapod_steps()
    character, data = ctx.character, ctx.data
    n = len(states)
    reference, _ = timed_com(character, data, states, Timing(), swing_durations(character, states))
    found = _resting_where_blamed(character, data, states, reference, 1.0, {3})
    assert found is not None
    curve, used, resting = found
    assert resting == {3} and len(used) == n and curve.valid
    times, segments = curve.phase_times, curve.curve.segments
    assert len(segments) == n and np.all(np.diff(times) > 0)
    velocity, acceleration = curve.curve.derivative(1), curve.curve.derivative(2)
    for t in times[1:-1]:
        for c in (curve.curve, velocity, acceleration):
            np.testing.assert_allclose(c(t - 1e-9), c(t + 1e-9), atol=1e-5)
    for t in (times[3] + 1e-9, times[4] - 1e-9):
        assert np.linalg.norm(velocity(t)) < 1e-6
    np.testing.assert_allclose(curve.curve(times[4]), _rest_point(character.model, states, 3))
    dynamic = [j for j in range(n) if j not in resting]
    reports = trajectory.validate_dynamics(
        curve.curve, [contact_phase(character, s) for s in states], times, 12
    )
    assert all(reports[j].fraction_valid == 1.0 for j in dynamic)


def test_runs_blame_and_filled_gaps() -> None:
    """``_runs``: the maximal runs of consecutive phases, in order; ``_blamed``: the
    phases carrying ``REST_BLAME_SHARE`` of the blame, largest first; ``_gaps_filled``: a
    lone phase between two others joins them."""
    assert _runs({7, 1, 2, 3, 5}) == [(1, 4), (5, 6), (7, 8)]
    assert _runs(set()) == []
    blame = np.array([0.02, 0.62, 0.01, 0.3, 0.05])
    assert _blamed(blame) == {1, 3}
    assert _blamed(blame, offset=10) == {11, 13}
    assert _blamed(np.array([1.0])) == {0}
    assert _gaps_filled({1, 3, 7}) == {1, 2, 3, 7}
    assert _gaps_filled({1, 4}) == {1, 4}


def test_phases_remembered_per_state_equal_fresh_ones() -> None:
    """A state's contact phase and kinematic polytope, remembered per state object, equal
    those built anew, cold or warm, in any order; an equal state (another object) is built
    anew alike."""
    from planner.motion import sequence

    ctx, states = _hexapod_steps()
    character, data = ctx.character, ctx.data
    fresh = [
        (
            sequence._contact_phase(float(character.mass), s),
            sequence._phase_kinematics(
                s, [data.com_constraint(c.limb).polytope for c in s.contacts]
            ),
        )
        for s in states
    ]
    sequence._PER_STATE.clear()
    copies = [ContactState(np.array(s.q), s.contacts) for s in states]
    for order in (range(len(states)), reversed(range(len(states)))):
        for i in order:
            for state in (states[i], copies[i]):
                phase = contact_phase(character, state)
                kin = sequence.phase_kinematics(data, state)
                assert np.array_equal(phase.wrench_generators, fresh[i][0].wrench_generators)
                assert kin is not None and fresh[i][1] is not None
                assert np.array_equal(kin.A, fresh[i][1].A)
                assert np.array_equal(kin.b, fresh[i][1].b)
    assert contact_phase(character, states[0]) is contact_phase(character, states[0])


def test_a_step_down_keeps_the_com_within_reach_of_its_states_own_height() -> None:
    """A plan's kinematic constraints of a state are its effectors' COM polytopes (2PAC
    Eq. 4), a floor ``COM_BELOW_STATES`` below the lower of the state's own COM and the next
    state's, and for a state entered by a step down (a limb put ``STEP_DOWN`` or more below
    where it left) a cap ``COM_ABOVE_STATE`` above the state's own COM. The hexapod's steps
    on flat ground are no step down, the same steps 10 cm down are."""
    from planner.motion import sequence

    ctx, flat = _hexapod_steps()
    character, data = ctx.character, ctx.data
    model = character.model
    down = [flat[0]]
    for state in flat[1:]:
        contacts = []
        for c in state.contacts:
            before = next((b for b in flat[0].contacts if b.limb == c.limb), None)
            if before is not None and not np.allclose(c.placement, before.placement):
                placement = c.placement.copy()
                placement[2, 3] -= 0.1  # put down 10 cm lower than where it left
                c = replace(c, placement=placement, points=c.points - [0.0, 0.0, 0.1])
            contacts.append(c)
        down.append(ContactState(state.q, tuple(contacts)))

    for states, steps in ((flat, []), (down, [2, 4, 6])):  # the states each foot is put down in
        planned = sequence.plan_kinematics(character, data, states)
        polytopes = [sequence.phase_kinematics(data, s) for s in states]
        for j, (kin, alone) in enumerate(zip(planned, polytopes, strict=True)):
            assert kin is not None and alone is not None
            added = 2 if j in steps else 1
            assert len(kin.b) == len(alone.b) + added
            assert np.array_equal(kin.A[: len(alone.b)], alone.A)
            assert np.array_equal(kin.b[: len(alone.b)], alone.b)
            # the floor: a point on it keeps to it, one 1 cm under it does not
            com = com_position(model, states[j].q)
            following = com_position(model, states[min(j + 1, len(states) - 1)].q)
            floor = min(com[2], following[2]) - tuning.COM_BELOW_STATES
            row, bound = kin.A[len(alone.b)], kin.b[len(alone.b)]
            assert np.array_equal(row, [0.0, 0.0, -1.0])
            assert float(row @ [com[0], com[1], floor] - bound) == pytest.approx(0.0, abs=1e-12)
            assert float(row @ [com[0], com[1], floor - 0.01] - bound) == pytest.approx(0.01)
            if j in steps:
                # the cap: the state's own COM keeps to it, a point 1 cm above it does not
                above = com + np.array([0.0, 0.0, tuning.COM_ABOVE_STATE + 0.01])
                assert np.array_equal(kin.A[-1], [0.0, 0.0, 1.0])
                assert float(kin.A[-1] @ com - kin.b[-1]) == pytest.approx(-tuning.COM_ABOVE_STATE)
                assert float(kin.A[-1] @ above - kin.b[-1]) == pytest.approx(0.01)


def _fake_build(  # type: ignore[no-untyped-def]
    original: tuple[ContactState, ...], bad: int, replanned_clean: bool, held_clean: bool = False
):
    """A stand-in for ``build_motion`` (no tracking): a build through the ``original`` states
    cannot play phase ``bad`` (unless ``held_clean`` and it sets its stance back), a build
    through re-planned states phase ``bad + 1`` (the trials never come clean), and a build of
    2PAC's whole curve through re-planned states is clean when ``replanned_clean``. Returns
    the stand-in and the specs it was given."""
    from planner.motion.builder import BuiltMotion, MotionReport
    from planner.motion.types import Keyframe, Phase

    given: list[object] = []

    def build(character, scene_bvh, spec, *, abandon_unclean=False, **_):  # type: ignore[no-untyped-def]
        given.append(spec)
        first = spec.phases[bad].stance is original[bad].contacts
        fails = bad if first else bad + 1
        total = len(spec.phases)
        clean = not abandon_unclean and (
            (first and held_clean and spec.hold_stance) or (not first and replanned_clean)
        )
        report = MotionReport(
            phases_animated=fails if abandon_unclean else total,
            phases_total=total,
            cut_short=False,
            colliding_keyframes=0,
            worst_scene_depth=0.0,
            worst_shape=None,
            worst_self_depth=0.0,
            max_hold_error=0.0 if clean else 0.1,
            com_error_max=0.0,
            com_error_p99=0.0,
            qp_fallbacks=0,
            abandoned=abandon_unclean,
            abandoned_phase=fails if abandon_unclean else None,
            abandoned_because="a keyframe collides or a contact slips" if abandon_unclean else None,
        )
        end = spec.phases[fails - 1].t1 if abandon_unclean else spec.phases[-1].t1
        keys = tuple(
            Keyframe(t=float(t), q=np.asarray(spec.q_start), contacts=())
            for t in keyframe_grid(spec.phases[0].t0, end, spec.rate)
        )
        phases = tuple(Phase(t0=p.t0, t1=p.t1, contacts=p.stance) for p in spec.phases)
        return BuiltMotion(phases, (), keys, report, np.asarray(spec.q_start))

    return build, given


def test_the_last_resort_sets_its_stance_back_only_where_that_makes_it_clean(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When no dynamic curve comes clean, 2PAC's curve is built whole as it is and, that not
    being clean, again with each keyframe's stance set back on its contacts: the set-back
    build is the answer when it is clean (a climbing wall's slipping stance), the build as it
    is otherwise (a rubble walk whose set-back legs collide)."""
    from planner.motion import sequence

    ctx, states = _hexapod_steps()
    for held_clean in (True, False):
        build, given = _fake_build(states, 4, replanned_clean=False, held_clean=held_clean)
        monkeypatch.setattr(sequence, "build_motion", build)
        motion = sequence_motion(ctx.character, ctx.data, ctx.scene.collision.bvh, states)
        whole = [s for s in given if not s.phases[0].rigid_stance]
        assert [s.hold_stance for s in whole] == [False, True]
        assert motion.quality.complete == held_clean
        assert motion.states == states


@pytest.mark.parametrize("replanned_clean", [True, False])
def test_a_fallback_keeps_the_replanned_changes_only_when_they_play_clean(
    monkeypatch: pytest.MonkeyPatch, replanned_clean: bool
) -> None:
    """When no dynamic curve comes clean and 2PAC's curve through the states first given
    does not either, 2PAC's curve through the contact changes the trials re-planned is built
    too, and its states are the answer when it is clean; otherwise the re-plans are undone.
    A last-resort build that is not clean is built again with its stance set back on the
    contacts; the trials never set back."""
    from planner.motion import sequence

    ctx, states = _hexapod_steps()
    bad = 4
    # re-planned: the same states from the one before the failing change on, as new objects
    other = (
        *states[:3],
        *(ContactState(s.q, tuple(replace(c) for c in s.contacts)) for s in states[3:]),
    )
    calls: list[int] = []

    def replan(planned, phase, reserve):  # type: ignore[no-untyped-def]
        calls.append(phase)
        return other if len(calls) == 1 else None

    build, given = _fake_build(states, bad, replanned_clean)
    monkeypatch.setattr(sequence, "build_motion", build)
    motion = sequence_motion(
        ctx.character, ctx.data, ctx.scene.collision.bvh, states, replan=replan
    )
    assert calls and calls[0] == bad
    replans = motion.report["contact_replans"]
    assert isinstance(replans, list)
    assert replans[0].startswith(f"phase {bad} could not be played")
    assert motion.report["com_method"] in ("2pac", "2pac+rest_to_rest")
    # the last builds: 2PAC's whole curve through the first states, as it is then set back
    # (neither clean), then through the re-planned ones (set back only when not clean)
    whole = [s for s in given if not s.phases[0].rigid_stance]
    assert [s.hold_stance for s in whole] == [False, True, False] + (
        [] if replanned_clean else [True]
    )
    assert not any(s.hold_stance for s in given if s.phases[0].rigid_stance)
    assert all(s.phases[bad].stance is states[bad].contacts for s in whole[:2])
    assert all(s.phases[bad].stance is other[bad].contacts for s in whole[2:])
    if replanned_clean:
        assert motion.states == other
        assert motion.quality.complete
        assert replans[-1].endswith("the re-planned changes are kept, on 2PAC's curve")
    else:
        assert motion.states == states
        assert not motion.quality.complete
        assert replans[-1].endswith("all undone")


def test_a_chest_standing_back_up_takes_its_time() -> None:
    """A state whose chest stands back up to the reference after a bent one (the end of a
    climb) gives the phases on either side of it time for the chest to turn at CHEST_SPEED;
    a chest that sways elsewhere does not slow anything."""
    character, _ = character_and_data("humanoid")
    model = character.model
    pitch = int(model.idx_qs[model.getJointId("torso_pitch")])
    bent, straight, swayed = (np.array(character.q_ref) for _ in range(3))
    bent[pitch], swayed[pitch] = 0.8, 0.3
    states = [ContactState(q, ()) for q in (bent, straight, swayed)]
    turn_s = 0.8 / tuning.CHEST_SPEED
    for durations in (
        swing_durations(character, states),
        dynamic_durations(character, states),
    ):
        assert durations[0] >= turn_s - 1e-9 and durations[1] >= turn_s - 1e-9
        assert durations[2] < turn_s  # the sway after it is not timed (0.3 rad, at rest)
    assert max(swing_durations(character, [states[2], states[0]])) < turn_s


@settings(max_examples=200, deadline=None)
@given(
    lengths=st.lists(st.floats(0.004, 0.3), min_size=1, max_size=12),
    rate=st.sampled_from([24.0, 30.0, 60.0]),
)
def test_keyframe_times_put_a_time_in_a_short_phase_and_keep_the_spacing(
    lengths: list[float], rate: float
) -> None:
    """``phase_keyframe_times``: the grid's ends, gaps of half a period to one and a half, a
    phase that had a time keeps one, a short phase between two phases of two periods or more
    gets one, and a grid whose every phase has a time is ``keyframe_grid`` itself."""
    ends = np.cumsum(lengths).tolist()
    t1 = ends[-1]
    period = 1.0 / rate
    plain = keyframe_grid(0.0, t1, rate)
    times = phase_keyframe_times(0.0, t1, rate, ends)
    assert times[0] == 0.0 and times[-1] == pytest.approx(t1) and len(times) == len(plain)
    if t1 >= 0.5 * period:
        gaps = np.diff(times)
        assert gaps.min() >= 0.5 * period - 1e-9 and gaps.max() <= 1.5 * period + 1e-9

    def held(grid: np.ndarray) -> list[int]:
        phase = [min(bisect.bisect_right(ends, float(t)), len(ends) - 1) for t in grid]
        return [phase.count(k) for k in range(len(ends))]

    before, after = held(plain), held(times)
    assert all(a >= 1 for a, b in zip(after, before, strict=True) if b >= 1)
    if all(b >= 1 for b in before):
        np.testing.assert_array_equal(times, plain)
    for k in range(1, len(ends) - 1):
        if lengths[k - 1] >= 2 * period and lengths[k + 1] >= 2 * period:
            assert after[k] >= 1, (k, lengths)


def test_a_window_keeps_to_the_kinematics_of_the_whole_plan(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A window's QP [lo, hi) gets the same kinematic constraints as those phases have in the
    whole plan: the step-down caps from the states before it and the floor of its last phase
    from the state after it."""
    from planner.motion import sequence

    ctx, flat = _hexapod_steps()
    character, data = ctx.character, ctx.data
    reference, _ = timed_com(character, data, flat, Timing(), swing_durations(character, flat))
    earlier = dynamic_com(character, data, flat, reference).curve
    assert earlier is not None
    lo, hi = 2, 5
    # the state after the window crouched 10 cm: the floor of the window's last phase is
    # below its COM, not its own
    q = np.array(flat[hi].q)
    q[2] -= 0.1
    states = [*flat[:hi], ContactState(q, flat[hi].contacts), *flat[hi + 1 :]]
    whole = sequence.plan_kinematics(character, data, states)
    seen: list[object] = []
    real = trajectory.solve_dynamic_com

    def recording(*args: object, **kwargs: object) -> trajectory.DynamicOutcome:
        seen.append(kwargs["kinematics"])
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(sequence.trajectory, "solve_dynamic_com", recording)
    factors = [1.0] * len(states)
    segments = earlier.curve.segments
    sequence._dynamic_window(character, data, states, reference, 1.0, factors, lo, hi, segments)
    (window,) = seen
    assert isinstance(window, list) and len(window) == hi - lo
    for got, expected in zip(window, whole[lo:hi], strict=True):
        assert got is not None and expected is not None
        np.testing.assert_array_equal(got.A, expected.A)
        np.testing.assert_array_equal(got.b, expected.b)
    assert whole[hi - 1] is not None and whole[hi - 2] is not None
    assert whole[hi - 1].b[-1] > whole[hi - 2].b[-1] + 0.05  # that floor is lower


@pytest.mark.parametrize(
    ("stretch_by", "passing_at", "order"),
    [
        # the stretched levels right after the first plain one
        (1.2, (1, True), [(0, False), (0, True), (1, True)]),
        # then the plain levels left
        (1.2, (2, False), [(0, False), (0, True), (1, True), (2, True), (1, False), (2, False)]),
        # nothing to stretch: the plain levels only
        (1.0, (1, False), [(0, False), (1, False)]),
        (1.0, None, [(0, False), (1, False), (2, False)]),
    ],
)
def test_the_stretched_shifts_come_before_the_slower_plain_levels(
    monkeypatch: pytest.MonkeyPatch,
    stretch_by: float,
    passing_at: tuple[int, bool] | None,
    order: list[tuple[int, bool]],
) -> None:
    """When the first plain level fails, the QP is tried with the weight shifts stretched at
    each level, then with the whole plan slowed to the later levels; the answer says which
    plain levels were tried and whether its factors hold the stretch. The QP stands in for
    the order alone, passing at one (level, stretched) pair (the rubble plans where this
    happens are measured by ``bench/motion.py``)."""
    from planner.motion import sequence

    ctx, states = _hexapod_steps()
    character, data = ctx.character, ctx.data
    levels = tuning.DYNAMIC_SLOWDOWNS
    stretch = [1.0] * len(states)
    stretch[1] = stretch_by
    reference, _ = timed_com(character, data, states, Timing(), swing_durations(character, states))
    passing = dynamic_com(character, data, states, reference).curve
    assert passing is not None
    tried: list[tuple[int, bool]] = []

    def window(*args: object) -> trajectory.DynamicOutcome:
        factors = list(args[5])  # type: ignore[call-overload]
        key = (levels.index(factors[0]), factors[1] > factors[0])
        tried.append(key)
        return trajectory.DynamicOutcome(passing if key == passing_at else None, None)

    monkeypatch.setattr(sequence, "_shift_stretch", lambda *args: stretch)
    monkeypatch.setattr(sequence, "_dynamic_window", window)
    found = dynamic_com(character, data, states, reference)
    assert tried == order
    assert found.plain == tuple(levels[k] for k, stretched in order if not stretched)
    if passing_at is None:
        assert found.curve is None and not found.stretched
        return
    assert found.curve is passing and found.stretched == passing_at[1]
    # the report says why the plan's shifts were stretched or the whole plan slowed
    motion = sequence_motion(
        character, data, ctx.scene.collision.bvh, states, timing=Timing(overlap=False)
    )
    trials = [str(t) for t in motion.report["dynamic_trials"]]
    if passing_at == (1, False):  # nothing to stretch
        assert trials[0] == (
            f"no curve passes Eq. 1 at {levels[0]:g} times the brisk durations: the whole "
            f"plan slowed to {levels[1]:g}"
        )
    elif passing_at[1]:
        assert trials[0].startswith(f"no curve passes Eq. 1 at {levels[0]:g} times the brisk")
        assert "weight shifts lengthened" in trials[0]
    else:
        assert trials[0] == (
            f"no curve passes Eq. 1 at {levels[0]:g} and {levels[1]:g} times the brisk "
            f"durations, nor with the weight shifts stretched: the whole plan slowed to "
            f"{levels[2]:g}"
        )
