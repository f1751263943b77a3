"""Dynamic COM curves (trajectory.dynamic): Eq. 1 along the curve, C2 joins, rest ends,
kinematic constraints, and the same answer for the same input."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import sparse

import trajectory
from tests.trajectory.helpers import figure2_phases, patch, walking_phases
from trajectory import Halfspaces

HEIGHT = 0.9


Walk = tuple[list[trajectory.ContactPhase], list[float], np.ndarray, np.ndarray]


def _walk(n_phases: int, swing: float, shift: float) -> Walk:
    phases = walking_phases(n_phases)
    durations = [swing if i % 2 else shift for i in range(n_phases)]
    durations[0] = durations[-1] = 0.4
    first = np.vstack([c.points for c in phases[0].contacts]).mean(axis=0)
    last = np.vstack([c.points for c in phases[-1].contacts]).mean(axis=0)
    up = np.array([0.0, 0.0, HEIGHT])
    return phases, durations, first + up, last + up


def _assert_c2(curve: trajectory.PiecewiseBezier) -> None:
    """C2 at every phase boundary: both sides of each join agree (position, velocity,
    acceleration)."""
    for k in range(1, len(curve.segments)):
        a, b = curve.segments[k - 1], curve.segments[k]
        for order in (0, 1, 2):
            left = a.derivative(order)(a.t1) if order else a(a.t1)
            right = b.derivative(order)(b.t0) if order else b(b.t0)
            np.testing.assert_allclose(left, right, atol=1e-5 * (1 + np.abs(left).max()))


def _exact_validity(
    result: trajectory.DynamicCom, phases: list[trajectory.ContactPhase], per_phase: int
) -> float:
    reports = trajectory.validate_dynamics(result.curve, phases, result.phase_times, per_phase)
    return float(np.mean([r.fraction_valid for r in reports]))


@settings(max_examples=12, deadline=None)
@given(n=st.sampled_from([3, 5, 7]), swing=st.floats(0.3, 0.8), shift=st.floats(0.1, 0.4))
def test_a_walk_at_a_brisk_pace_passes_eq1_along_the_whole_curve(
    n: int, swing: float, shift: float
) -> None:
    phases, durations, start, end = _walk(n, swing, shift)
    result = trajectory.dynamic_com(phases, durations, start, end)
    assert result is not None and result.valid
    # far denser than the collocation times: the margin covers the gaps between them
    assert _exact_validity(result, phases, 40) >= 0.97
    curve = result.curve
    np.testing.assert_allclose(curve(curve.t0), start, atol=1e-6)
    np.testing.assert_allclose(curve(curve.t1), end, atol=1e-6)
    for order in (1, 2):
        ends = curve.derivative(order)(np.array([curve.t0, curve.t1]))
        np.testing.assert_allclose(ends, 0.0, atol=1e-5)
    _assert_c2(curve)
    np.testing.assert_allclose(result.phase_times, np.concatenate([[0], np.cumsum(durations)]))


def test_the_curve_sways_less_than_a_quasi_static_one_at_the_same_pace() -> None:
    """The point of a dynamic COM: the wrench, not the COM, moves over the stance foot."""
    phases, durations, start, end = _walk(7, 0.35, 0.1)
    result = trajectory.dynamic_com(phases, durations, start, end)
    assert result is not None and result.valid
    lateral = result.curve(np.linspace(0, result.curve.t1, 200))[:, 1]
    # the stance feet are 0.1 m either side: a quasi-static COM would have to reach them
    assert np.ptp(lateral) < 0.15


def test_an_impossible_pace_is_refused_not_returned_valid() -> None:
    """A 1.5 m walk in 0.4 s cannot keep the wrench in the cones: None or not valid."""
    phases, _durations, start, end = _walk(7, 0.05, 0.05)
    result = trajectory.dynamic_com(phases, [0.05] * 7, start, end + np.array([1.0, 0.0, 0.0]))
    assert result is None or not result.valid


def test_kinematic_constraints_hold_along_the_curve() -> None:
    phases, durations, start, end = _walk(5, 0.4, 0.15)
    ceiling = HEIGHT + 0.005
    kin = Halfspaces(np.array([[0.0, 0.0, 1.0]]), np.array([ceiling]))
    result = trajectory.dynamic_com(phases, durations, start, end, kinematics=[kin] * 5)
    assert result is not None and result.valid
    z = result.curve(np.linspace(0, result.curve.t1, 300))[:, 2]
    assert z.max() <= ceiling + trajectory.dynamic.KINEMATIC_SLACK + 1e-9


def test_a_hand_on_a_wall_phase_set_solves_and_replays_identically() -> None:
    phases = figure2_phases()
    start = np.array([0.05, -0.05, 0.9])
    end = np.array([0.15, -0.05, 0.9])
    reference = trajectory.plan_com_trajectory(phases, start, end)
    first, second = (
        trajectory.dynamic_com(
            phases,
            [0.4, 0.5, 0.4],
            start,
            end,
            reference=reference.curve,
            reference_times=list(reference.phase_times),
        )
        for _ in range(2)
    )
    assert first is not None and first.valid and second is not None
    for a, b in zip(first.curve.segments, second.curve.segments, strict=True):
        np.testing.assert_array_equal(a.control_points, b.control_points)


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("durations", {"durations": [0.3, -0.1, 0.3]}),
        ("durations", {"durations": [0.3, 0.3]}),
        ("kinematics", {"kinematics": [None]}),
        ("reference_times", {"reference": "curve", "reference_times": [0.0, 1.0]}),
    ],
)
def test_bad_input_names_the_field(field: str, kwargs: dict[str, Any]) -> None:
    phases = figure2_phases()
    start, end = np.array([0.05, -0.05, 0.9]), np.array([0.15, -0.05, 0.9])
    args = {"durations": [0.4, 0.5, 0.4], **kwargs}
    if args.get("reference") == "curve":
        args["reference"] = trajectory.plan_com_trajectory(phases, start, end).curve
    with pytest.raises(ValueError, match=field):
        trajectory.dynamic_com(phases, args.pop("durations"), start, end, **args)


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="degree"):
        trajectory.DynamicSettings(degree=4)
    with pytest.raises(ValueError, match="samples"):
        trajectory.DynamicSettings(samples=1)


def test_the_height_follows_the_reference_closer_than_the_path() -> None:
    """A reference whose height dips 5 cm in the middle of a walk (legs spread in double
    support) keeps the curve's height within 1.5 cm of it at every collocation time, while
    the horizontal path may round the reference's corners."""
    phases, durations, start, end = _walk(7, 0.35, 0.1)
    times = np.concatenate([[0.0], np.cumsum(durations)])
    mid = 0.5 * (start + end) - np.array([0.0, 0.0, 0.05])
    reference = trajectory.PiecewiseBezier(
        (
            trajectory.BezierCurve(np.stack([start, start, mid]), 0.0, times[-1] / 2),
            trajectory.BezierCurve(np.stack([mid, end, end]), times[-1] / 2, times[-1]),
        )
    )
    result = trajectory.dynamic_com(
        phases, durations, start, end, reference=reference, reference_times=list(times)
    )
    assert result is not None and result.valid
    samples = np.linspace(0.0, times[-1], 100)
    gap = np.abs(result.curve(samples)[:, 2] - reference(samples)[:, 2])
    assert float(gap.max()) < 0.015
    flat = trajectory.dynamic_com(
        phases,
        durations,
        start,
        end,
        reference=reference,
        reference_times=list(times),
        settings=trajectory.DynamicSettings(vertical_tracking_weight=10.0),
    )
    assert flat is not None
    assert float(np.abs(flat.curve(samples)[:, 2] - reference(samples)[:, 2]).max()) > 0.015


def test_a_window_found_again_joins_its_neighbours_c2() -> None:
    """``before`` / ``after``: phases 3-4 of a walk found again slower, between segments 2
    and 5 of the earlier answer, start and end on them with the same velocity and
    acceleration and pass Eq. 1; a segment that does not meet ``start`` is refused."""
    phases, durations, start, end = _walk(7, 0.3, 0.1)
    first = trajectory.dynamic_com(phases, durations, start, end)
    assert first is not None and first.valid
    before, after = first.curve.segments[2], first.curve.segments[5]
    slower = [1.5 * x for x in durations[3:5]]
    window = trajectory.dynamic_com(
        phases[3:5],
        slower,
        before.control_points[-1],
        after.control_points[0],
        before=before,
        after=after,
    )
    assert window is not None and window.valid
    head, tail = window.curve.segments[0], window.curve.segments[-1]
    for order in (0, 1, 2):
        for left, right in ((before, head), (tail, after)):
            a = left.derivative(order)(left.t1) if order else left(left.t1)
            b = right.derivative(order)(right.t0) if order else right(right.t0)
            np.testing.assert_allclose(a, b, atol=1e-5 * (1 + np.abs(a).max()))
    np.testing.assert_allclose(window.phase_times, np.concatenate([[0], np.cumsum(slower)]))
    with pytest.raises(ValueError, match="start"):
        trajectory.dynamic_com(phases[3:5], slower, start, after.control_points[0], before=before)


def test_rows_left_out_until_needed_give_the_answer_of_the_qp_with_every_row(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``lazy_rows``: a kinematic wall the free curve would cross (y <= 4 mm; it sways
    8.5 mm) enters the QP once an answer crosses it. A round's answer that crosses it is
    only the next round's linearisation point, the wall's rows then in its QP; an answer
    kept as a curve satisfies every row of the whole QP to 1e-6 and its control points are
    those of the whole QP solved at once to 1e-6 m. The final curve passes Eq. 1, the wall
    holds along it, and it lies within 2 mm of the curve found with every row from the
    start (the rounds linearise at other points on the way)."""
    phases, durations, start, end = _walk(5, 0.4, 0.15)
    wall = Halfspaces(np.array([[0.0, 1.0, 0.0]]), np.array([0.004]))
    solves: list[tuple[tuple[Any, ...], Any, Any, bool, bool]] = []
    original = trajectory.dynamic._solve_lazy

    def recording(*args: Any, settle: bool = True) -> Any:
        x, working, certificate, unsettled = original(*args, settle=settle)
        solves.append((args, x, working, settle, unsettled is None))
        return x, working, certificate, unsettled

    monkeypatch.setattr(trajectory.dynamic, "_solve_lazy", recording)
    lazy = trajectory.dynamic_com(phases, durations, start, end, kinematics=[wall] * 5)
    monkeypatch.undo()
    every = trajectory.dynamic_com(
        phases,
        durations,
        start,
        end,
        kinematics=[wall] * 5,
        settings=trajectory.DynamicSettings(lazy_rows=False),
    )
    assert lazy is not None and lazy.valid and every is not None
    n_curve = 5 * (trajectory.DynamicSettings().degree + 1) * 3
    added = unsettled = 0
    for args, x, used, settle, complete in solves:
        n, p, q, a_eq, b_eq, curve_rows, margins, margin_rhs, working = args
        assert x is not None
        every_row = np.ones(curve_rows.size, dtype=bool)
        rows, bounds = curve_rows.rows(every_row)
        np.testing.assert_allclose(curve_rows.excess(x), rows @ x - bounds, atol=1e-12)
        np.testing.assert_allclose(a_eq @ x, b_eq, atol=1e-6)
        added += int(used.sum() - working.sum())
        if not complete:  # the rows it breaks are in the next round's QP
            assert not settle
            unsettled += 1
            broken = curve_rows.excess(x) > trajectory.dynamic.LAZY_ROW_TOLERANCE
            assert np.any(broken & ~working) and np.all(used[broken])
            continue
        a_in = sparse.vstack([rows, margins])
        b_in = np.concatenate([bounds, margin_rhs])
        assert float(np.max(a_in @ x - b_in)) <= 1e-6
        whole, certificate = trajectory.dynamic._solve(n, p, q, a_eq, b_eq, a_in, b_in)
        assert whole is not None and certificate is None
        np.testing.assert_allclose(x[:n_curve], whole[:n_curve], atol=1e-6)
    assert added > 0 and unsettled > 0  # the wall's rows did enter, after the first round
    assert solves[-1][4]  # the answer kept keeps every row
    for a, b in zip(lazy.curve.segments, every.curve.segments, strict=True):
        np.testing.assert_allclose(a.control_points, b.control_points, atol=2e-3)
    y = lazy.curve(np.linspace(0, lazy.curve.t1, 300))[:, 1]
    assert y.max() <= 0.004 + trajectory.dynamic.KINEMATIC_SLACK + 1e-9
    assert y.max() > 0.004  # the wall binds


def test_rows_left_out_still_make_an_infeasible_qp_infeasible() -> None:
    """A ceiling 5 cm below the start (a row left out at first): None, as with every row."""
    phases, durations, start, end = _walk(5, 0.4, 0.15)
    ceiling = Halfspaces(np.array([[0.0, 0.0, 1.0]]), np.array([HEIGHT - 0.05]))
    for lazy_rows in (True, False):
        settings = trajectory.DynamicSettings(lazy_rows=lazy_rows)
        assert (
            trajectory.dynamic_com(
                phases, durations, start, end, kinematics=[ceiling] * 5, settings=settings
            )
            is None
        )


def _first_rounds(
    monkeypatch: pytest.MonkeyPatch, share: float
) -> tuple[trajectory.DynamicCom | None, list[tuple[Any, Any, bool]]]:
    """The wall walk of the lazy-row test solved near a reference (the curve found without
    the wall, swaying 8.5 mm across it) with ``PREDICTED_ROW_SHARE`` at ``share``; per
    :func:`_solve_lazy` call, its curve rows, the rows it started with and whether its
    answer kept every row."""
    phases, durations, start, end = _walk(5, 0.4, 0.15)
    free = trajectory.dynamic_com(phases, durations, start, end)
    assert free is not None
    wall = Halfspaces(np.array([[0.0, 1.0, 0.0]]), np.array([0.004]))
    calls: list[tuple[Any, Any, bool]] = []
    original = trajectory.dynamic._solve_lazy

    def recording(*args: Any, settle: bool = True) -> Any:
        out = original(*args, settle=settle)
        calls.append((args[5], args[-1].copy(), out[3] is None))
        return out

    monkeypatch.setattr(trajectory.dynamic, "_solve_lazy", recording)
    monkeypatch.setattr(trajectory.dynamic, "PREDICTED_ROW_SHARE", share)
    found = trajectory.dynamic_com(
        phases,
        durations,
        start,
        end,
        kinematics=[wall] * 5,
        reference=free.curve,
        reference_times=list(free.phase_times),
    )
    monkeypatch.undo()
    return found, calls


def test_kinematic_rows_near_the_reference_are_in_the_first_round(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``PREDICTED_ROW_DEPTH``: the wall's rows, which the reference comes within 5 cm of,
    are in the first round's QP (no trust box row is), and its answer keeps every row: no
    round only adds them. Left out (``PREDICTED_ROW_SHARE`` 0: too many to predict), the
    first answer crosses the wall and is only a linearisation point. Either curve passes
    Eq. 1 and holds the wall."""
    predicted, calls = _first_rounds(monkeypatch, trajectory.dynamic.PREDICTED_ROW_SHARE)
    curve_rows, first, complete = calls[0]
    per = curve_rows.points * 3
    kinematic = np.ones(curve_rows.size, dtype=bool)
    for offset in curve_rows.offsets[:-1]:
        kinematic[offset : offset + 2 * per] = False
    assert np.array_equal(first, kinematic)  # every wall row, no box row
    assert complete
    lazy, lazy_calls = _first_rounds(monkeypatch, 0.0)
    assert not lazy_calls[0][1].any() and not lazy_calls[0][2]
    assert len(calls) < len(lazy_calls)
    for found in (predicted, lazy):
        assert found is not None and found.valid
        y = found.curve(np.linspace(0, found.curve.t1, 300))[:, 1]
        assert y.max() <= 0.004 + trajectory.dynamic.KINEMATIC_SLACK + 1e-9


def _unrefined_runs_replaced(
    monkeypatch: pytest.MonkeyPatch, replaced: Callable[[Any], Any]
) -> list[bool]:
    """Clarabel's solver made to answer its unrefined runs with ``replaced(solution)`` (the
    run's real solution in, a stand-in out); the list it returns records, run by run,
    whether the run was refined."""
    real = trajectory.dynamic.clarabel.DefaultSolver
    runs: list[bool] = []

    class Solver:
        def __init__(self, *args: Any) -> None:
            self.refine = bool(args[-1].iterative_refinement_enable)
            self.solver = real(*args)

        def solve(self) -> Any:
            runs.append(self.refine)
            solution = self.solver.solve()
            return solution if self.refine else replaced(solution)

    monkeypatch.setattr(trajectory.dynamic.clarabel, "DefaultSolver", Solver)
    return runs


def test_a_run_without_refinement_that_does_not_settle_is_run_again_refined(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Clarabel's unrefined run stopping for lack of progress far from an answer: the QP is
    solved again with refinement, and the answer is the one a refined run gives."""
    phases, durations, start, end = _walk(3, 0.4, 0.15)
    clarabel = trajectory.dynamic.clarabel

    class Unsettled:  # stopped far from an answer
        status = clarabel.SolverStatus.InsufficientProgress
        x = ()
        r_prim = r_dual = 1e-3
        obj_val, obj_val_dual = 1.0, 2.0

    runs = _unrefined_runs_replaced(monkeypatch, lambda solution: Unsettled())
    retried = trajectory.dynamic_com(phases, durations, start, end)
    monkeypatch.undo()
    monkeypatch.setattr(trajectory.dynamic, "SOLVER_REFINEMENT", True)
    refined = trajectory.dynamic_com(phases, durations, start, end)
    assert runs[:2] == [False, True] and retried is not None and refined is not None
    for a, b in zip(retried.curve.segments, refined.curve.segments, strict=True):
        np.testing.assert_array_equal(a.control_points, b.control_points)


def test_a_run_at_the_iteration_cap_is_not_repeated(monkeypatch: pytest.MonkeyPatch) -> None:
    """Clarabel's run reaching ``SOLVER_MAX_ITERATIONS`` far from an answer: no second,
    refined run of the same QP, no curve; every run is capped at that count."""
    phases, durations, start, end = _walk(3, 0.4, 0.15)
    clarabel = trajectory.dynamic.clarabel
    real = clarabel.DefaultSolver
    caps: list[int] = []

    class Capped:  # stopped far from an answer
        status = clarabel.SolverStatus.MaxIterations
        x = ()
        r_prim = r_dual = 1e-3
        obj_val, obj_val_dual = 1.0, 2.0

    class Solver:
        def __init__(self, *args: Any) -> None:
            caps.append(int(args[-1].max_iter))
            self.solver = real(*args)

        def solve(self) -> Any:
            self.solver.solve()
            return Capped()

    monkeypatch.setattr(clarabel, "DefaultSolver", Solver)
    assert trajectory.dynamic_com(phases, durations, start, end) is None
    assert caps == [trajectory.dynamic.SOLVER_MAX_ITERATIONS]


def test_a_run_that_stalls_within_the_reduced_tolerance_is_taken_without_a_refined_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Clarabel's unrefined run ending AlmostSolved (its progress stalled after meeting
    ``REDUCED_TOLERANCE``, as the climbing wall's whole-plan QPs do): its answer is the
    curve, with no second, refined run; every run asks the reduced tolerances of the
    module."""
    phases, durations, start, end = _walk(3, 0.4, 0.15)
    clarabel = trajectory.dynamic.clarabel
    real = clarabel.DefaultSolver
    runs: list[tuple[bool, float, float]] = []

    class Stalled:
        def __init__(self, solution: Any) -> None:
            self.status = clarabel.SolverStatus.AlmostSolved
            self.x = solution.x

    class Solver:
        def __init__(self, *args: Any) -> None:
            settings = args[-1]
            runs.append(
                (
                    bool(settings.iterative_refinement_enable),
                    float(settings.reduced_tol_gap_abs),
                    float(settings.reduced_tol_feas),
                )
            )
            self.solver = real(*args)

        def solve(self) -> Any:
            return Stalled(self.solver.solve())

    monkeypatch.setattr(clarabel, "DefaultSolver", Solver)
    stalled = trajectory.dynamic_com(phases, durations, start, end)
    monkeypatch.undo()
    solved = trajectory.dynamic_com(phases, durations, start, end)
    reduced = trajectory.dynamic.REDUCED_TOLERANCE
    assert stalled is not None and solved is not None
    assert runs and all(run == (False, reduced, reduced) for run in runs)
    assert len(runs) == stalled.iterations  # one run per linearisation round, none refined
    for a, b in zip(stalled.curve.segments, solved.curve.segments, strict=True):
        np.testing.assert_array_equal(a.control_points, b.control_points)


def test_the_curve_rows_are_the_box_then_the_kinematic_rows_in_order() -> None:
    """``_CurveRows`` row by row: per phase the trust box (x <= high, then -x <= -low), then
    each control point's reachable kinematic rows; any selection of them is those rows in
    order (canonical CSR: sorted columns, no duplicates), and ``excess`` is each row's
    left side less its bound. The weights' margins are -beta <= -margin, one per weight."""
    from trajectory import dynamic

    phases, _, start, _ = _walk(3, 0.6, 0.4)
    d, samples = 5, 4
    layout = dynamic._Layout(phases, d, [samples] * len(phases))
    rng = np.random.default_rng(2)
    normals = rng.normal(size=(6, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # six rows near the start, three out of the trust box's reach
    far = -normals[:3]
    kin = Halfspaces(
        np.vstack([normals, far]), np.concatenate([normals @ start + 0.05, far @ start + 2.0])
    )
    kins = [kin, None, kin]
    boxes = [start + rng.normal(0.0, 0.05, (samples, 3)) for _ in phases]
    curve_rows = dynamic._CurveRows(layout, d, kins, boxes)
    expected: list[np.ndarray] = []
    bounds: list[float] = []
    for j, kin_j in enumerate(kins):
        low = boxes[j].min(axis=0) - dynamic.TRUST_RADIUS
        high = boxes[j].max(axis=0) + dynamic.TRUST_RADIUS
        for sign, edge in ((1.0, high), (-1.0, -low)):
            for i in range(d + 1):
                for axis in range(3):
                    row = np.zeros(layout.n)
                    row[layout.point(j, i) + axis] = sign
                    expected.append(row)
                    bounds.append(float(edge[axis]))
        if kin_j is None:
            continue
        centre, half = 0.5 * (low + high), 0.5 * (high - low)
        keep = kin_j.A @ centre + np.abs(kin_j.A) @ half > kin_j.b + dynamic.KINEMATIC_SLACK
        assert 0 < keep.sum() < keep.size  # some rows out of the box's reach, some not
        for i in range(d + 1):
            for a, b in zip(kin_j.A[keep], kin_j.b[keep], strict=True):
                row = np.zeros(layout.n)
                row[layout.point(j, i) : layout.point(j, i) + 3] = a
                expected.append(row)
                bounds.append(float(b + dynamic.KINEMATIC_SLACK))
    whole, whole_b = np.array(expected), np.array(bounds)
    assert curve_rows.size == len(expected)
    x = rng.normal(size=layout.n)
    np.testing.assert_allclose(curve_rows.excess(x), whole @ x - whole_b, atol=1e-12)
    for mask in (
        np.ones(curve_rows.size, dtype=bool),
        rng.random(curve_rows.size) < 0.3,
        np.zeros(curve_rows.size, dtype=bool),
    ):
        rows, rhs = curve_rows.rows(mask)
        assert rows.shape == (int(mask.sum()), layout.n)
        assert np.array_equal(rows.toarray(), whole[mask])
        assert np.array_equal(rhs, whole_b[mask])
        assert rows.has_canonical_format
    margins, margin_rhs = dynamic._margin_rows(layout, 0.002)
    weights = layout.n - layout.n_curve
    assert np.array_equal(
        margins.toarray(), -np.eye(layout.n)[layout.n_curve :]
    ) and np.array_equal(margin_rhs, np.full(weights, -0.002))


@pytest.mark.parametrize(("dual", "taken"), [(5e-8, True), (5e-7, False)])
def test_a_run_that_stalls_near_the_answer_is_taken_only_within_the_stalled_tolerance(
    monkeypatch: pytest.MonkeyPatch, dual: float, taken: bool
) -> None:
    """Clarabel's unrefined run stalling (InsufficientProgress) feasible to
    ``REDUCED_TOLERANCE``: its answer is taken with no refined run when its dual residual is
    within ``STALLED_TOLERANCE`` (5e-8 <= 1e-7), else the QP is solved again refined."""
    phases, durations, start, end = _walk(3, 0.4, 0.15)
    clarabel = trajectory.dynamic.clarabel

    class Stalled:
        def __init__(self, solution: Any) -> None:
            self.status = clarabel.SolverStatus.InsufficientProgress
            self.x = solution.x
            self.obj_val, self.obj_val_dual = solution.obj_val, solution.obj_val_dual
            self.r_prim, self.r_dual = 1e-9, dual

    runs = _unrefined_runs_replaced(monkeypatch, Stalled)
    stalled = trajectory.dynamic_com(phases, durations, start, end)
    assert stalled is not None
    assert (True in runs) is not taken
    if taken:
        assert len(runs) == stalled.iterations  # one run per linearisation round


@pytest.mark.parametrize("far", [3, 5])
def test_an_infeasible_qp_blames_the_phase_whose_contacts_cannot_carry_the_curve(
    far: int,
) -> None:
    """A walk of 7 phases whose single-support phase ``far`` stands on a foot 1 m to the
    side (out of the trust box's reach): no curve, and Clarabel's certificate puts most of
    its weight on that phase's Eq. 1 rows; a feasible walk blames nothing."""
    phases, durations, start, end = _walk(7, 0.4, 0.15)
    outcome = trajectory.solve_dynamic_com(phases, durations, start, end)
    assert outcome.com is not None and outcome.com.valid and outcome.blame is None
    aside = patch(np.array([0.3, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), half=0.08)
    phases[far] = trajectory.ContactPhase([aside])
    outcome = trajectory.solve_dynamic_com(phases, durations, start, end)
    assert outcome.com is None and outcome.blame is not None
    assert outcome.blame.shape == (7,)
    np.testing.assert_allclose(outcome.blame.sum(), 1.0)
    assert int(np.argmax(outcome.blame)) == far
    assert outcome.blame[far] > 0.5


def test_sample_spacing_gives_a_short_phase_fewer_collocation_times() -> None:
    """``sample_spacing``: as many samples as that spacing takes, ``MIN_PHASE_SAMPLES`` at
    least and ``samples`` at most; 0 keeps ``samples`` for every phase; negative is refused."""
    spaced = trajectory.DynamicSettings(sample_spacing=0.01)
    assert spaced.phase_samples(0.04) == 5
    assert spaced.phase_samples(0.05) == 6
    assert spaced.phase_samples(0.001) == trajectory.dynamic.MIN_PHASE_SAMPLES
    assert spaced.phase_samples(0.5) == spaced.samples
    assert trajectory.DynamicSettings().phase_samples(0.04) == 12
    with pytest.raises(ValueError, match="sample_spacing"):
        trajectory.DynamicSettings(sample_spacing=-0.01)


def test_a_walk_sampled_by_spacing_passes_eq1_at_its_own_collocation_times() -> None:
    """A brisk walk of short phases (0.05 s shifts) sampled every 10 ms: a smaller QP (fewer
    generator weights) whose curve passes Eq. 1 at each phase's own collocation times, keeps
    its ends at rest and stays within 2 cm of the curve sampled 12 times per phase (the same
    cost, taken at 12 times per phase either way)."""
    phases, durations, start, end = _walk(7, 0.3, 0.05)
    settings = trajectory.DynamicSettings(sample_spacing=0.01)
    spaced = trajectory.dynamic_com(phases, durations, start, end, settings=settings)
    dense = trajectory.dynamic_com(phases, durations, start, end)
    assert spaced is not None and spaced.valid and dense is not None and dense.valid
    counts = [settings.phase_samples(d) for d in durations]
    assert sum(counts) < 12 * len(durations)
    for phase, t0, t1, count in zip(
        phases, spaced.phase_times[:-1], spaced.phase_times[1:], counts, strict=True
    ):
        times = np.linspace(t0, t1, count)
        holds, _ = trajectory.holds_at(
            phase, spaced.curve(times), spaced.curve.derivative(2)(times)
        )
        assert holds.all()
    curve = spaced.curve
    np.testing.assert_allclose(curve(curve.t0), start, atol=1e-6)
    np.testing.assert_allclose(curve(curve.t1), end, atol=1e-6)
    grid = np.linspace(curve.t0, curve.t1, 200)
    assert float(np.max(np.linalg.norm(curve(grid) - dense.curve(grid), axis=1))) < 0.02


def _walk_with_a_wall() -> tuple[
    list[trajectory.ContactPhase], list[float], np.ndarray, np.ndarray, list[Halfspaces | None]
]:
    """A 17-phase walk whose phase 8 has a kinematic wall y <= 2 mm (none elsewhere)."""
    phases, durations, start, end = _walk(17, 0.4, 0.15)
    kinematics: list[Halfspaces | None] = [None] * 17
    kinematics[8] = Halfspaces(np.array([[0.0, 1.0, 0.0]]), np.array([0.002]))
    return phases, durations, start, end, kinematics


def test_a_qp_below_the_repair_size_is_solved_again_whole(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Below ``REPAIR_MIN_VARIABLES`` (the walk with a wall: about 5,000 variables) a failing
    round is followed by a round of the whole QP, never a window."""
    phases, durations, start, end, kinematics = _walk_with_a_wall()
    sizes: list[int] = []
    solve = trajectory.dynamic._solve

    def recording_solve(n: int, *args: Any) -> Any:
        sizes.append(n)
        return solve(n, *args)

    monkeypatch.setattr(trajectory.dynamic, "_solve", recording_solve)
    found = trajectory.dynamic_com(phases, durations, start, end, kinematics=kinematics)
    assert found is not None and found.valid
    assert len(sizes) == 2 and sizes[0] == sizes[1] < trajectory.dynamic.REPAIR_MIN_VARIABLES


def test_failing_phases_are_solved_again_in_windows_the_rest_of_the_curve_kept(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``local_repair``: a kinematic wall in phase 8 of 17 (y <= 2 mm, a row left out at
    first) that the first answer crosses is repaired by solving phases 5 to 11 again, joined
    C2 to the first answer's phases on both sides, which are kept as they were: one QP of the
    whole curve instead of two. The curve passes Eq. 1 (in the window between its collocation
    times too), holds the wall and is C2."""
    phases, durations, start, end, kinematics = _walk_with_a_wall()
    sizes: list[int] = []
    answers: list[trajectory.PiecewiseBezier] = []
    solve, curve_of = trajectory.dynamic._solve, trajectory.dynamic._curve

    def recording_solve(n: int, *args: Any) -> Any:
        sizes.append(n)
        return solve(n, *args)

    def recording_curve(layout: Any, *args: Any) -> Any:
        made = curve_of(layout, *args)
        if layout.n_phases == 17:
            answers.append(made)
        return made

    monkeypatch.setattr(trajectory.dynamic, "_solve", recording_solve)
    monkeypatch.setattr(trajectory.dynamic, "_curve", recording_curve)
    monkeypatch.setattr(trajectory.dynamic, "REPAIR_MIN_VARIABLES", 0)  # a small QP here
    repaired = trajectory.dynamic_com(phases, durations, start, end, kinematics=kinematics)
    whole_rounds = trajectory.dynamic_com(
        phases,
        durations,
        start,
        end,
        kinematics=kinematics,
        settings=trajectory.DynamicSettings(local_repair=False),
    )
    monkeypatch.undo()
    assert repaired is not None and repaired.valid
    assert whole_rounds is not None and whole_rounds.valid
    whole = max(sizes)
    first_run = sizes[: len(sizes) - 2]  # the run without repair solved the whole QP twice
    assert sizes[-2:] == [whole, whole] and first_run.count(whole) == 1
    assert all(n < whole for n in first_run[1:])  # the window's QPs
    first = answers[0]
    for j, segment in enumerate(repaired.curve.segments):
        if j < 5 or j > 11:
            np.testing.assert_array_equal(segment.control_points, first.segments[j].control_points)
    dense = trajectory.validate_dynamics(repaired.curve, phases, repaired.phase_times)
    assert all(report.fraction_valid == 1.0 for report in dense[5:12])  # between samples too
    y = repaired.curve(np.linspace(repaired.phase_times[8], repaired.phase_times[9], 50))[:, 1]
    assert y.max() <= 0.002 + trajectory.dynamic.KINEMATIC_SLACK + 1e-9
    _assert_c2(repaired.curve)


@pytest.mark.parametrize(
    ("failing", "n", "windows"),
    [
        ([7, 9, 13], 125, [(4, 17)]),
        ([0], 10, [(0, 4)]),
        ([9], 10, [(6, 10)]),
        ([1, 10], 20, [(0, 5), (7, 14)]),
        ([2, 9], 20, [(0, 13)]),  # (0, 6) and (6, 13) touch: one window
        ([], 20, []),
    ],
)
def test_repair_windows_reach_three_phases_each_side_and_merge_when_they_meet(
    failing: list[int], n: int, windows: list[tuple[int, int]]
) -> None:
    assert trajectory.dynamic._repair_windows(failing, n) == windows


@pytest.mark.parametrize(
    ("bad", "broken", "expected", "scanned"),
    [
        ({3}, [], [3], 40),
        ({3}, [20], [3, 20], 40),  # windows (0, 7) and (17, 24)
        ({2, 5, 8}, [], [2, 5, 8], 40),  # (0, 12)
        ({2, 5, 8, 11, 14, 17}, [], None, 18),  # (0, 21): over half of 40, the scan stops
    ],
)
def test_the_failing_phases_are_found_until_their_windows_would_cover_half(
    monkeypatch: pytest.MonkeyPatch,
    bad: set[int],
    broken: list[int],
    expected: list[int] | None,
    scanned: int,
) -> None:
    checked: list[int] = []

    def passes(phase: Any, sample: Any, weights: Any) -> bool:
        checked.append(phase)
        return phase not in bad

    monkeypatch.setattr(trajectory.dynamic, "_passes", passes)
    phases: list[Any] = list(range(40))
    samples: list[Any] = [None] * 40
    assert trajectory.dynamic._failing_phases(phases, samples, samples, broken) == expected
    assert len(checked) == scanned - len([j for j in broken if j < scanned])
