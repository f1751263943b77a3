"""Transition points, quasi-static polylines, 2PAC curves and the end-to-end planner."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import trajectory
from tests.trajectory.helpers import figure2_phases, patch, walking_phases
from trajectory import (
    BoundaryState,
    ContactPhase,
    EffectorConstraint,
    Halfspaces,
    TransitionCost,
)

UP = np.array([0.0, 0.0, 1.0])


def box(lo: np.ndarray, hi: np.ndarray) -> Halfspaces:
    return Halfspaces(np.vstack([np.eye(3), -np.eye(3)]), np.concatenate([hi, -lo]))


def random_box(rng: np.random.Generator) -> Halfspaces:
    lo = rng.uniform(-1, 0, 3)
    return box(lo, lo + rng.uniform(0.2, 1.5, 3))


def inside_point(poly: Halfspaces, rng: np.random.Generator) -> np.ndarray:
    lo, hi = -poly.b[3:], poly.b[:3]
    return rng.uniform(lo, hi)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.sampled_from([1, 2]))
def test_attractor_curves_stay_in_kinematic_polytope(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    kin = random_box(rng)
    start = BoundaryState(inside_point(kin, rng))
    end = BoundaryState(inside_point(kin, rng))
    att = np.array([inside_point(kin, rng) for _ in range(m)])
    curve = trajectory.attractor_curve(start, end, att, duration=float(rng.uniform(0.5, 3)))
    assert curve.degree == 5 + m
    pts = curve(np.linspace(curve.t0, curve.t1, 101))
    assert np.all(kin.violation(pts) <= 1e-12)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(0, 3))
def test_curves_meet_boundary_conditions(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    s = BoundaryState(*rng.normal(size=(3, 3)))
    e = BoundaryState(*rng.normal(size=(3, 3)))
    T = float(rng.uniform(0.3, 4))
    curve = trajectory.attractor_curve(s, e, rng.normal(size=(m, 3)), T, t0=1.0)
    d1, d2 = curve.derivative(1), curve.derivative(2)
    for t, st_ in ((curve.t0, s), (curve.t1, e)):
        np.testing.assert_allclose(curve(t), st_.position, atol=1e-9)
        np.testing.assert_allclose(d1(t), st_.vel, atol=1e-8)
        np.testing.assert_allclose(d2(t), st_.acc, atol=1e-7)


def test_sliding_window_has_continuous_velocity() -> None:
    phases = walking_phases(9)
    traj = trajectory.plan_com_trajectory(phases, np.array([0.0, 0.0, 0.9]), n_checks=0)
    segs = traj.segments
    assert len(segs) >= 2
    for a, b in itertools.pairwise(segs):
        np.testing.assert_allclose(a(a.t1), b(b.t0), atol=1e-9)
        np.testing.assert_allclose(a.derivative()(a.t1), b.derivative()(b.t0), atol=1e-8)
        np.testing.assert_allclose(a.derivative(2)(a.t1), b.derivative(2)(b.t0), atol=1e-6)
    # the character does not stop at the intermediate windows
    assert any(np.linalg.norm(a.derivative()(a.t1)) > 1e-3 for a in segs[:-1])


@settings(max_examples=8, deadline=None)
@given(
    swing=st.floats(0.2, 1.5),
    shift=st.floats(0.05, 0.5),
    n_phases=st.integers(3, 11),
    cost=st.sampled_from(["distance", "tired"]),
)
def test_every_phase_gets_its_minimum_duration(
    swing: float, shift: float, n_phases: int, cost: str
) -> None:
    """The sliding window is slowed down (or a window falls back, and says so) until every
    phase lasts its minimum; the joins stay continuous in velocity and acceleration."""
    phases = walking_phases(n_phases)
    start = np.array([0.0, 0.0, 0.9])
    centres = [np.vstack([c.points for c in p.contacts]).mean(axis=0) for p in phases]
    targets = [centres[min(j + 2, n_phases - 1)] + [0.0, 0.0, 0.9] for j in range(n_phases - 1)]
    minimums = [swing if j % 2 else shift for j in range(n_phases)]
    traj = trajectory.plan_com_trajectory(
        phases,
        start,
        n_checks=0,
        cost=TransitionCost(cost),  # type: ignore[arg-type]
        targets=targets,
        min_durations=minimums,
        max_stretch=40.0,
    )
    durations = np.diff(traj.phase_times)
    assert np.all(durations >= np.asarray(minimums) - 0.05), (durations, minimums)
    assert len(traj.phase_methods) == n_phases
    assert set(traj.phase_methods) <= {"2pac", "rest_to_rest"}
    for a, b in itertools.pairwise(traj.segments):
        np.testing.assert_allclose(a(a.t1), b(b.t0), atol=1e-9)
        np.testing.assert_allclose(a.derivative()(a.t1), b.derivative()(b.t0), atol=1e-7)
        np.testing.assert_allclose(a.derivative(2)(a.t1), b.derivative(2)(b.t0), atol=1e-5)


@pytest.mark.parametrize(
    ("swing", "n_phases", "cost"),
    [(0.3, 5, "tired"), (0.3, 9, "distance"), (0.45, 7, "tired"), (0.6, 9, "tired")],
)
def test_a_window_keeps_the_shortest_candidate_as_if_every_one_were_slowed_in_full(
    swing: float, n_phases: int, cost: str
) -> None:
    """Each window tries its candidates (extra control points after the first attractor)
    from the most to the fewest and drops one as soon as it would end after the best so far:
    the curve kept is bit for bit the one of slowing every candidate in full, fewest extra
    points first, and keeping the strictly shortest."""
    from trajectory import com
    from trajectory.polytope import stack

    real = com._window_curve
    windows = []

    def checked(w, state, att, goal, j, t, phase_start, last):  # type: ignore[no-untyped-def]
        found = real(w, state, att, goal, j, t, phase_start, last)
        after = att[1] if len(att) > 1 else goal
        sets = None if last else stack([w.eqs[j + len(att)], w.kins[j + len(att)]])
        best = None
        for extra in range(com.MAX_EXTRA_ATTRACTORS + 1):
            middle = att[0] + (np.arange(1, extra + 1) / (extra + 1))[:, None] * (after - att[0])
            points = np.vstack([att[:1], middle, att[1:]])
            full = com._stretched_curve(w, state, points, att, goal, j, t, phase_start, sets)
            if full is not None and (best is None or full[0].t1 < best[0].t1):
                best = full
        assert (found is None) == (best is None)
        if found is not None and best is not None:
            assert found[0].t1 == best[0].t1 and found[1] == best[1] and found[2] == best[2]
            assert np.array_equal(found[0].control_points, best[0].control_points)
        windows.append(found)
        return found

    phases = walking_phases(n_phases)
    centres = [np.vstack([c.points for c in p.contacts]).mean(axis=0) for p in phases]
    targets = [centres[min(j + 2, n_phases - 1)] + [0.0, 0.0, 0.9] for j in range(n_phases - 1)]
    with pytest.MonkeyPatch.context() as patched:
        patched.setattr(com, "_window_curve", checked)
        trajectory.plan_com_trajectory(
            phases,
            np.array([0.0, 0.0, 0.9]),
            n_checks=0,
            cost=TransitionCost(cost),  # type: ignore[arg-type]
            targets=targets,
            min_durations=[swing if j % 2 else 0.1 for j in range(n_phases)],
            max_stretch=40.0,
        )
    assert any(found is not None for found in windows)


def test_tired_transition_points_spread_over_the_stance_and_stay_2pac() -> None:
    """With "tired" aimed at the phase after next, the two transition points around a
    single-support phase differ (the COM travels while the foot swings), so no window
    needs to fall back; with "distance" they coincide."""
    phases = walking_phases(7)
    start = np.array([0.0, 0.0, 0.9])
    centres = [np.vstack([c.points for c in p.contacts]).mean(axis=0) for p in phases]
    targets = [centres[min(j + 2, 6)] + [0.0, 0.0, 0.9] for j in range(6)]
    tired = trajectory.plan_com_trajectory(
        phases, start, n_checks=0, cost=TransitionCost("tired"), targets=targets
    )
    plain = trajectory.plan_com_trajectory(phases, start, n_checks=0)
    gaps = [
        np.linalg.norm(tired.transitions[j].point - tired.transitions[j - 1].point)
        for j in (1, 3, 5)
    ]
    assert min(gaps) > 0.02
    same = [
        np.linalg.norm(plain.transitions[j].point - plain.transitions[j - 1].point)
        for j in (1, 3, 5)
    ]
    assert max(same) < 1e-3
    timed = trajectory.plan_com_trajectory(
        phases,
        start,
        np.array([0.45, 0.0, 0.9]),  # an end beyond the last transition point
        n_checks=0,
        cost=TransitionCost("tired"),
        targets=targets,
        min_durations=[0.15, 0.5] * 3 + [0.15],
        max_stretch=40.0,
    )
    assert timed.phase_methods == ("2pac",) * 7


def test_timing_arguments_are_checked() -> None:
    phases = walking_phases(3)
    with pytest.raises(ValueError, match="min_durations"):
        trajectory.plan_com_trajectory(phases, np.zeros(3), min_durations=[0.1])
    with pytest.raises(ValueError, match="min_durations"):
        trajectory.plan_com_trajectory(phases, np.zeros(3), min_durations=[0.1, -1.0, 0.1])
    with pytest.raises(ValueError, match="targets"):
        trajectory.plan_com_trajectory(phases, np.zeros(3), targets=[None])
    with pytest.raises(ValueError, match="max_stretch"):
        trajectory.plan_com_trajectory(phases, np.zeros(3), max_stretch=0.5)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_quasi_static_polyline_satisfies_eq1(seed: int) -> None:
    """Eq. 1 with zero acceleration holds at every sample of every phase, and the dynamic
    violation of the epsilon-feasible timing vanishes with the acceleration bound."""
    rng = np.random.default_rng(seed)
    phases = walking_phases(int(rng.integers(3, 6)))
    start = np.array([0.0, 0.0, float(rng.uniform(0.7, 1.0))])
    worst = []
    for eps in (0.02, 0.002):
        traj = trajectory.plan_com_trajectory(
            phases, start, method="quasi_static", max_acceleration=eps, n_checks=6
        )
        assert traj.quasi_static_feasible
        for j, phase in enumerate(phases):
            a, b = traj.phase_times[j], traj.phase_times[j + 1]
            pts = traj.curve(np.linspace(a, b, 15))
            margin = trajectory.equilibrium_halfspaces(phase).violation(pts)
            assert np.all(margin <= 1e-6)
            for c in pts:
                assert trajectory.equilibrium_margin(phase, c).margin >= -1e-6 * 70 * 9.81
        worst.append(max(r.worst_violation for r in traj.reports))
        assert worst[-1] <= 2.0 * 70.0 * eps
    assert worst[1] <= worst[0] + 1e-9


def test_infeasible_transition_gives_positive_slack() -> None:
    left = ContactPhase([patch(np.array([0.0, 0.0, 0.0]), UP, 0.05)])
    right = ContactPhase([patch(np.array([1.0, 0.0, 0.0]), UP, 0.05)])
    eq_l, eq_r = (trajectory.equilibrium_halfspaces(p) for p in (left, right))
    tp = trajectory.transition_point(eq_l, eq_r, np.array([0.0, 0.0, 0.9]))
    assert not tp.feasible
    assert tp.slack > 0.4
    assert np.all(np.isfinite(tp.point))
    # kinematic constraints that cannot hold together: still a point, never an error
    k1 = box(np.array([-1.0, -1, 0.5]), np.array([-0.5, 1, 1]))
    k2 = box(np.array([0.5, -1, 0.5]), np.array([1.0, 1, 1]))
    tp2 = trajectory.transition_point(eq_l, eq_l, np.zeros(3), kin_prev=k1, kin_next=k2)
    assert not tp2.feasible and tp2.kinematic_slack > 0
    # equality form agrees
    tp3 = trajectory.transition_qp_generators(left, k1, np.array([0.3, 0.0, 0.9]))
    assert not tp3.feasible and tp3.slack > 0


def test_transition_forms_agree_and_costs() -> None:
    phase = ContactPhase([patch(np.array([0.2, 0.1, 0.0]), UP, 0.1)])
    eq = trajectory.equilibrium_halfspaces(phase)
    kin = box(np.array([-1.0, -1, 0.8]), np.array([1.0, 1, 1.0]))
    c0 = np.array([0.6, 0.5, 1.5])
    a = trajectory.transition_point(eq, eq, c0, kin_prev=kin)
    b = trajectory.transition_qp_generators(phase, kin, c0)
    assert a.feasible and b.feasible
    np.testing.assert_allclose(a.point, b.point, atol=1e-4)
    low = trajectory.transition_point(
        eq, eq, c0, kin_prev=kin, cost=TransitionCost("low", strength=1.0)
    )
    assert low.point[2] == pytest.approx(0.8, abs=1e-6)
    side = trajectory.transition_point(
        eq,
        eq,
        np.array([0.2, 0.1, 0.9]),
        kin_prev=kin,
        target=np.array([1.0, 0.1, 0.9]),
        cost=TransitionCost("to_one_side", strength=1.0),
    )
    assert side.point[1] > 0.1 + 0.05
    groovy = [
        trajectory.transition_point(
            eq,
            eq,
            np.array([0.2, 0.1, 0.9]),
            kin_prev=kin,
            target=np.array([1.0, 0.1, 0.9]),
            cost=TransitionCost("groovy", strength=1.0, index=i),
        ).point[1]
        for i in (0, 1)
    ]
    assert groovy[0] > 0.15 > 0.05 > groovy[1]
    tired = trajectory.transition_point(
        eq,
        eq,
        np.array([0.2, 0.1, 0.9]),
        kin_prev=kin,
        target=np.array([0.2, 0.1, 0.9]),
        cost=TransitionCost("tired"),
    )
    np.testing.assert_allclose(tired.point, [0.2, 0.1, 0.9], atol=1e-6)
    user = trajectory.check_transition_point(np.array([0.2, 0.1, 0.9]), [eq], [kin])
    assert user.feasible
    user_bad = trajectory.check_transition_point(np.array([0.5, 0.1, 0.9]), [eq], [kin])
    assert not user_bad.feasible and user_bad.slack > 0.1
    with pytest.raises(ValueError, match="kind"):
        TransitionCost("silly")  # type: ignore[arg-type]


def test_kinematic_stacking_moves_rows_to_world() -> None:
    local = box(np.array([-0.1, -0.1, 0.6]), np.array([0.1, 0.1, 1.0]))
    ang = 0.7
    R = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    p = np.array([1.0, 2.0, 0.1])
    kin = trajectory.kinematic_polytope([EffectorConstraint(local, R, p)])
    c_local = np.array([0.05, -0.08, 0.7])
    assert kin.contains(R @ c_local + p)
    assert not kin.contains(R @ np.array([0.15, 0.0, 0.7]) + p)
    two = trajectory.kinematic_polytope(
        [EffectorConstraint(local, R, p), EffectorConstraint(local, np.eye(3), p)]
    )
    assert two.A.shape == (12, 3)
    with pytest.raises(ValueError, match="rotation"):
        EffectorConstraint(local, 2 * np.eye(3), p)


def test_multi_attractor_degree_raising() -> None:
    poly = np.array([[0.0, 0, 0.9], [0.3, 0.0, 0.9], [0.3, 0.3, 0.9], [0.6, 0.3, 0.9]])
    sets = [
        box(np.array([-0.05, -0.05, 0.85]), np.array([0.35, 0.05, 0.95])),
        box(np.array([0.25, -0.05, 0.85]), np.array([0.35, 0.35, 0.95])),
        box(np.array([0.25, 0.25, 0.85]), np.array([0.65, 0.35, 0.95])),
    ]
    curve, ok = trajectory.multi_attractor_curve(poly, sets, 3.0)
    assert ok and curve.degree > 5
    np.testing.assert_allclose(curve(curve.t0), poly[0], atol=1e-12)
    np.testing.assert_allclose(curve(curve.t1), poly[-1], atol=1e-12)


def test_figure2_worked_example() -> None:
    """Two feet and a hand; lift the right foot; put it down ahead (2PAC Figure 2)."""
    phases = figure2_phases()
    start, end = np.array([0.0, 0.0, 0.9]), np.array([0.2, 0.0, 0.9])
    kin = [box(np.array([-0.3, -0.4, 0.75]), np.array([0.5, 0.3, 1.0]))] * 3
    for method in ("2pac", "quasi_static"):
        traj = trajectory.plan_com_trajectory(
            phases, start, end, kinematics=kin, method=method, n_checks=8
        )
        assert len(traj.transitions) == 2 and traj.quasi_static_feasible
        t12, t23 = (t.point for t in traj.transitions)
        # lifting the foot: the transition holds on the left foot and the hand alone
        assert trajectory.is_static_equilibrium(phases[1], t12)
        assert trajectory.is_static_equilibrium(phases[0], t12)
        assert trajectory.is_static_equilibrium(phases[2], t23)
        np.testing.assert_allclose(traj.curve(traj.curve.t0), start, atol=1e-9)
        np.testing.assert_allclose(traj.curve(traj.curve.t1), end, atol=1e-9)
        assert np.all(np.diff(traj.phase_times) >= 0)
        pts = traj.curve(np.linspace(traj.curve.t0, traj.curve.t1, 50))
        assert np.all(kin[0].violation(pts) <= 1e-9)
        assert len(traj.reports) == 3
    # the hand matters: without it the single-foot phase cannot hold the start COM
    no_hand = ContactPhase([phases[1].contacts[0]])
    assert trajectory.is_static_equilibrium(phases[1], start)
    assert not trajectory.is_static_equilibrium(no_hand, start)


def test_plan_validation_errors() -> None:
    with pytest.raises(ValueError, match="phases"):
        trajectory.plan_com_trajectory([], np.zeros(3))
    with pytest.raises(ValueError, match="start_com"):
        trajectory.plan_com_trajectory(walking_phases(2), np.zeros(2))
    with pytest.raises(ValueError, match="method"):
        trajectory.plan_com_trajectory(walking_phases(2), np.zeros(3), method="fast")  # type: ignore[arg-type]


def test_formulations_agree_on_nested_phases() -> None:
    phases = walking_phases(6)
    start = np.array([0.0, 0.0, 0.9])
    a = trajectory.plan_com_trajectory(phases, start, formulation="polytope", n_checks=0)
    b = trajectory.plan_com_trajectory(phases, start, formulation="generators", n_checks=0)
    for ta, tb in zip(a.transitions, b.transitions, strict=True):
        np.testing.assert_allclose(ta.point, tb.point, atol=1e-4)
        assert ta.feasible == tb.feasible


def test_given_duration_rescales_time() -> None:
    phases = walking_phases(5)
    start = np.array([0.0, 0.0, 0.9])
    free = trajectory.plan_com_trajectory(phases, start, n_checks=0)
    fixed = trajectory.plan_com_trajectory(phases, start, n_checks=0, duration=7.0)
    assert fixed.curve.t1 - fixed.curve.t0 == pytest.approx(7.0)
    assert fixed.phase_times[-1] == pytest.approx(7.0)
    ts = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(
        free.curve(free.curve.t0 + ts * (free.curve.t1 - free.curve.t0)),
        fixed.curve(fixed.curve.t0 + ts * 7.0),
        atol=1e-9,
    )
    with pytest.raises(ValueError, match="duration"):
        trajectory.plan_com_trajectory(phases, start, duration=-1.0)


def test_user_placed_transitions_are_checked_not_moved() -> None:
    phases = figure2_phases()
    start = np.array([0.0, 0.0, 0.9])
    good = np.array([0.05, 0.02, 1.0])
    bad = np.array([0.9, 0.9, 1.0])
    traj = trajectory.plan_com_trajectory(phases, start, user_transitions=[good, None], n_checks=0)
    np.testing.assert_allclose(traj.transitions[0].point, good)
    assert traj.transitions[0].feasible == bool(trajectory.is_static_equilibrium(phases[1], good))
    traj2 = trajectory.plan_com_trajectory(phases, start, user_transitions=[bad, None], n_checks=0)
    np.testing.assert_allclose(traj2.transitions[0].point, bad)
    assert not traj2.transitions[0].feasible and traj2.transitions[0].slack > 0.1
    with pytest.raises(ValueError, match="user_transitions"):
        trajectory.plan_com_trajectory(phases, start, user_transitions=[good])
