"""Dynamic COM curves: a C2 piecewise Bezier COM over given phase durations whose
gravito-inertial wrench lies in each phase's contact wrench cone (2PAC Eq. 1) at
collocation times, so the COM may move as fast as the contacts allow instead of staying
in static equilibrium.

Eq. 1 with zero angular momentum rate: G_j' beta = w(c, a) = [m (a - g), c x m (a - g)],
beta >= 0 (generator weights). The force rows are linear in the control points; the torque
c x m (a - g) is bilinear, so it is linearised about the previous iterate (c_, a_):
c x a ~= c_ x a + c x a_ - c_ x a_, and the convex QP is solved again about its answer
(sequential convex programming). Weights carry a margin (a fraction of the body weight per
generator) that absorbs the linearisation error; the answer is accepted only when the exact
Eq. 1 holds at every collocation time (checked with the same robustness LP as
``validate_dynamics``).

Units: metres, seconds, world frame z up; weights are in body weights (m g) for
conditioning. The QP is sparse and solved by Clarabel (interior point, deterministic). The
rows on the curve alone (trust box, kinematics: most of the QP's rows, and hardly ever
binding) enter it only once an answer breaks one of them (``DynamicSettings.lazy_rows``):
the same optimum from a QP a few times smaller.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import clarabel
import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from trajectory._types import GRAVITY, BoolArray, FloatArray, as_float_array
from trajectory.bezier import BezierCurve, PiecewiseBezier, bernstein
from trajectory.contacts import ContactPhase
from trajectory.equilibrium import equilibrium_margin
from trajectory.polytope import Halfspaces


@dataclass(frozen=True, slots=True)
class DynamicSettings:
    """Tuning of the dynamic COM QP.

    degree : Bezier degree of each phase's segment (>= 5: C2 joins and rest ends leave
        free points). samples : collocation times per phase, both ends included.
    iterations : linearisation rounds at most. margin : smallest generator weight, in body
        weights, while solving (robustness to the linearisation and between samples).
    acceleration_weight : cost of the squared acceleration (s^4 per phase second).
    tracking_weight : cost of the squared horizontal distance to the reference curve
        (1/m^2). vertical_tracking_weight : the same for the height. The reference's
        height is one a body can stand at, the kinematic polytopes allow more than legs
        with the arms down give: at the horizontal weight a walk's curve stayed 4.5 cm
        above what the legs reach in double support, and the body raised an arm to follow.
    force_weight : cost of the squared generator weights (spreads the force over contacts).
    lazy_rows : the inequality rows on the curve alone (trust box, kinematics) enter the QP
        only once an answer breaks one of them (the same optimum, a smaller QP); False puts
        them all in from the start (for comparisons).
    """

    degree: int = 7
    samples: int = 12
    iterations: int = 4
    margin: float = 1e-3
    acceleration_weight: float = 1.0
    tracking_weight: float = 10.0
    vertical_tracking_weight: float = 1e4
    force_weight: float = 1e-2
    lazy_rows: bool = True

    def __post_init__(self) -> None:
        if self.degree < 5:
            raise ValueError(f"degree: at least 5 is needed, got {self.degree}")
        if self.samples < 2:
            raise ValueError(f"samples: at least 2 are needed, got {self.samples}")
        if self.iterations < 1:
            raise ValueError(f"iterations: at least 1 is needed, got {self.iterations}")


@dataclass(frozen=True, slots=True, eq=False)
class DynamicCom:
    """A dynamically consistent COM: ``curve`` (one segment per phase), ``phase_times``
    (n + 1,) s, ``iterations`` used, and ``valid`` True when Eq. 1 held exactly at every
    collocation time of the last iterate."""

    curve: PiecewiseBezier
    phase_times: FloatArray
    iterations: int
    valid: bool


def _second_difference(degree: int) -> FloatArray:
    """(degree - 1, degree + 1) map from control points to second-derivative points
    (without the degree (degree - 1) / T^2 factor)."""
    out = np.zeros((degree - 1, degree + 1))
    for k in range(degree - 1):
        out[k, k : k + 3] = (1.0, -2.0, 1.0)
    return out


def _skews(u: FloatArray) -> FloatArray:
    """(k, 3, 3) cross-product matrices [u_i]x of the rows of ``u`` (k, 3)."""
    out = np.zeros((u.shape[0], 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -u[:, 2], u[:, 1]
    out[:, 1, 0], out[:, 1, 2] = u[:, 2], -u[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -u[:, 1], u[:, 0]
    return out


class _Layout:
    """Variable layout: control points of every phase (phase, point, xyz), then the
    generator weights of every collocation sample."""

    def __init__(self, phases: Sequence[ContactPhase], degree: int, samples: int) -> None:
        self.n_phases = len(phases)
        self.points = degree + 1
        self.n_curve = self.n_phases * self.points * 3
        self.weights_at: list[list[int]] = []
        offset = self.n_curve
        for phase in phases:
            m = phase.wrench_generators.shape[0]
            row = []
            for _ in range(samples):
                row.append(offset)
                offset += m
            self.weights_at.append(row)
        self.n = offset

    def point(self, phase: int, index: int) -> int:
        """Index of the x coordinate of control point ``index`` of ``phase``."""
        return (phase * self.points + index) * 3


def dynamic_com(
    phases: Sequence[ContactPhase],
    durations: Sequence[float],
    start: FloatArray,
    end: FloatArray,
    *,
    kinematics: Sequence[Halfspaces | None] | None = None,
    reference: PiecewiseBezier | None = None,
    reference_times: Sequence[float] | None = None,
    settings: DynamicSettings | None = None,
    before: BezierCurve | None = None,
    after: BezierCurve | None = None,
) -> DynamicCom | None:
    """A C2 COM from ``start`` to ``end`` (3,), at rest at both, phase j lasting
    durations[j] s, whose wrench lies in phase j's contact cone at ``settings.samples``
    times of the phase and whose position satisfies ``kinematics[j]`` there. The curve
    stays near ``reference`` (or None), whose phase j spans reference_times[j] to
    reference_times[j + 1] (n + 1 times, s; the reference is compared phase by phase at the
    same fractions of each phase). None when a
    QP is infeasible; ``valid`` False when the linearisation did not settle into an exactly
    valid curve within ``settings.iterations`` rounds. ``before`` / ``after`` : segments (of
    the same degree) the curve joins C2 instead of starting / ending at rest: it starts where
    ``before`` ends (``start`` must be that point) and ends where ``after`` starts (``end``
    likewise); its times still start at 0 (a window of a longer curve, shifted by the
    caller)."""
    settings = settings or DynamicSettings()
    phases = list(phases)
    if not phases:
        raise ValueError("phases: at least one contact phase is needed")
    times = np.concatenate([[0.0], np.cumsum(np.asarray(durations, dtype=np.float64))])
    if len(durations) != len(phases) or not np.all(np.diff(times) > 0):
        raise ValueError("durations: one positive duration per phase is needed")
    c0 = as_float_array(start, (3,), "start")
    c1 = as_float_array(end, (3,), "end")
    kins = list(kinematics) if kinematics is not None else [None] * len(phases)
    if len(kins) != len(phases):
        raise ValueError("kinematics: one entry per phase is needed")
    d = settings.degree
    layout = _Layout(phases, d, settings.samples)
    u = np.linspace(0.0, 1.0, settings.samples)
    basis = bernstein(d, u)  # (samples, d + 1)
    basis2 = bernstein(d - 2, u) @ _second_difference(d) * d * (d - 1)

    sample_times = [times[j] + u * (times[j + 1] - times[j]) for j in range(len(phases))]
    all_times = np.concatenate(sample_times)
    per_phase = [slice(j * u.size, (j + 1) * u.size) for j in range(len(phases))]
    targets: list[FloatArray] | None = None
    if reference is not None:
        if reference_times is None or len(reference_times) != len(phases) + 1:
            raise ValueError("reference_times: one time per phase boundary is needed")
        rt = np.asarray(reference_times, dtype=np.float64)
        targets = [
            reference(np.clip(rt[j] + u * (rt[j + 1] - rt[j]), reference.t0, reference.t1))
            for j in range(len(phases))
        ]
        lin = [(t, np.zeros_like(t)) for t in targets]
    else:
        line = [c0 + (ts / times[-1])[:, None] * (c1 - c0) for ts in sample_times]
        lin = [(t, np.zeros_like(t)) for t in line]
    boxes = [c for c, _ in lin]
    durations_arr = np.diff(times)
    head = _join_points(before, float(durations_arr[0]), d, c0, at_end=False)
    tail = _join_points(after, float(durations_arr[-1]), d, c1, at_end=True)
    eq_rows, eq_rhs, in_rows, in_rhs = _fixed_rows(layout, times, head, tail, d, kins, boxes)
    in_rhs = np.concatenate([in_rhs, np.full(layout.n - layout.n_curve, -settings.margin)])
    # the rows before the weights' margins are on the curve alone (trust box, kinematics)
    lazy = np.arange(in_rhs.size) < in_rhs.size - (layout.n - layout.n_curve)
    working = ~lazy if settings.lazy_rows else np.ones_like(lazy)
    cost_p, cost_q = _cost(layout, times, basis, basis2, settings, targets)
    result: DynamicCom | None = None
    for iteration in range(1, settings.iterations + 1):
        w_rows, w_rhs = _wrench_rows(layout, phases, times, basis, basis2, lin)
        x, working = _solve_lazy(
            layout.n,
            cost_p,
            cost_q,
            sparse.vstack([eq_rows, w_rows]),
            np.concatenate([eq_rhs, w_rhs]),
            in_rows,
            in_rhs,
            working,
        )
        if x is None:
            return result
        curve = _curve(layout, x, times, d)
        # every phase's samples in one evaluation of each curve (the same points as phase
        # by phase: a sample on a break is the later segment's either way)
        positions, accelerations = curve(all_times), curve.derivative(2)(all_times)
        lin = [(positions[k], accelerations[k]) for k in per_phase]
        valid = all(
            equilibrium_margin(phase, c, a).feasible
            for phase, (cs, accs) in zip(phases, lin, strict=True)
            for c, a in zip(cs, accs, strict=True)
        )
        result = DynamicCom(curve, times, iteration, valid)
        if valid:
            return result
    return result


def _fixed_rows(
    layout: _Layout,
    times: FloatArray,
    head: FloatArray,
    tail: FloatArray,
    d: int,
    kins: Sequence[Halfspaces | None],
    boxes: Sequence[FloatArray],
) -> tuple[sparse.csr_matrix, FloatArray, sparse.csr_matrix, FloatArray]:
    """Equalities (the first three control points ``head`` (3, 3), the last three ``tail``
    (3, 3, last first), C0/C1/C2 joins) and inequalities (kinematics, then the weight margin
    -beta <= -margin whose right-hand side the caller appends)."""
    rows: list[dict[int, float]] = []
    rhs: list[float] = []
    n_last = layout.n_phases - 1
    for axis in range(3):
        for index in range(3):
            rows.append({layout.point(0, index) + axis: 1.0})
            rhs.append(float(head[index, axis]))
            rows.append({layout.point(n_last, d - index) + axis: 1.0})
            rhs.append(float(tail[index, axis]))
    for j in range(layout.n_phases - 1):
        ta, tb = times[j + 1] - times[j], times[j + 2] - times[j + 1]
        for axis in range(3):
            a = [layout.point(j, d - k) + axis for k in range(3)]  # P_d, P_d-1, P_d-2
            b = [layout.point(j + 1, k) + axis for k in range(3)]  # Q_0, Q_1, Q_2
            rows.append({a[0]: 1.0, b[0]: -1.0})
            rhs.append(0.0)
            # velocity: (P_d - P_d-1) / ta = (Q_1 - Q_0) / tb
            rows.append({a[0]: 1.0 / ta, a[1]: -1.0 / ta, b[1]: -1.0 / tb, b[0]: 1.0 / tb})
            rhs.append(0.0)
            # acceleration: (P_d - 2 P_d-1 + P_d-2) / ta^2 = (Q_2 - 2 Q_1 + Q_0) / tb^2
            rows.append(
                {
                    a[0]: 1.0 / ta**2,
                    a[1]: -2.0 / ta**2,
                    a[2]: 1.0 / ta**2,
                    b[2]: -1.0 / tb**2,
                    b[1]: 2.0 / tb**2,
                    b[0]: -1.0 / tb**2,
                }
            )
            rhs.append(0.0)
    eq = _matrix(rows, layout.n)
    # each phase's control points stay in a box around its reference (trust region);
    # kinematics hold on the control points (the curve lies in their convex hull, so along
    # the whole phase, a little conservative), keeping only the rows the box can reach;
    # KINEMATIC_SLACK absorbs round-off of the states' own COMs on the boundary
    # built directly in CSR form: rows in order, each row's columns increasing (a box row
    # has one entry, a kinematic row the three coordinates of one control point), which is
    # the matrix COO -> CSR made from the same entries (a long window has millions of rows)
    data: list[FloatArray] = []
    ci: list[NDArray[Any]] = []
    counts: list[NDArray[Any]] = []  # entries per row
    bounds: list[FloatArray] = []
    per_phase = (d + 1) * 3
    for j, kin in enumerate(kins):
        low = np.min(boxes[j], axis=0) - TRUST_RADIUS
        high = np.max(boxes[j], axis=0) + TRUST_RADIUS
        cols = np.arange(layout.point(j, 0), layout.point(j, 0) + per_phase)
        for sign in (1.0, -1.0):  # x <= high, -x <= -low
            data.append(np.full(per_phase, sign))
            ci.append(cols)
            counts.append(np.ones(per_phase, dtype=np.int64))
        bounds += [np.tile(high, d + 1), -np.tile(low, d + 1)]
        if kin is None or kin.A.shape[0] == 0:
            continue
        centre, half = 0.5 * (low + high), 0.5 * (high - low)
        reachable = kin.A @ centre + np.abs(kin.A) @ half > kin.b + KINEMATIC_SLACK
        a_rows, b_rows = kin.A[reachable], kin.b[reachable]
        k = a_rows.shape[0]
        if k == 0:
            continue
        # the k rows for each control point in turn: (d + 1) k rows of 3 entries
        data.append(np.tile(a_rows.ravel(), d + 1))
        ci.append(np.repeat(cols.reshape(d + 1, 3), k, axis=0).ravel())
        counts.append(np.full((d + 1) * k, 3, dtype=np.int64))
        bounds += [b_rows + KINEMATIC_SLACK] * (d + 1)
    margin = np.arange(layout.n_curve, layout.n)
    data.append(-np.ones(margin.size))
    ci.append(margin)
    counts.append(np.ones(margin.size, dtype=np.int64))
    per_row = np.concatenate(counts)
    indptr = np.zeros(per_row.size + 1, dtype=np.int64)
    np.cumsum(per_row, out=indptr[1:])
    in_rows = sparse.csr_matrix(
        (np.concatenate(data), np.concatenate(ci), indptr), shape=(per_row.size, layout.n)
    )
    in_rhs = np.concatenate(bounds) if bounds else np.zeros(0)
    return eq, np.asarray(rhs), in_rows, in_rhs


def _join_points(
    segment: BezierCurve | None, duration: float, degree: int, point: FloatArray, at_end: bool
) -> FloatArray:
    """(3, 3) the three control points at one end of the curve (from that end inward) that
    join ``segment`` C2, for an end phase lasting ``duration`` s: at rest at ``point`` when
    ``segment`` is None. ``at_end``: ``segment`` follows the curve (else it precedes it)."""
    if segment is None:
        return np.tile(point, (3, 1))
    ctrl = np.asarray(segment.control_points, dtype=np.float64)
    if ctrl.shape != (degree + 1, 3):
        raise ValueError(f"before/after: a segment of degree {degree} in 3D is needed")
    near = ctrl[:3] if at_end else ctrl[::-1][:3]  # from the shared point outward
    if float(np.linalg.norm(near[0] - point)) > 1e-9:
        raise ValueError("start/end: must be where the joined segment ends/starts")
    ratio = duration / (segment.t1 - segment.t0)
    first = near[0] + ratio * (near[0] - near[1])  # velocity matched (sign: walking inward)
    second = 2.0 * first - near[0] + ratio**2 * (near[2] - 2.0 * near[1] + near[0])
    return np.stack([near[0], first, second])


KINEMATIC_SLACK = 5e-4
"""m: how far the control points may lie outside a phase's kinematic polytope."""

TRUST_RADIUS = 0.25
"""m: how far a phase's control points may leave the box of its reference positions."""

LAZY_ROW_TOLERANCE = 1e-9
"""m: how far an answer may break a row left out of the QP (trust box, kinematics) before
that row is put in and the QP solved again (``DynamicSettings.lazy_rows``)."""

LAZY_ROW_MARGIN = 1e-3
"""m: when a row left out is broken, every row left out that the answer comes within this
of is put in too (fewer rounds; a row that does not bind leaves the optimum as it is)."""

SOLVER_REFINEMENT = False
"""Whether Clarabel first solves with iterative refinement of its KKT solves (its default is
on): off halves the time of a solve, and moved the control points by less than 3e-7 m on the
captured plans' QPs. A run that ends neither solved (to ``SOLVER_TOLERANCE``, or to
``REDUCED_TOLERANCE`` where its progress stalls) nor infeasible is repeated with it on."""

_SETTLED = frozenset(
    {
        clarabel.SolverStatus.Solved,
        clarabel.SolverStatus.AlmostSolved,
        clarabel.SolverStatus.PrimalInfeasible,
        clarabel.SolverStatus.DualInfeasible,
    }
)
"""Clarabel's statuses that are taken as they are (the others are run again refined)."""

_ANSWERED = frozenset({clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved})
"""Clarabel's statuses whose answer is used: solved to ``SOLVER_TOLERANCE``, or to
``REDUCED_TOLERANCE`` when its progress stalled before."""

SOLVER_TOLERANCE = 1e-10
"""Clarabel's gap and feasibility tolerances (its default is 1e-8). At the default the answer
of a QP without its idle rows stopped up to 5e-5 m (control points) from that of the QP with
them; at 1e-10 both are within 2e-6 m of each other on the captured plans' QPs."""

REDUCED_TOLERANCE = 1e-8
"""Clarabel's gap and feasibility tolerances for an answer whose progress stalls before
``SOLVER_TOLERANCE`` (its status then AlmostSolved; Clarabel's own reduced tolerances are
5e-5 and 1e-4): Clarabel's default full accuracy. The climbing wall's whole-plan QPs (80,000
variables) stall so after about 25 iterations without refinement; run again refined they took
twice as long each (2.4 s instead of 1.1 s) for a curve that Eq. 1 passes either way."""


def _wrench_rows(
    layout: _Layout,
    phases: Sequence[ContactPhase],
    times: FloatArray,
    basis: FloatArray,
    basis2: FloatArray,
    lin: Sequence[tuple[FloatArray, FloatArray]],
) -> tuple[sparse.csr_matrix, FloatArray]:
    """Eq. 1 at every collocation sample, linearised about ``lin`` (per phase, the sample
    positions and accelerations), in body weights: G' beta - w_lin(c, a) = w_const; six rows
    per sample, phase by phase."""
    data: list[FloatArray] = []
    ri: list[NDArray[Any]] = []
    ci: list[NDArray[Any]] = []
    rhs: list[FloatArray] = []
    gvec = np.array([0.0, 0.0, -GRAVITY])
    row = 0
    for j, phase in enumerate(phases):
        gens = phase.wrench_generators  # (m, 6): G' beta = w / (m g), beta in body weights
        c_bar, a_bar = lin[j]  # (s, 3) each
        n_s = c_bar.shape[0]
        duration = times[j + 1] - times[j]
        cols = np.array([layout.point(j, i) for i in range(basis.shape[1])])
        curve_cols = (cols[:, None] + np.arange(3)[None, :]).ravel()  # (3 (d + 1),)
        # per unit mass: force a - g; torque c x (a - g) ~ -[a_-g]x c + [c_]x a - c_ x a_
        dc = np.zeros((n_s, 6, 3))
        da = np.zeros((n_s, 6, 3))
        da[:, :3] = np.eye(3)
        dc[:, 3:] = -_skews(a_bar - gvec)
        da[:, 3:] = _skews(c_bar)
        # (s, 6, d + 1, 3) -> (6 s, 3 (d + 1)), columns in the order of curve_cols
        block = (
            -(
                basis[:, None, :, None] * dc[:, :, None, :]
                + (basis2 / duration**2)[:, None, :, None] * da[:, :, None, :]
            )
            / GRAVITY
        )
        rows = np.arange(row, row + 6 * n_s)
        ri.append(np.repeat(rows, curve_cols.size))
        ci.append(np.tile(curve_cols, rows.size))
        data.append(block.ravel())
        firsts = np.asarray(layout.weights_at[j])
        m = gens.shape[0]
        ri.append(np.repeat(rows, m))
        ci.append(np.repeat(firsts, 6 * m) + np.tile(np.arange(m), 6 * n_s))
        data.append(np.tile(gens.T.ravel(), n_s))
        torque = -np.cross(c_bar, a_bar)
        rhs.append((np.hstack([np.tile(-gvec, (n_s, 1)), torque]) / GRAVITY).ravel())
        row += 6 * n_s
    matrix = sparse.coo_matrix(
        (np.concatenate(data), (np.concatenate(ri), np.concatenate(ci))), shape=(row, layout.n)
    )
    return matrix.tocsr(), np.concatenate(rhs)


def _cost(
    layout: _Layout,
    times: FloatArray,
    basis: FloatArray,
    basis2: FloatArray,
    settings: DynamicSettings,
    targets: Sequence[FloatArray] | None,
) -> tuple[sparse.csc_matrix, FloatArray]:
    """0.5 x' P x + q' x: squared accelerations (times the phase's share of time),
    squared distance to the reference, squared weights."""
    n = layout.n
    data: list[FloatArray] = []
    ri: list[NDArray[Any]] = []
    ci: list[NDArray[Any]] = []
    q = np.zeros(n)
    samples = basis.shape[0]
    for j in range(layout.n_phases):
        duration = times[j + 1] - times[j]
        share = duration / samples
        acc = basis2 / duration**2
        smooth = settings.acceleration_weight * share * acc.T @ acc
        ref = None if targets is None else targets[j]
        cols = np.array([layout.point(j, i) for i in range(basis.shape[1])])
        for axis in range(3):
            idx = cols + axis
            gram = smooth
            if ref is not None:
                weight = (
                    settings.vertical_tracking_weight if axis == 2 else settings.tracking_weight
                )
                gram = smooth + weight * share * basis.T @ basis
                q[idx] -= weight * share * basis.T @ ref[:, axis]
            ri.append(np.repeat(idx, idx.size))
            ci.append(np.tile(idx, idx.size))
            data.append(gram.ravel())
    weights = np.arange(layout.n_curve, n)
    ri.append(weights)
    ci.append(weights)
    data.append(np.full(weights.size, settings.force_weight))
    p = sparse.coo_matrix(
        (np.concatenate(data), (np.concatenate(ri), np.concatenate(ci))), shape=(n, n)
    )
    return sparse.triu(p.tocsc(), format="csc"), q


def _matrix(rows: Sequence[dict[int, float]], n: int) -> sparse.csr_matrix:
    data, ri, ci = [], [], []
    for r, row in enumerate(rows):
        for c, v in row.items():
            ri.append(r)
            ci.append(c)
            data.append(v)
    return sparse.csr_matrix((data, (ri, ci)), shape=(len(rows), n))


def _solve_lazy(
    n: int,
    p: sparse.csc_matrix,
    q: FloatArray,
    a_eq: sparse.spmatrix,
    b_eq: FloatArray,
    a_in: sparse.csr_matrix,
    b_in: FloatArray,
    working: BoolArray,
) -> tuple[FloatArray | None, BoolArray]:
    """:func:`_solve` with only the inequality rows ``working`` (k,) of ``a_in`` (k, n); when
    its answer breaks another row by more than ``LAZY_ROW_TOLERANCE``, every row it comes
    within ``LAZY_ROW_MARGIN`` of joins them and the QP is solved again. The answer is that of
    the QP with every row (the rows left out are not binding at it), None when that QP is
    infeasible (a QP with fewer rows is, or rows are added until it is). Returns (the answer
    or None, the rows used, for the next solve)."""
    while True:
        x = _solve(n, p, q, a_eq, b_eq, a_in[working], b_in[working])
        if x is None:
            return None, working
        excess = a_in @ x - b_in
        if not np.any(excess[~working] > LAZY_ROW_TOLERANCE):
            return x, working
        working = working | (excess > -LAZY_ROW_MARGIN)


def _solve(
    n: int,
    p: sparse.csc_matrix,
    q: FloatArray,
    a_eq: sparse.spmatrix,
    b_eq: FloatArray,
    a_in: sparse.spmatrix,
    b_in: FloatArray,
) -> FloatArray | None:
    """min 0.5 x'Px + q'x s.t. a_eq x = b_eq, a_in x <= b_in; None unless solved (to
    ``SOLVER_TOLERANCE``, or ``REDUCED_TOLERANCE`` where progress stalls before). Solved
    without refining the KKT solves first (``SOLVER_REFINEMENT``), again with refinement
    when that run ends neither solved nor with an infeasibility certificate."""
    a = sparse.vstack([a_eq, a_in]).tocsc()
    b = np.concatenate([b_eq, b_in])
    cones = [clarabel.ZeroConeT(a_eq.shape[0]), clarabel.NonnegativeConeT(a_in.shape[0])]
    for refine in (SOLVER_REFINEMENT, True):
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = SOLVER_TOLERANCE
        settings.reduced_tol_gap_abs = settings.reduced_tol_gap_rel = REDUCED_TOLERANCE
        settings.reduced_tol_feas = REDUCED_TOLERANCE
        settings.iterative_refinement_enable = refine
        solution = clarabel.DefaultSolver(p, q, a, b, cones, settings).solve()
        if refine or solution.status in _SETTLED:
            break
    if solution.status not in _ANSWERED:
        return None
    x = np.asarray(solution.x, dtype=np.float64)
    return x if x.shape == (n,) and np.all(np.isfinite(x)) else None


def _curve(layout: _Layout, x: FloatArray, times: FloatArray, d: int) -> PiecewiseBezier:
    segments = []
    for j in range(layout.n_phases):
        start = layout.point(j, 0)
        ctrl = x[start : start + (d + 1) * 3].reshape(d + 1, 3)
        segments.append(BezierCurve(ctrl, float(times[j]), float(times[j + 1])))
    return PiecewiseBezier(tuple(segments))


__all__ = ["DynamicCom", "DynamicSettings", "dynamic_com"]
