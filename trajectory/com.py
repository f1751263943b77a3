"""COM trajectories through contact phases: quasi-static polylines and 2PAC Bezier curves.

Glossary: c(j) a COM point of phase j, c(j,j+1) the transition point between phases j and
j+1 (an attractor when used as a control point), T a duration in seconds, tau in [0, 1]
the normalised curve parameter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from trajectory._types import FloatArray, as_float_array
from trajectory.bezier import BezierCurve, PiecewiseBezier
from trajectory.contacts import Contact, ContactPhase
from trajectory.equilibrium import (
    EQ1_TOLERANCE,
    equilibrium_halfspaces,
    holds_at,
    settled_by_weights,
)
from trajectory.polytope import Halfspaces, stack
from trajectory.transition import (
    TransitionCost,
    TransitionPoint,
    check_transition_point,
    transition_point,
    transition_qp_generators,
)

SMOOTHSTEP_PEAK_ACC = 10.0 / math.sqrt(3.0)
"""Peak |s''| of the quintic smoothstep 10 t^3 - 15 t^4 + 6 t^5 on [0, 1]."""


@dataclass(frozen=True, slots=True, eq=False)
class BoundaryState:
    """COM position (3,) m, velocity (3,) m/s and acceleration (3,) m/s^2, world frame."""

    position: FloatArray
    velocity: FloatArray | None = None
    acceleration: FloatArray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", as_float_array(self.position, (3,), "position"))
        for name in ("velocity", "acceleration"):
            value = getattr(self, name)
            arr = np.zeros(3) if value is None else np.array(value, dtype=np.float64)
            object.__setattr__(self, name, as_float_array(arr, (3,), name))

    @property
    def vel(self) -> FloatArray:
        """Velocity (3,), never None."""
        assert self.velocity is not None
        return self.velocity

    @property
    def acc(self) -> FloatArray:
        """Acceleration (3,), never None."""
        assert self.acceleration is not None
        return self.acceleration


def _boundary_points(
    start: BoundaryState, end: BoundaryState, n: int, duration: float
) -> tuple[FloatArray, FloatArray]:
    """First three and last three control points imposing position, velocity, acceleration."""
    p0 = start.position
    p1 = p0 + start.vel * duration / n
    p2 = start.acc * duration**2 / (n * (n - 1)) + 2.0 * p1 - p0
    q0 = end.position
    q1 = q0 - end.vel * duration / n
    q2 = end.acc * duration**2 / (n * (n - 1)) + 2.0 * q1 - q0
    return np.array([p0, p1, p2]), np.array([q2, q1, q0])


def attractor_curve(
    start: BoundaryState,
    end: BoundaryState,
    attractors: FloatArray,
    duration: float,
    t0: float = 0.0,
) -> BezierCurve:
    """2PAC curve of degree 5 + m with m attractors as middle control points (Eq. 8, 9).

    attractors (m, 3); with m = 1 this is Eq. 8 (degree 6), m = 2 Eq. 9 (degree 7).
    """
    att = np.asarray(attractors, dtype=np.float64).reshape(-1, 3)
    if duration <= 0 or not np.isfinite(duration):
        raise ValueError(f"duration: must be positive and finite, got {duration}")
    n = 5 + att.shape[0]
    head, tail = _boundary_points(start, end, n, duration)
    return BezierCurve(np.vstack([head, att, tail]), t0, t0 + duration)


def _polyline_times(points: FloatArray, max_acceleration: float) -> FloatArray:
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    durations = np.sqrt(SMOOTHSTEP_PEAK_ACC * lengths / max_acceleration)
    return np.concatenate([[0.0], np.cumsum(np.maximum(durations, 1e-3))])


def polyline_parametrisation(points: FloatArray, tau: FloatArray) -> FloatArray:
    """Epsilon-feasible s(tau) of a polyline (k, 3): at rest at every vertex, tau (n,) in [0, 1].

    Segment times are proportional to sqrt(length) (equal peak acceleration on every
    segment) and each segment follows a quintic smoothstep.
    """
    times = _polyline_times(points, 1.0)
    t = np.asarray(tau, dtype=np.float64) * times[-1]
    idx = np.clip(np.searchsorted(times, t, side="right") - 1, 0, points.shape[0] - 2)
    local = np.clip((t - times[idx]) / (times[idx + 1] - times[idx]), 0.0, 1.0)
    s = local**3 * (10.0 - 15.0 * local + 6.0 * local**2)
    out: FloatArray = points[idx] + s[:, None] * (points[idx + 1] - points[idx])
    return out


def quasi_static_polyline(
    points: FloatArray, max_acceleration: float = 0.05, t0: float = 0.0
) -> PiecewiseBezier:
    """Polyline c(1) c(1,2) c(2) ... as rest-to-rest quintic segments (epsilon-feasible).

    points (k, 3), k >= 2; each segment is a degree-5 Bezier with control points
    (a, a, a, b, b, b), so it stays on the segment, starts and ends at rest, and its peak
    acceleration is ``max_acceleration`` (m/s^2).
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 2:
        raise ValueError(f"points: expected shape (k >= 2, 3), got {pts.shape}")
    if max_acceleration <= 0:
        raise ValueError(f"max_acceleration: must be positive, got {max_acceleration}")
    times = t0 + _polyline_times(pts, max_acceleration)
    segs = []
    for i in range(pts.shape[0] - 1):
        ctrl = np.repeat(pts[i : i + 2], 3, axis=0)
        segs.append(BezierCurve(ctrl, times[i], times[i + 1]))
    return PiecewiseBezier(tuple(segs))


def weierstrass_curve(
    polyline: FloatArray,
    degree: int,
    duration: float,
    start: BoundaryState | None = None,
    end: BoundaryState | None = None,
    t0: float = 0.0,
) -> BezierCurve:
    """Eq. 11: control points s(k / n) of the epsilon-feasible polyline, k = 0..n.

    With boundary states the first and last three control points impose them (n >= 5).
    """
    n = int(degree)
    if n < 5:
        raise ValueError(f"degree: must be >= 5, got {degree}")
    pts = polyline_parametrisation(np.asarray(polyline, dtype=np.float64), np.linspace(0, 1, n + 1))
    if start is not None or end is not None:
        st = start or BoundaryState(pts[0])
        en = end or BoundaryState(pts[-1])
        head, tail = _boundary_points(st, en, n, duration)
        pts[:3] = head
        pts[-3:] = tail
    return BezierCurve(pts, t0, t0 + duration)


def multi_attractor_curve(
    polyline: FloatArray,
    feasible: Sequence[Halfspaces],
    duration: float,
    *,
    start: BoundaryState | None = None,
    end: BoundaryState | None = None,
    max_degree: int = 40,
    n_checks: int = 64,
    tol: float = 1e-6,
) -> tuple[BezierCurve, bool]:
    """Eq. 10-11 with degree raising: the smallest degree whose curve keeps every check
    point inside the feasible set of the polyline segment it approximates.

    polyline (k, 3); feasible[i] is the constraint set of segment i (k - 1 items).
    Returns the curve and whether the constraints hold at all check points.
    """
    pts = np.asarray(polyline, dtype=np.float64)
    if len(feasible) != pts.shape[0] - 1:
        raise ValueError("feasible: one constraint set per polyline segment is needed")
    tau = np.linspace(0.0, 1.0, n_checks)
    times = _polyline_times(pts, 1.0)
    seg = np.clip(np.searchsorted(times / times[-1], tau, side="right") - 1, 0, len(feasible) - 1)
    curve = weierstrass_curve(pts, 5, duration, start, end)
    for n in range(max(5, pts.shape[0] - 1), max_degree + 1):
        curve = weierstrass_curve(pts, n, duration, start, end)
        c = curve(curve.t0 + tau * duration)
        ok = all(bool(np.all(feasible[i].violation(c[seg == i]) <= tol)) for i in np.unique(seg))
        if ok:
            return curve, True
    return curve, False


@dataclass(frozen=True, slots=True)
class PhaseReport:
    """Dynamic validation (Eq. 1) of one phase over [t0, t1] at n_samples points.

    fraction_valid in [0, 1]; worst_violation >= 0 is the largest negative robustness
    margin found, N (0 when every sample is valid); transition_slack from the QP.
    """

    phase: int
    t0: float
    t1: float
    n_samples: int
    fraction_valid: float
    worst_violation: float


@dataclass(frozen=True, slots=True, eq=False)
class ComTrajectory:
    """A planned COM trajectory.

    curve : Bezier segments with their times (s), world frame.
    transitions : one TransitionPoint per phase change.
    phase_times : (n_phases + 1,) start time of each phase and the end time, s.
    reports : per-phase dynamic validation (empty when validation was skipped).
    phase_methods : per phase, "2pac" (an attractor window of the sliding window) or
    "rest_to_rest" (its window fell back to stopping at the transition points because no
    stretch of the window gave the phase its minimum duration, see ``plan_com_trajectory``).
    """

    curve: PiecewiseBezier
    transitions: tuple[TransitionPoint, ...]
    phase_times: FloatArray
    reports: tuple[PhaseReport, ...]
    method: str
    phase_methods: tuple[str, ...] = ()

    @property
    def segments(self) -> tuple[BezierCurve, ...]:
        """The Bezier segments."""
        return self.curve.segments

    @property
    def quasi_static_feasible(self) -> bool:
        """True when every transition has a quasi-static solution."""
        return all(t.feasible for t in self.transitions)


def validate_dynamics(
    curve: PiecewiseBezier | BezierCurve,
    phases: Sequence[ContactPhase],
    phase_times: FloatArray,
    n_samples: int = 10,
    tol: float = EQ1_TOLERANCE,
) -> tuple[PhaseReport, ...]:
    """Check Eq. 1 (zero angular momentum rate) at n_samples times inside every phase,
    within ``tol`` N per kg (``trajectory.equilibrium.holds_at``, after the samples
    ``settled_by_weights`` settles)."""
    acc_curve = curve.derivative(2)
    spans = [(float(phase_times[j]), float(phase_times[j + 1])) for j in range(len(phases))]
    per_phase = [
        np.linspace(a, b, n_samples + 2)[1:-1] if b > a else np.full(1, a) for a, b in spans
    ]
    if not per_phase:
        return ()
    # every phase's samples in one evaluation of each curve
    ends = np.cumsum([0, *(ts.size for ts in per_phase)])
    every = np.concatenate(per_phase)
    positions, accelerations = curve(every), acc_curve(every)
    reports = []
    for j, phase in enumerate(phases):
        (a, b), ts = spans[j], per_phase[j]
        cs, accs = positions[ends[j] : ends[j + 1]], accelerations[ends[j] : ends[j + 1]]
        valid = settled_by_weights(phase, cs, accs)
        rest = np.flatnonzero(~valid)  # the LP answers them, and gives the margins of those failing
        worst = 0.0
        if rest.size:
            held, margins = holds_at(phase, cs[rest], accs[rest], tol)
            valid[rest] = held
            worst = float(-margins[~held].min()) if not held.all() else 0.0
        reports.append(PhaseReport(j, a, b, ts.size, float(np.mean(valid)), worst))
    return tuple(reports)


def _same_contact(a: Contact, b: Contact) -> bool:
    return a is b or (
        a.mu == b.mu
        and a.n_rays == b.n_rays
        and a.points.shape == b.points.shape
        and bool(np.array_equal(a.points, b.points))
        and bool(np.array_equal(a.normal, b.normal))
    )


def _nested(p: ContactPhase, q: ContactPhase) -> bool:
    """True when one phase's contacts are a subset of the other's."""
    small, big = (p, q) if len(p.contacts) <= len(q.contacts) else (q, p)
    return all(any(_same_contact(c, d) for d in big.contacts) for c in small.contacts)


def _closest_time(curve: BezierCurve, point: FloatArray, lo: float, hi: float) -> float:
    ts = np.linspace(lo, hi, 33)
    d = np.linalg.norm(curve(ts) - point, axis=1)
    return float(ts[int(np.argmin(d))])


def plan_com_trajectory(
    phases: Sequence[ContactPhase],
    start_com: FloatArray,
    end_com: FloatArray | None = None,
    *,
    kinematics: Sequence[Halfspaces | None] | None = None,
    method: Literal["2pac", "quasi_static"] = "2pac",
    formulation: Literal["auto", "polytope", "generators"] = "auto",
    cost: TransitionCost | None = None,
    w: float = 1000.0,
    seconds_per_metre: float = 4.0,
    min_window: float = 1.0,
    max_acceleration: float = 0.05,
    n_checks: int = 10,
    duration: float | None = None,
    user_transitions: Sequence[FloatArray | None] | None = None,
    targets: Sequence[FloatArray | None] | None = None,
    min_durations: Sequence[float] | None = None,
    max_stretch: float = 4.0,
    max_speed: float = math.inf,
) -> ComTrajectory:
    """Phases + start COM (+ end COM) -> COM trajectory with its transitions and report.

    kinematics: K c <= k per phase (None entries mean unconstrained). "2pac" uses
    attractor curves over windows of up to three phases joined with continuous velocity
    (sliding window, section 6.4.1); "quasi_static" the rest-to-rest polyline. Window
    durations are seconds_per_metre times the control polygon length (at least
    min_window), or the whole trajectory is uniformly rescaled to ``duration`` seconds when
    given. n_checks samples per phase for the dynamic report (0 skips it).
    user_transitions: one entry per phase change, a (3,) point placed by the user (checked
    for feasibility against both phases, never moved) or None to compute it.
    formulation "polytope" solves Eq. 6 on the equilibrium polytopes of both phases (any
    cost); "generators" solves Eq. 13 with the generator weights of the phase with fewer
    contact points (no polytope is computed; distance cost only), which is faster and
    exact when consecutive contact sets are nested; "auto" picks "generators" when the
    cost is the default distance and every change adds or removes contacts, else "polytope".
    targets: one entry per phase change, the point the "tired", "groovy" and "to_one_side"
    costs aim at (None: the end COM for the last change, no target otherwise).
    min_durations: one entry per phase, s (2pac only): each window of the sliding window is
    slowed down until every phase it decides lasts at least its minimum (a swing needs its
    time); a window that would need more than ``max_stretch`` times its nominal duration
    falls back to rest-to-rest segments through its transition points with those durations
    (``phase_methods`` says which phases did). max_speed: m/s (2pac only), each window is
    also slowed down until the COM speed stays under it.
    """
    phases = list(phases)
    if not phases:
        raise ValueError("phases: at least one contact phase is needed")
    if method not in ("2pac", "quasi_static"):
        raise ValueError(f"method: expected '2pac' or 'quasi_static', got {method!r}")
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration: must be positive and finite, got {duration}")
    if formulation not in ("auto", "polytope", "generators"):
        raise ValueError(
            f"formulation: expected 'auto', 'polytope' or 'generators', got {formulation!r}"
        )
    start = as_float_array(start_com, (3,), "start_com")
    end = None if end_com is None else as_float_array(end_com, (3,), "end_com")
    if kinematics is not None and len(kinematics) != len(phases):
        raise ValueError("kinematics: one entry per phase is needed")
    free = Halfspaces(np.zeros((0, 3)), np.zeros(0))
    kins: list[Halfspaces] = (
        [free] * len(phases)
        if kinematics is None
        else [free if k is None else k for k in kinematics]
    )
    cost = cost or TransitionCost()
    nested = [_nested(phases[j], phases[j + 1]) for j in range(len(phases) - 1)]
    if formulation == "auto":
        fast = cost.kind == "distance" and all(nested)
        formulation = "generators" if fast else "polytope"
    if formulation == "polytope":
        eqs = [equilibrium_halfspaces(p) for p in phases]
    else:
        eqs = [free] * len(phases)

    if user_transitions is not None and len(user_transitions) != len(phases) - 1:
        raise ValueError("user_transitions: one entry per phase change is needed")
    if targets is not None and len(targets) != len(phases) - 1:
        raise ValueError("targets: one entry per phase change is needed")
    if min_durations is not None and len(min_durations) != len(phases):
        raise ValueError("min_durations: one entry per phase is needed")
    if min_durations is not None and not all(np.isfinite(d) and d >= 0.0 for d in min_durations):
        raise ValueError("min_durations: must be finite and >= 0")
    if not max_speed > 0:
        raise ValueError(f"max_speed: must be positive, got {max_speed}")
    if not (np.isfinite(max_stretch) and max_stretch >= 1.0):
        raise ValueError(f"max_stretch: must be >= 1, got {max_stretch}")
    transitions: list[TransitionPoint] = []
    c_prev = start
    for j in range(len(phases) - 1):
        tgt = end if (end is not None and j == len(phases) - 2) else None
        if targets is not None and targets[j] is not None:
            tgt = as_float_array(targets[j], (3,), f"targets[{j}]")
        placed = None if user_transitions is None else user_transitions[j]
        if placed is not None:
            pair = [equilibrium_halfspaces(phases[j]), equilibrium_halfspaces(phases[j + 1])]
            tp = check_transition_point(
                as_float_array(placed, (3,), f"user_transitions[{j}]"),
                pair,
                [kins[j], kins[j + 1]],
            )
        elif formulation == "polytope":
            tp = transition_point(
                eqs[j],
                eqs[j + 1],
                c_prev,
                kin_prev=kins[j],
                kin_next=kins[j + 1],
                w=w,
                cost=replace(cost, index=j),
                target=tgt,
            )
        else:
            a, b = phases[j], phases[j + 1]
            fewer = a if a.n_points <= b.n_points else b
            tp = transition_qp_generators(fewer, stack([kins[j], kins[j + 1]]), c_prev, w=w)
        transitions.append(tp)
        c_prev = tp.point
    tpts = np.array([t.point for t in transitions]).reshape(-1, 3)
    final = end if end is not None else (tpts[-1] if len(tpts) else start)

    if method == "quasi_static" or len(phases) == 1:
        poly = np.vstack([start, tpts, final])
        curve = quasi_static_polyline(poly, max_acceleration)
        phase_times = curve.breaks[: len(phases) + 1].copy()
        phase_times[-1] = curve.t1
        if len(phases) == 1:
            phase_times = np.array([curve.t0, curve.t1])
        phase_methods = ("quasi_static",) * len(phases)
    else:
        window = _Window(
            eqs,
            kins,
            seconds_per_metre,
            min_window,
            np.zeros(len(phases)) if min_durations is None else np.asarray(min_durations),
            max_stretch,
            max_acceleration,
            max_speed,
        )
        curve, phase_times, phase_methods = _sliding_window(window, start, tpts, final)
    if duration is not None:
        scale = duration / (curve.t1 - curve.t0)
        curve = PiecewiseBezier(
            tuple(seg.retimed(seg.t0 * scale, seg.t1 * scale) for seg in curve.segments)
        )
        phase_times = phase_times * scale
    reports = validate_dynamics(curve, phases, phase_times, n_checks) if n_checks > 0 else ()
    return ComTrajectory(curve, tuple(transitions), phase_times, reports, method, phase_methods)


@dataclass(frozen=True, slots=True)
class _Window:
    """What every window of the sliding window needs: per phase equilibrium and kinematic
    sets and minimum durations (s); the nominal pace (s per metre of control polygon, at
    least ``min_window`` s per window), the largest slow-down before a window falls back,
    and the peak acceleration (m/s^2) of the fallback's rest-to-rest segments."""

    eqs: Sequence[Halfspaces]
    kins: Sequence[Halfspaces]
    seconds_per_metre: float
    min_window: float
    min_durations: FloatArray
    max_stretch: float
    max_acceleration: float
    max_speed: float


def _window_curve(
    w: _Window,
    state: BoundaryState,
    att: FloatArray,
    goal: FloatArray,
    j: int,
    t: float,
    phase_start: float,
    last: bool,
) -> tuple[BezierCurve, float, list[float]] | None:
    """The shortest attractor curve of the window over phases j..j+len(att) starting at t
    (phase j began at ``phase_start``) that gives each phase it decides its minimum
    duration: (curve, cut time, switch times), or None when none does within
    ``max_stretch`` times the nominal duration.

    Candidates differ by extra control points spread on the segment after the first
    attractor (toward the second one, or toward the goal in the last window): the curve
    lingers there, which gives that phase (a swing) a larger share of the window. The
    points lie between two points of the phase's convex feasible set, so inside it.
    """
    best: tuple[BezierCurve, float, list[float]] | None = None
    after = att[1] if len(att) > 1 else goal
    # where the window may be cut: the next phase's equilibrium and kinematic sets (once)
    target_set = None if last else stack([w.eqs[j + len(att)], w.kins[j + len(att)]])
    # most extra points first: the curve that lingers most is nearly always the shortest
    # (7 or 8 extra points in all 114 windows of six plans: walks, stairs, rubble), and a
    # candidate is dropped as soon as it would end after the best so far; of equals, the
    # one with the fewest extra points is kept. Fewer points are tried only while they do
    # no worse: the first that ends later (or finds no curve) after one was found ends the
    # search
    for extra in range(MAX_EXTRA_ATTRACTORS, -1, -1):
        fractions = np.arange(1, extra + 1) / (extra + 1)
        middle = att[0] + fractions[:, None] * (after - att[0])
        points = np.vstack([att[:1], middle, att[1:]])
        no_later = math.inf if best is None else best[0].t1
        found = _stretched_curve(
            w, state, points, att, goal, j, t, phase_start, target_set, no_later
        )
        if found is not None and (best is None or found[0].t1 <= best[0].t1):
            best = found
        elif best is not None:
            break
    return best


MAX_EXTRA_ATTRACTORS = 8
"""Extra control points tried between a window's first attractor and the next point."""


def _stretched_curve(
    w: _Window,
    state: BoundaryState,
    points: FloatArray,
    att: FloatArray,
    goal: FloatArray,
    j: int,
    t: float,
    phase_start: float,
    target_set: Halfspaces | None,
    no_later: float = math.inf,
) -> tuple[BezierCurve, float, list[float]] | None:
    """The window's curve through control points ``points`` (its attractors ``att`` among
    them), slowed down until each phase gets its minimum duration; None beyond
    ``max_stretch`` times the nominal duration. ``target_set``: the sets of the phase after
    the window's last attractor, where the curve is cut (None: the last window, not cut).
    None as soon as the curve would end after ``no_later`` s (slowed more, it would only end
    later)."""
    last = target_set is None
    m = len(att)
    ctrl = np.vstack([state.position, points, goal])
    length = float(np.sum(np.linalg.norm(np.diff(ctrl, axis=0), axis=1)))
    nominal = max(w.min_window, w.seconds_per_metre * length)
    duration = nominal
    for _ in range(8):
        if t + duration > no_later:
            return None
        curve = attractor_curve(state, BoundaryState(goal), points, duration, t)
        cut = curve.t1
        if target_set is not None:
            taus = np.linspace(0.6, 0.95, 15)
            inside = target_set.violation(curve(t + taus * duration)) <= 1e-9
            if np.any(inside):
                cut = t + float(taus[int(np.argmax(inside))]) * duration
        switches = []
        lo = t
        for a in att:
            lo = _closest_time(curve, a, lo, cut)
            switches.append(lo)
        # (time the phase gets, its minimum, the part of that time that grows with duration)
        spans: list[tuple[float, float, float | None]] = [
            (switches[0] - phase_start, float(w.min_durations[j]), switches[0] - t)
        ]
        spans += [
            (switches[i + 1] - switches[i], w.min_durations[j + 1 + i], None) for i in range(m - 1)
        ]
        if last:
            spans.append((cut - switches[-1], w.min_durations[j + m], None))
        speeds = np.linalg.norm(curve.derivative(1)(np.linspace(t, cut, 33)), axis=1)
        stretch = max(1.0, float(np.max(speeds)) / w.max_speed)
        for got, need, growing in spans:
            if got >= need - 1e-9:
                continue
            scalable = got if growing is None else growing
            if scalable <= 1e-9:
                return None
            stretch = max(stretch, (need - (got - scalable)) / scalable)
        if stretch <= 1.0:
            return curve, cut, switches
        duration *= stretch * 1.02
        if duration > w.max_stretch * nominal:
            return None
    return None


def _rest_to_rest(
    w: _Window, state: BoundaryState, points: FloatArray, minimums: Sequence[float], t: float
) -> list[BezierCurve]:
    """Quintic segments from ``state`` through ``points`` (k, 3), at rest at each point,
    segment i lasting at least minimums[i] s and long enough that its acceleration peak
    stays under ``max_acceleration``; the first segment starts with the state's velocity
    and acceleration."""
    segments = []
    for i, b in enumerate(points):
        a = state.position
        length = float(np.linalg.norm(b - a))
        duration = max(
            float(minimums[i]), math.sqrt(SMOOTHSTEP_PEAK_ACC * length / w.max_acceleration), 1e-3
        )
        head, tail = _boundary_points(state, BoundaryState(b), 5, duration)
        segments.append(BezierCurve(np.vstack([head, tail]), t, t + duration))
        t += duration
        state = BoundaryState(b)
    return segments


def _sliding_window(
    w: _Window, start: FloatArray, tpts: FloatArray, final: FloatArray
) -> tuple[PiecewiseBezier, FloatArray, tuple[str, ...]]:
    """2PAC's sliding window (section 6.4.1): windows of up to two attractors, each from the
    state the previous one was cut at, joined with continuous velocity and acceleration."""
    n_phases = len(w.eqs)
    # rest points of the intermediate phases: midpoints of consecutive transition points
    rest = [start]
    for j in range(1, n_phases - 1):
        rest.append(0.5 * (tpts[j - 1] + tpts[j]))
    rest.append(final)
    state = BoundaryState(start)
    t = 0.0
    j = 0
    segments: list[BezierCurve] = []
    switches: list[float] = []
    methods: list[str] = []
    while j < n_phases - 1:
        m = 2 if j + 2 <= n_phases - 1 else 1
        att = tpts[j : j + m]
        last = j + m == n_phases - 1
        phase_start = switches[-1] if switches else 0.0
        found = _window_curve(w, state, att, rest[j + m], j, t, phase_start, last)
        if found is None:
            # no stretch gives every phase its time: stop at the transition points instead
            points = np.vstack([att, final[None, :]]) if last else att
            spent = t - phase_start
            minimums = [max(w.min_durations[j] - spent, 0.0), *w.min_durations[j + 1 : j + m]]
            if last:
                minimums.append(w.min_durations[j + m])
            pieces = _rest_to_rest(w, state, points, minimums, t)
            segments.extend(pieces)
            switches.extend(piece.t1 for piece in pieces[:m])
            methods.extend(["rest_to_rest"] * (m + 1 if last else m))
            state = BoundaryState(att[-1]) if not last else BoundaryState(final)
            t = pieces[-1].t1
            j += m
            continue
        curve, cut, window_switches = found
        switches.extend(window_switches)
        methods.extend(["2pac"] * (m + 1 if last else m))
        if cut < curve.t1:
            piece, _ = curve.split(cut)
            vel = curve.derivative(1)(cut)
            acc = curve.derivative(2)(cut)
            state = BoundaryState(piece.control_points[-1], vel, acc)
        else:
            piece = curve
            state = BoundaryState(rest[j + m])
        segments.append(piece)
        t = piece.t1
        j += m
    phase_times = np.array([0.0, *switches, t])
    return PiecewiseBezier(tuple(segments)), phase_times, tuple(methods)
