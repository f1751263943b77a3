"""Dynamic COM curves: a C2 piecewise Bezier COM over given phase durations whose
gravito-inertial wrench lies in each phase's contact wrench cone (2PAC Eq. 1) at
collocation times, so the COM may move as fast as the contacts allow instead of staying
in static equilibrium.

Eq. 1 with zero angular momentum rate: G_j' beta = w(c, a) = [m (a - g), c x m (a - g)],
beta >= 0 (generator weights). The force rows are linear in the control points; the torque
c x m (a - g) is bilinear, so it is linearised about the previous iterate (c_, a_):
c x a ~= c_ x a + c x a_ - c_ x a_, and the convex QP is solved again about its answer
(sequential convex programming). Weights carry a margin (a fraction of the body weight per
generator) that absorbs the linearisation error; the answer is accepted only when the
nonlinear Eq. 1 holds at every collocation time (within ``EQ1_TOLERANCE``, checked with the
same robustness LP as ``validate_dynamics``: ``trajectory.equilibrium.holds``).

Units: metres, seconds, world frame z up; weights are in body weights (m g) for
conditioning. The QP is sparse and solved by Clarabel (interior point, deterministic). The
rows on the curve alone (trust box, kinematics: most of the QP's rows, and hardly ever
binding) enter it only once an answer breaks one of them (``DynamicSettings.lazy_rows``):
the same optimum from a QP a few times smaller. A whole curve's first round has from the
start the kinematic rows its reference comes near (``PREDICTED_ROW_DEPTH``), which would
otherwise cost a round that only adds them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, ParamSpec

import clarabel
import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from trajectory._types import GRAVITY, BoolArray, FloatArray, as_float_array
from trajectory.bezier import BezierCurve, PiecewiseBezier, bernstein
from trajectory.com import validate_dynamics
from trajectory.contacts import ContactPhase
from trajectory.equilibrium import holds
from trajectory.polytope import Halfspaces

P = ParamSpec("P")


@dataclass(frozen=True, slots=True)
class DynamicSettings:
    """Tuning of the dynamic COM QP.

    degree : Bezier degree of each phase's segment (>= 5: C2 joins and rest ends leave
        free points). samples : collocation times per phase, both ends included.
    sample_spacing : s; when positive, a phase gets only as many samples as spacing them
        this far apart takes (``MIN_PHASE_SAMPLES`` at least, ``samples`` at most), so that
        a short phase is not sampled every few milliseconds.
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
    local_repair : a round's answer failing in a few phases has windows around them solved
        again, the rest of the curve kept (``REPAIR_RADIUS``, ``REPAIR_MAX_SHARE``; QPs of
        ``REPAIR_MIN_VARIABLES`` or more), before another round of the whole QP; False: whole
        rounds only (for comparisons).
    """

    degree: int = 7
    samples: int = 12
    sample_spacing: float = 0.0
    iterations: int = 4
    margin: float = 1e-3
    acceleration_weight: float = 1.0
    tracking_weight: float = 10.0
    vertical_tracking_weight: float = 1e4
    force_weight: float = 1e-2
    lazy_rows: bool = True
    local_repair: bool = True

    def __post_init__(self) -> None:
        if self.degree < 5:
            raise ValueError(f"degree: at least 5 is needed, got {self.degree}")
        if self.samples < 2:
            raise ValueError(f"samples: at least 2 are needed, got {self.samples}")
        if self.iterations < 1:
            raise ValueError(f"iterations: at least 1 is needed, got {self.iterations}")
        if not self.sample_spacing >= 0.0:
            raise ValueError(f"sample_spacing: at least 0 is needed, got {self.sample_spacing}")

    def phase_samples(self, duration: float) -> int:
        """Collocation times of a phase lasting ``duration`` s (``sample_spacing``)."""
        if self.sample_spacing <= 0.0:
            return self.samples
        wanted = math.ceil(duration / self.sample_spacing - 1e-9) + 1
        return max(min(MIN_PHASE_SAMPLES, self.samples), min(self.samples, wanted))


MIN_PHASE_SAMPLES = 4
"""Fewest collocation times of a phase under ``DynamicSettings.sample_spacing`` (both ends
and two between)."""


@dataclass(frozen=True, slots=True, eq=False)
class DynamicCom:
    """A dynamically consistent COM: ``curve`` (one segment per phase), ``phase_times``
    (n + 1,) s, ``iterations`` used, and ``valid`` True when Eq. 1 held (within
    ``EQ1_TOLERANCE``) at every collocation time of the last iterate."""

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


class _Basis:
    """A phase's collocation fractions ``u`` (samples,) in [0, 1], the Bernstein basis of
    its segment there ``basis`` (samples, d + 1) and of its second derivative ``basis2``
    (samples, d + 1; to divide by the phase's duration squared)."""

    def __init__(self, degree: int, samples: int) -> None:
        self.u = np.linspace(0.0, 1.0, samples)
        self.basis = bernstein(degree, self.u)
        self.basis2 = (
            bernstein(degree - 2, self.u) @ _second_difference(degree) * degree * (degree - 1)
        )


class _Layout:
    """Variable layout: control points of every phase (phase, point, xyz), then the
    generator weights of every collocation sample."""

    def __init__(self, phases: Sequence[ContactPhase], degree: int, samples: Sequence[int]) -> None:
        self.n_phases = len(phases)
        self.points = degree + 1
        self.n_curve = self.n_phases * self.points * 3
        self.weights_at: list[list[int]] = []
        self.generators: list[int] = []  # per phase, its generator count m
        offset = self.n_curve
        for phase, count in zip(phases, samples, strict=True):
            m = phase.wrench_generators.shape[0]
            self.generators.append(m)
            row = []
            for _ in range(count):
                row.append(offset)
                offset += m
            self.weights_at.append(row)
        self.n = offset

    def point(self, phase: int, index: int) -> int:
        """Index of the x coordinate of control point ``index`` of ``phase``."""
        return (phase * self.points + index) * 3

    def weights_of(self, x: FloatArray, phase: int) -> FloatArray:
        """(s, m) the generator weights of ``phase``'s samples in the answer ``x`` (n,)."""
        first, m = self.weights_at[phase], self.generators[phase]
        return x[first[0] : first[0] + m * len(first)].reshape(len(first), m)


@dataclass(frozen=True, slots=True, eq=False)
class DynamicOutcome:
    """What :func:`solve_dynamic_com` found: ``com`` as :func:`dynamic_com` returns it, and
    where its QP was infeasible, ``blame`` (n,): each phase's share of the weight that
    Clarabel's infeasibility certificate puts on its Eq. 1 rows (sums to 1; the phases
    whose contacts cannot carry the curve asked of them), else None."""

    com: DynamicCom | None
    blame: FloatArray | None


def solve_dynamic_com(
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
) -> DynamicOutcome:
    """A C2 COM from ``start`` to ``end`` (3,), at rest at both, phase j lasting
    durations[j] s, whose wrench lies in phase j's contact cone at its collocation times
    (``DynamicSettings.phase_samples``) and whose position satisfies ``kinematics[j]``
    there. The curve stays near ``reference`` (or None), whose phase j spans
    reference_times[j] to reference_times[j + 1] (n + 1 times, s; the reference is compared
    phase by phase at the same fractions of each phase). None when a
    QP is infeasible (the outcome's ``blame`` then says which phases); ``valid`` False when
    the linearisation did not settle into a valid curve within
    ``settings.iterations`` rounds. ``before`` / ``after`` : segments (of
    the same degree) the curve joins C2 instead of starting / ending at rest: it starts where
    ``before`` ends (``start`` must be that point) and ends where ``after`` starts (``end``
    likewise); its times still start at 0 (a window of a longer curve, shifted by the
    caller).

    Where a round's answer fails Eq. 1 (or breaks a row left out) in a few phases only, those
    phases and ``REPAIR_RADIUS`` phases on each side are solved again as windows, the curve
    outside them kept and joined C2, linearised about the round's answer
    (``DynamicSettings.local_repair``, QPs of ``REPAIR_MIN_VARIABLES`` or more, once per
    call): a few small QPs instead of another round of the whole one. When a window finds no
    curve valid at its collocation times and between them, the next round is the whole QP's,
    as without."""
    return _solve_rounds(
        phases,
        durations,
        start,
        end,
        kinematics=kinematics,
        reference=reference,
        reference_times=reference_times,
        settings=settings or DynamicSettings(),
        before=before,
        after=after,
    )


def _solve_rounds(
    phases: Sequence[ContactPhase],
    durations: Sequence[float],
    start: FloatArray,
    end: FloatArray,
    *,
    kinematics: Sequence[Halfspaces | None] | None,
    reference: PiecewiseBezier | None,
    reference_times: Sequence[float] | None,
    settings: DynamicSettings,
    before: BezierCurve | None,
    after: BezierCurve | None,
    first: Sequence[tuple[FloatArray, FloatArray]] | None = None,
    repair: bool = True,
    kept_ends: tuple[bool, bool] = (False, False),
) -> DynamicOutcome:
    """:func:`solve_dynamic_com` (same arguments), its first round linearised about
    ``first`` (per phase, the positions and accelerations at its collocation times) when
    given, else about the reference at rest; ``repair``: whether a round's failing phases
    may be solved again as windows. ``kept_ends``: whether the first sample of the first
    phase (the last of the last) is that of a curve kept around a repair window, which
    passes Eq. 1 there already: the C2 join fixes it, and its weights keep no margin (the
    linearisation is exact at the point it is taken about, the margin may not be)."""
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
    # the cost and trust boxes at ``samples`` per phase, Eq. 1 at each phase's own count
    counts = [settings.phase_samples(float(t)) for t in np.diff(times)]
    layout = _Layout(phases, d, counts)
    bases = {count: _Basis(d, count) for count in {settings.samples, *counts}}
    full = bases[settings.samples]
    per_phase_basis = [bases[count] for count in counts]
    ends = np.cumsum([0, *counts])
    per_phase = [slice(int(a), int(b)) for a, b in itertools.pairwise(ends)]
    all_times = np.concatenate(
        [times[j] + b.u * (times[j + 1] - times[j]) for j, b in enumerate(per_phase_basis)]
    )

    def guess(j: int, u: FloatArray) -> FloatArray:
        """(len(u), 3) the reference (else the line from start to end) at fractions u of
        phase j."""
        if reference is None:
            fractions = (times[j] + u * (times[j + 1] - times[j])) / times[-1]
            return np.asarray(c0 + fractions[:, None] * (c1 - c0))
        at = np.clip(rt[j] + u * (rt[j + 1] - rt[j]), reference.t0, reference.t1)
        return np.asarray(reference(at))

    if reference is not None:
        if reference_times is None or len(reference_times) != len(phases) + 1:
            raise ValueError("reference_times: one time per phase boundary is needed")
        rt = np.asarray(reference_times, dtype=np.float64)
    boxes = [guess(j, full.u) for j in range(len(phases))]
    targets = None if reference is None else boxes
    lin = (
        list(first)
        if first is not None
        else [
            (boxes[j] if counts[j] == full.u.size else guess(j, b.u), np.zeros((counts[j], 3)))
            for j, b in enumerate(per_phase_basis)
        ]
    )
    durations_arr = np.diff(times)
    head = _join_points(before, float(durations_arr[0]), d, c0, at_end=False)
    tail = _join_points(after, float(durations_arr[-1]), d, c1, at_end=True)
    eq_rows, eq_rhs = _fixed_rows(layout, times, head, tail, d)
    margin_rows, margin_rhs = _margin_rows(layout, settings.margin)
    last = len(phases) - 1
    for kept, (j, k) in zip(kept_ends, ((0, 0), (last, counts[last] - 1)), strict=True):
        if kept:  # that sample's weights: no margin
            first_weight = layout.weights_at[j][k] - layout.n_curve
            margin_rhs[first_weight : first_weight + phases[j].wrench_generators.shape[0]] = 0.0
    curve_rows = _CurveRows(layout, d, kins, boxes)
    working = np.full(curve_rows.size, not settings.lazy_rows)
    if settings.lazy_rows and first is None and reference is not None:
        # the kinematic rows the reference comes near are likely to bind: in from the start,
        # they spare the round that would only add them (when they are few enough)
        near = curve_rows.near(_reference_points(layout, guess, d), PREDICTED_ROW_DEPTH)
        if np.count_nonzero(near) <= PREDICTED_ROW_SHARE * margin_rhs.size:
            working = near
    cost_p, cost_q = _cost(layout, times, full, settings, targets)
    result: DynamicCom | None = None
    # a round's failing phases solved again as windows (at most once)
    repair_left = (
        repair
        and settings.local_repair
        and len(phases) > 2 * REPAIR_RADIUS + 1
        and layout.n >= REPAIR_MIN_VARIABLES
    )
    for iteration in range(1, settings.iterations + 1):
        w_rows, w_rhs = _wrench_rows(layout, phases, times, per_phase_basis, lin)
        last_round = iteration == settings.iterations
        x, working, certificate, unsettled = _solve_lazy(
            layout.n,
            cost_p,
            cost_q,
            sparse.vstack([eq_rows, w_rows]),
            np.concatenate([eq_rhs, w_rhs]),
            curve_rows,
            margin_rows,
            margin_rhs,
            working,
            settle=last_round,
        )
        if x is None:
            blame = None
            if certificate is not None:  # its rows: the fixed rows, then Eq. 1's, phase by phase
                weight = np.abs(certificate[eq_rhs.size : eq_rhs.size + w_rhs.size])
                weight = np.add.reduceat(weight, 6 * ends[:-1])
                total = float(weight.sum())
                blame = weight / total if total > 0.0 else None
            return DynamicOutcome(result, blame)
        complete = unsettled is None
        for index in range(3):  # the fixed end points exactly (SOLVER_EQUILIBRATION)
            x[layout.point(0, index) : layout.point(0, index) + 3] = head[index]
            x[layout.point(last, d - index) : layout.point(last, d - index) + 3] = tail[index]
        curve = _curve(layout, x, times, d)
        # every phase's samples in one evaluation of each curve (the same points as phase
        # by phase: a sample on a break is the later segment's either way)
        positions, accelerations = curve(all_times), curve.derivative(2)(all_times)
        lin = [(positions[k], accelerations[k]) for k in per_phase]
        given = [layout.weights_of(x, j) for j in range(len(phases))]
        if repair_left:
            broken = [] if unsettled is None else curve_rows.broken_phases(unsettled)
            failing = _failing_phases(phases, lin, given, broken)
            valid = complete and failing == []
            if failing:
                windows = _repair_windows(failing, len(phases))
                repair_left = False  # once: where windows fail, so may they again
                rounds_left = max(1, min(REPAIR_ROUNDS, settings.iterations - iteration))
                repaired = _repaired(
                    curve,
                    windows,
                    phases,
                    durations_arr,
                    (c0, c1),
                    (before, after),
                    kins,
                    reference,
                    rt if reference is not None else None,
                    replace(settings, iterations=rounds_left),
                    lin,
                )
                if repaired is not None:
                    result = DynamicCom(repaired[0], times, iteration + repaired[1], True)
                    break
        else:
            valid = complete and all(
                _passes(phase, sample, weights)
                for phase, sample, weights in zip(phases, lin, given, strict=True)
            )
        if not complete:
            # an answer breaking rows left out (trust box, kinematics) is only the next
            # round's linearisation point, its broken rows now in the QP
            continue
        result = DynamicCom(curve, times, iteration, valid)
        if valid:
            break
    return DynamicOutcome(result, None)


def _passes(
    phase: ContactPhase, samples: tuple[FloatArray, FloatArray], weights: FloatArray
) -> bool:
    """Whether Eq. 1 holds at each of a phase's collocation samples (positions and
    accelerations, (s, 3) each), within ``EQ1_TOLERANCE`` (the tolerance of
    ``validate_dynamics``); ``weights`` (s, m): the QP's generator weights there, which
    settle most samples without their LP (``trajectory.equilibrium.holds``)."""
    return bool(holds(phase, *samples, weights=weights).all())


def _failing_phases(
    phases: Sequence[ContactPhase],
    samples: Sequence[tuple[FloatArray, FloatArray]],
    weights: Sequence[FloatArray],
    broken: Sequence[int],
) -> list[int] | None:
    """The phases (increasing) that fail Eq. 1 at a collocation sample (per phase, positions
    and accelerations (s, 3), and the QP's generator weights (s, m)) or are in ``broken``;
    None as soon as their repair windows would cover more than ``REPAIR_MAX_SHARE`` of the
    phases (the rest is not checked)."""
    failing: list[int] = []
    limit = REPAIR_MAX_SHARE * len(phases)
    if sum(b - a for a, b in _repair_windows(sorted(broken), len(phases))) > limit:
        return None  # the phases that break a row are too many already
    for j, (phase, sample, given) in enumerate(zip(phases, samples, weights, strict=True)):
        if j in broken or not _passes(phase, sample, given):
            failing.append(j)
            if sum(b - a for a, b in _repair_windows(failing, len(phases))) > limit:
                return None
    return failing


def _repair_windows(failing: Sequence[int], n: int) -> list[tuple[int, int]]:
    """Phase windows [a, b) around the ``failing`` phases (increasing), ``REPAIR_RADIUS``
    phases on each side, within the n phases; windows that overlap or touch are one."""
    windows: list[tuple[int, int]] = []
    for j in failing:
        a, b = max(0, j - REPAIR_RADIUS), min(n, j + REPAIR_RADIUS + 1)
        if windows and a <= windows[-1][1]:
            windows[-1] = (windows[-1][0], max(windows[-1][1], b))
        else:
            windows.append((a, b))
    return windows


def _repaired(
    curve: PiecewiseBezier,
    windows: Sequence[tuple[int, int]],
    phases: Sequence[ContactPhase],
    durations: FloatArray,
    ends: tuple[FloatArray, FloatArray],
    joins: tuple[BezierCurve | None, BezierCurve | None],
    kins: Sequence[Halfspaces | None],
    reference: PiecewiseBezier | None,
    reference_times: FloatArray | None,
    settings: DynamicSettings,
    lin: Sequence[tuple[FloatArray, FloatArray]],
) -> tuple[PiecewiseBezier, int] | None:
    """``curve`` with each window [a, b) of its phases solved again (linearised about
    ``lin``, the curve's samples), joined C2 to the segments on each side (or to the curve's
    own ``ends`` and ``joins``), and the most rounds a window took; None when a window finds
    no curve that passes Eq. 1 at its collocation times and at ``validate_dynamics``'s
    samples of each of its phases."""
    segments = list(curve.segments)
    n = len(segments)
    rounds = 0
    for a, b in windows:
        # a window starts where the segment before it ends and ends where the one after it
        # starts (exactly: the joins are C0 only to the solver's tolerance)
        before, start = joins[0], ends[0]
        if a > 0:
            before = segments[a - 1]
            start = np.asarray(before.control_points[-1], dtype=np.float64)
        after, end = joins[1], ends[1]
        if b < n:
            after = segments[b]
            end = np.asarray(after.control_points[0], dtype=np.float64)
        found = _solve_rounds(
            phases[a:b],
            durations[a:b].tolist(),
            start,
            end,
            kinematics=kins[a:b],
            reference=reference,
            reference_times=None
            if reference_times is None
            else reference_times[a : b + 1].tolist(),
            settings=settings,
            before=before,
            after=after,
            first=lin[a:b],
            repair=False,
            kept_ends=(a > 0, b < n),
        ).com
        if found is None or not found.valid:
            return None
        # between its collocation times too: a window joined to kept segments at both ends
        # bends more than the whole curve would, and its ends keep no margin
        dense = validate_dynamics(found.curve, phases[a:b], found.phase_times)
        if any(report.fraction_valid < 1.0 for report in dense):
            return None
        rounds = max(rounds, found.iterations)
        for k, segment in enumerate(found.curve.segments):
            old = segments[a + k]
            segments[a + k] = segment.retimed(old.t0, old.t1)
    return PiecewiseBezier(tuple(segments)), rounds


def _curve_only(solve: Callable[P, DynamicOutcome]) -> Callable[P, DynamicCom | None]:
    """``solve`` answering its outcome's curve only."""

    def curve(*args: P.args, **kwargs: P.kwargs) -> DynamicCom | None:
        return solve(*args, **kwargs).com

    return curve


dynamic_com = _curve_only(solve_dynamic_com)
""":func:`solve_dynamic_com`'s curve (same arguments): None when a QP is infeasible."""


def _reference_points(
    layout: _Layout, guess: Callable[[int, FloatArray], FloatArray], d: int
) -> FloatArray:
    """(n,) a variable vector whose control points of phase j are ``guess(j, u)`` (the
    reference, (d + 1, 3)) at d + 1 evenly spaced fractions u of the phase (a stand-in for
    the reference's own control points over the phase); its weights zero."""
    x = np.zeros(layout.n)
    fractions = np.linspace(0.0, 1.0, d + 1)
    for j in range(layout.n_phases):
        start = layout.point(j, 0)
        x[start : start + 3 * (d + 1)] = guess(j, fractions).ravel()
    return x


def _fixed_rows(
    layout: _Layout, times: FloatArray, head: FloatArray, tail: FloatArray, d: int
) -> tuple[sparse.csr_matrix, FloatArray]:
    """Equalities: the first three control points ``head`` (3, 3), the last three ``tail``
    (3, 3, last first), C0/C1/C2 joins."""
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
    return _matrix(rows, layout.n), np.asarray(rhs)


def _margin_rows(layout: _Layout, margin: float) -> tuple[sparse.csr_matrix, FloatArray]:
    """The weights' margins -beta <= -margin: one row per generator weight, in order."""
    count = layout.n - layout.n_curve
    rows = sparse.csr_matrix(
        (
            -np.ones(count),
            np.arange(layout.n_curve, layout.n),
            np.arange(count + 1, dtype=np.int64),
        ),
        shape=(count, layout.n),
    )
    return rows, np.full(count, -margin)


class _CurveRows:
    """The inequality rows on the control points alone, phase by phase: the trust box (each
    coordinate of each point x <= high, then -x <= -low), then the rows of the phase's
    kinematic polytope that the box can reach, for each control point in turn. Kept
    implicit: a long window has millions of them and few ever bind, so they are evaluated
    on an answer (:meth:`excess`) and made into matrix rows only where asked (:meth:`rows`).

    Each phase's control points stay in a box around its reference (trust region);
    kinematics hold on the control points (the curve lies in their convex hull, so along
    the whole phase, a little conservative); ``KINEMATIC_SLACK`` absorbs round-off of the
    states' own COMs on the boundary."""

    def __init__(
        self,
        layout: _Layout,
        d: int,
        kins: Sequence[Halfspaces | None],
        boxes: Sequence[FloatArray],
    ) -> None:
        self.n = layout.n
        self.points = d + 1
        self.first: list[int] = []  # column of each phase's first control point
        self.high: list[FloatArray] = []  # (3,) m per phase
        self.low: list[FloatArray] = []
        self.a: list[FloatArray] = []  # (k, 3) reachable kinematic rows per phase
        self.b: list[FloatArray] = []  # (k,) their bounds, slack included
        sizes = []
        for j, kin in enumerate(kins):
            low = np.min(boxes[j], axis=0) - TRUST_RADIUS
            high = np.max(boxes[j], axis=0) + TRUST_RADIUS
            a_rows, b_rows = np.zeros((0, 3)), np.zeros(0)
            if kin is not None and kin.A.shape[0] > 0:
                centre, half = 0.5 * (low + high), 0.5 * (high - low)
                reachable = kin.A @ centre + np.abs(kin.A) @ half > kin.b + KINEMATIC_SLACK
                a_rows, b_rows = kin.A[reachable], kin.b[reachable] + KINEMATIC_SLACK
            self.first.append(layout.point(j, 0))
            self.high.append(high)
            self.low.append(low)
            self.a.append(a_rows)
            self.b.append(b_rows)
            sizes.append(self.points * (6 + a_rows.shape[0]))
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

    @property
    def size(self) -> int:
        """The number of rows."""
        return int(self.offsets[-1])

    def excess(self, x: FloatArray) -> FloatArray:
        """(size,) each row's left side at ``x`` (n,) less its bound (> 0: broken)."""
        out = np.empty(self.size)
        per = self.points * 3
        for j, first in enumerate(self.first):
            ctrl = x[first : first + per].reshape(self.points, 3)
            o = self.offsets[j]
            out[o : o + per] = (ctrl - self.high[j]).ravel()
            out[o + per : o + 2 * per] = (self.low[j] - ctrl).ravel()
            out[o + 2 * per : self.offsets[j + 1]] = (ctrl @ self.a[j].T - self.b[j]).ravel()
        return out

    def near(self, x: FloatArray, depth: float) -> BoolArray:
        """(size,) the kinematic rows (not the trust box's) that ``x`` (n,) keeps less than
        ``depth`` m inside their bounds, or breaks."""
        out = self.excess(x) > -depth
        per = self.points * 3
        for offset in self.offsets[:-1]:
            out[offset : offset + 2 * per] = False
        return out

    def broken_phases(self, excess: FloatArray) -> list[int]:
        """The phases (increasing) with a row whose ``excess`` (size,; :meth:`excess` of an
        answer) is over ``LAZY_ROW_TOLERANCE``."""
        broken = np.flatnonzero(excess > LAZY_ROW_TOLERANCE)
        phases = np.searchsorted(self.offsets, broken, side="right") - 1
        return sorted(set(phases.tolist()))

    def rows(self, mask: BoolArray) -> tuple[sparse.csr_matrix, FloatArray]:
        """The rows ``mask`` (size,) selects, in order, as a CSR matrix (canonical: each
        row's columns increasing) and their bounds."""
        data: list[FloatArray] = []
        cols: list[NDArray[Any]] = []
        counts: list[NDArray[Any]] = []
        bounds: list[FloatArray] = []
        per = self.points * 3
        for j, first in enumerate(self.first):
            local = np.flatnonzero(mask[self.offsets[j] : self.offsets[j + 1]])
            if local.size == 0:
                continue
            box = local[local < 2 * per]
            upper = box < per
            data.append(np.where(upper, 1.0, -1.0))
            cols.append(first + box % per)
            counts.append(np.ones(box.size, dtype=np.int64))
            axes = box % 3
            bounds.append(np.where(upper, self.high[j][axes], -self.low[j][axes]))
            kin = local[local >= 2 * per] - 2 * per
            if kin.size:
                k = self.a[j].shape[0]
                point, row = kin // k, kin % k
                data.append(self.a[j][row].ravel())
                cols.append((first + 3 * point[:, None] + np.arange(3)).ravel())
                counts.append(np.full(kin.size, 3, dtype=np.int64))
                bounds.append(self.b[j][row])
        if not data:
            return sparse.csr_matrix((0, self.n)), np.zeros(0)
        per_row = np.concatenate(counts)
        indptr = np.zeros(per_row.size + 1, dtype=np.int64)
        np.cumsum(per_row, out=indptr[1:])
        matrix = sparse.csr_matrix(
            (np.concatenate(data), np.concatenate(cols), indptr), shape=(per_row.size, self.n)
        )
        return matrix, np.concatenate(bounds)


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

REPAIR_RADIUS = 3
"""Phases on each side of a failing phase that its repair window solves again with it
(``DynamicSettings.local_repair``). With two, a window on the climbing hexapod's wall bent
its curve more than the whole QP's round did: the body lagged it by 23 mm, the trial build
failed at every slower level and three phases stopped at rest; with three it plays as the
whole QP's curve did, for the same cost on the captured plans' QPs."""

REPAIR_ROUNDS = 2
"""Linearisation rounds a repair window takes at most (fewer when the curve's own rounds
run out sooner): the windows of the captured plans' QPs that passed took one or two, and a
window that fails costs its rounds on top of the next whole one."""

REPAIR_MIN_VARIABLES = 8000
"""Smallest QP (variables) whose failing phases are repaired in windows: finding them checks
every sample of a failing round (else the check stops at the first failing one), which cost
a smaller QP about as much as the round it could save (the quadruped's flat walk, 4,000
variables, 50 ms a round, took 5 % longer); the hexapod's walk (8,800), Talos' stairs
(8,800) and the climbing wall (58,000) save a round of 0.1 to 0.6 s."""

REPAIR_MAX_SHARE = 0.5
"""Largest share of a curve's phases that repair windows may cover; beyond it the next round
solves the whole QP again."""

TRUST_RADIUS = 0.25
"""m: how far a phase's control points may leave the box of its reference positions."""

LAZY_ROW_TOLERANCE = 1e-9
"""m: how far an answer may break a row left out of the QP (trust box, kinematics) before
that row is put in and the QP solved again (``DynamicSettings.lazy_rows``)."""

LAZY_ROW_MARGIN = 1e-3
"""m: when a row left out is broken, every row left out that the answer comes within this
of is put in too (fewer rounds; a row that does not bind leaves the optimum as it is)."""

PREDICTED_ROW_DEPTH = 0.05
"""m: a whole curve's first round puts in from the start the kinematic rows that its
reference comes within this of binding (:func:`_reference_points`), instead of waiting for an
answer to break them (``DynamicSettings.lazy_rows``). The hexapod's walk: its first round's
answer broke 305 rows in 7 phases, every one of them among the 4,247 rows within 5 cm of the
reference (within 3 cm, 560 rows missed two of those phases), and the round that only added
them (80 ms of its QP's 180 ms) was saved."""

PREDICTED_ROW_SHARE = 1.0
"""The predicted rows (``PREDICTED_ROW_DEPTH``) go in only when they are at most this share of
the QP's own inequality rows (one per generator weight); more would cost about as much as the
round they may spare: the climbing hexapod's wall (69,290 rows near its reference, against
41,136) took 0.82 s for its first round with them, 0.50 s for its rounds and windows without."""

SOLVER_REFINEMENT = False
"""Whether Clarabel first solves with iterative refinement of its KKT solves (its default is
on): off halves the time of a solve, and moved the control points by less than 3e-7 m on the
captured plans' QPs. A run that ends neither solved (to ``SOLVER_TOLERANCE``, or to
``REDUCED_TOLERANCE`` where its progress stalls), nor infeasible, nor at
``SOLVER_MAX_ITERATIONS`` is repeated with it on."""

SOLVER_EQUILIBRATION = False
"""Whether Clarabel rescales the QP's rows and columns before solving (Ruiz equilibration,
its default on). The QP is already in consistent units (control points in m, generator
weights in body weights) and the rescaled one took more iterations: on the captured dynamic
QPs of eight reference plans (the walls, stairs, walks and HyQ's terrains) 1.93 s instead of
2.42 s, 20 to 30 % less on the walls, the stairs and the hexapod's walk, the same on the
quadrupeds' walks (bounding the rescaling to 10 instead made the quadrupeds' QPs stall and
run again refined: 2.5 times as long). Unscaled, the answers meet the fixed end points to
about 1e-6 m only; :func:`_solve_rounds` sets them exactly (a window's C2 join to the curve
kept around it)."""

SOLVER_MAX_ITERATIONS = 100
"""Clarabel's iteration cap (its default is 200). The solves of 69 plans (three seeds of every
reference scenario) that settled took 58 iterations at most, 18 at the median; the one that
did not (a re-solved window of a rubble walk) ran to 200 without settling, 0.7 s, and again
refined to 200, 1.1 s more, for no answer."""

_SETTLED = frozenset(
    {
        clarabel.SolverStatus.Solved,
        clarabel.SolverStatus.AlmostSolved,
        clarabel.SolverStatus.PrimalInfeasible,
        clarabel.SolverStatus.DualInfeasible,
        clarabel.SolverStatus.MaxIterations,
    }
)
"""Clarabel's statuses that are taken as they are (the others are run again refined): a run
that reached ``SOLVER_MAX_ITERATIONS`` is not repeated (refined, the one seen did no better;
its answer is still used when :func:`_nearly_solved`)."""

_ANSWERED = frozenset({clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved})
"""Clarabel's statuses whose answer is used: solved to ``SOLVER_TOLERANCE``, or to
``REDUCED_TOLERANCE`` when its progress stalled before."""

STALLED_TOLERANCE = 1e-7
"""Clarabel's dual residual and relative gap up to which the answer of a run that stalls
short of ``REDUCED_TOLERANCE`` (InsufficientProgress, MaxIterations) is taken as it is, when
its primal residual is within ``REDUCED_TOLERANCE``: without it the climbing wall's whole-plan
QP (80,000 variables) stalled at a dual residual of 1.3e-8 and was run again refined, 1.5 s
more, for control points 3e-6 m from the first run's and the same objective to 1e-13."""

_STALLED = frozenset(
    {clarabel.SolverStatus.InsufficientProgress, clarabel.SolverStatus.MaxIterations}
)
"""Clarabel's statuses of a run that stopped short of its tolerances without a certificate."""

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
    bases: Sequence[_Basis],
    lin: Sequence[tuple[FloatArray, FloatArray]],
) -> tuple[sparse.csr_matrix, FloatArray]:
    """Eq. 1 at every collocation sample, linearised about ``lin`` (per phase, the sample
    positions and accelerations), in body weights: G' beta - w_lin(c, a) = w_const; six rows
    per sample, phase by phase. Built for every sample at once (S samples in all)."""
    counts = np.array([b.basis.shape[0] for b in bases], dtype=np.int64)
    phase_of = np.repeat(np.arange(len(phases)), counts)  # (S,)
    # each phase's duration squared alone: an array's ** 2 moved some by an ulp (and a plan)
    squares = np.array([(times[j + 1] - times[j]) ** 2 for j in range(len(phases))])
    basis = np.concatenate([b.basis for b in bases])  # (S, d + 1)
    basis2 = np.concatenate([b.basis2 for b in bases]) / squares[phase_of][:, None]
    c_bar = np.concatenate([c for c, _ in lin])  # (S, 3) each
    a_bar = np.concatenate([a for _, a in lin])
    n_s = c_bar.shape[0]
    gvec = np.array([0.0, 0.0, -GRAVITY])
    # per unit mass: force a - g; torque c x (a - g) ~ -[a_-g]x c + [c_]x a - c_ x a_
    dc = np.zeros((n_s, 6, 3))
    da = np.zeros((n_s, 6, 3))
    da[:, :3] = np.eye(3)
    dc[:, 3:] = -_skews(a_bar - gvec)
    da[:, 3:] = _skews(c_bar)
    # (S, 6, d + 1, 3) -> (6 S, 3 (d + 1)), columns point by point, x y z each
    block = (
        -(
            basis[:, None, :, None] * dc[:, :, None, :]
            + basis2[:, None, :, None] * da[:, :, None, :]
        )
        / GRAVITY
    )
    # each row: the 3 (d + 1) control point coordinates of its phase, then its sample's m
    # generator weights (row 6 k + r of sample k has G[:, r]); columns increasing (CSR)
    width = 3 * layout.points
    m_of = np.asarray(layout.generators, dtype=np.int64)[phase_of]  # (S,)
    per_row = np.repeat(m_of, 6)  # (6 S,)
    indptr = np.zeros(6 * n_s + 1, dtype=np.int64)
    np.cumsum(width + per_row, out=indptr[1:])
    total = int(indptr[-1])
    offset = np.arange(total) - np.repeat(indptr[:-1], width + per_row)  # within its row
    on_curve = offset < width
    firsts = np.concatenate([np.asarray(f, dtype=np.int64) for f in layout.weights_at])
    curve_cols = (phase_of * width)[:, None] + np.arange(width)  # (S, 3 (d + 1))
    data = np.empty(total)
    indices = np.empty(total, dtype=np.int64)
    data[on_curve] = block.ravel()
    indices[on_curve] = np.repeat(curve_cols, 6, axis=0).ravel()
    data[~on_curve] = np.concatenate(
        [
            np.tile(phase.wrench_generators.T.ravel(), int(count))
            for phase, count in zip(phases, counts, strict=True)
        ]
    )
    indices[~on_curve] = np.repeat(firsts, 6 * m_of) + offset[~on_curve] - width
    torque = -np.cross(c_bar, a_bar)
    rhs = (np.hstack([np.tile(-gvec, (n_s, 1)), torque]) / GRAVITY).ravel()
    matrix = sparse.csr_matrix((data, indices, indptr), shape=(6 * n_s, layout.n))
    return matrix, rhs


def _cost(
    layout: _Layout,
    times: FloatArray,
    full: _Basis,
    settings: DynamicSettings,
    targets: Sequence[FloatArray] | None,
) -> tuple[sparse.csc_matrix, FloatArray]:
    """0.5 x' P x + q' x: squared accelerations (times the phase's share of time) and
    squared distance to the reference ``targets`` (per phase, at ``full``'s fractions),
    squared weights."""
    n = layout.n
    data: list[FloatArray] = []
    ri: list[NDArray[Any]] = []
    ci: list[NDArray[Any]] = []
    q = np.zeros(n)
    basis, basis2 = full.basis, full.basis2
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
    curve_rows: _CurveRows,
    a_in: sparse.csr_matrix,
    b_in: FloatArray,
    working: BoolArray,
    *,
    settle: bool = True,
) -> tuple[FloatArray | None, BoolArray, FloatArray | None, FloatArray | None]:
    """:func:`_solve` with the inequalities ``a_in`` x <= ``b_in`` and only the rows
    ``working`` (size,) of ``curve_rows``; when its answer breaks another of those by more
    than ``LAZY_ROW_TOLERANCE``, every one it comes within ``LAZY_ROW_MARGIN`` of joins them
    and, when ``settle``, the QP is solved again. Settled, the answer is that of the QP with
    every row (the rows left out are not binding at it), None when that QP is infeasible (a
    QP with fewer rows is, or rows are added until it is). Returns (the answer or None, the
    rows used, for the next solve, :func:`_solve`'s certificate: its equality rows are the
    whole QP's, and, for an answer that breaks a row left out (only when not ``settle``), its
    :meth:`_CurveRows.excess` (size,), else None)."""
    while True:
        rows, bounds = curve_rows.rows(working)
        x, certificate = _solve(
            n, p, q, a_eq, b_eq, sparse.vstack([rows, a_in]), np.concatenate([bounds, b_in])
        )
        if x is None:
            return None, working, certificate, None
        excess = curve_rows.excess(x)
        if not np.any(excess[~working] > LAZY_ROW_TOLERANCE):
            return x, working, None, None
        working = working | (excess > -LAZY_ROW_MARGIN)
        if not settle:
            return x, working, None, excess


def _solve(
    n: int,
    p: sparse.csc_matrix,
    q: FloatArray,
    a_eq: sparse.spmatrix,
    b_eq: FloatArray,
    a_in: sparse.spmatrix,
    b_in: FloatArray,
) -> tuple[FloatArray | None, FloatArray | None]:
    """min 0.5 x'Px + q'x s.t. a_eq x = b_eq, a_in x <= b_in: (the answer, None), the answer
    None unless solved (to ``SOLVER_TOLERANCE``, or ``REDUCED_TOLERANCE`` where progress
    stalls before, or nearly: :func:`_nearly_solved`); (None, the dual certificate, one per
    row of a_eq then a_in) when Clarabel proves the QP primal infeasible. Solved without
    refining the KKT solves first (``SOLVER_REFINEMENT``), again with refinement when that
    run stalls short of an answer (``_SETTLED``); at most ``SOLVER_MAX_ITERATIONS`` each."""
    a = sparse.vstack([a_eq, a_in]).tocsc()
    # Clarabel factors every stored entry: a first round linearised about accelerations of
    # zero stores a third of its Eq. 1 entries as 0.0 (the torque's c x a_ terms). Without
    # them the hexapod walk's two QPs took 72 and 80 ms instead of 81 and 95
    a.eliminate_zeros()
    b = np.concatenate([b_eq, b_in])
    cones = [clarabel.ZeroConeT(a_eq.shape[0]), clarabel.NonnegativeConeT(a_in.shape[0])]
    for refine in (SOLVER_REFINEMENT, True):
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = SOLVER_TOLERANCE
        settings.reduced_tol_gap_abs = settings.reduced_tol_gap_rel = REDUCED_TOLERANCE
        settings.reduced_tol_feas = REDUCED_TOLERANCE
        settings.iterative_refinement_enable = refine
        settings.equilibrate_enable = SOLVER_EQUILIBRATION
        settings.max_iter = SOLVER_MAX_ITERATIONS
        solution = clarabel.DefaultSolver(p, q, a, b, cones, settings).solve()
        if refine or solution.status in _SETTLED or _nearly_solved(solution):
            break
    if solution.status == clarabel.SolverStatus.PrimalInfeasible:
        certificate = np.asarray(solution.z, dtype=np.float64)
        finite = certificate.shape == (b.size,) and np.all(np.isfinite(certificate))
        return None, certificate if finite else None
    if solution.status not in _ANSWERED and not _nearly_solved(solution):
        return None, None
    x = np.asarray(solution.x, dtype=np.float64)
    return (x if x.shape == (n,) and np.all(np.isfinite(x)) else None), None


def _nearly_solved(solution: Any) -> bool:
    """Whether a Clarabel run that stalled (InsufficientProgress, MaxIterations) stopped at
    an answer feasible within ``REDUCED_TOLERANCE`` and optimal within ``STALLED_TOLERANCE``
    (dual residual and gap relative to the objective)."""
    if solution.status not in _STALLED:
        return False
    gap = abs(solution.obj_val - solution.obj_val_dual) / max(1.0, abs(solution.obj_val))
    return bool(
        solution.r_prim <= REDUCED_TOLERANCE
        and solution.r_dual <= STALLED_TOLERANCE
        and gap <= STALLED_TOLERANCE
    )


def _curve(layout: _Layout, x: FloatArray, times: FloatArray, d: int) -> PiecewiseBezier:
    segments = []
    for j in range(layout.n_phases):
        start = layout.point(j, 0)
        ctrl = x[start : start + (d + 1) * 3].reshape(d + 1, 3)
        segments.append(BezierCurve(ctrl, float(times[j]), float(times[j + 1])))
    return PiecewiseBezier(tuple(segments))


__all__ = ["DynamicCom", "DynamicSettings", "dynamic_com"]
