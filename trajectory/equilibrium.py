"""Static equilibrium of a contact phase: the COM polytope (Eq. 2) and the robustness LP (Eq. 12).

Under gravity alone the static-equilibrium COM region is a vertical prism over a convex
polygon (the z column of A is zero), so the polytope is computed as the 2D projection of
the force polytope {beta >= 0 : sum f = m g e_z, sum tau_z = 0} by the incremental
support-function method of Bretl and Lall (2008): each support LP either confirms an edge of
the inner polygon or adds a vertex, so the result is exact up to the LP tolerance. Unbounded
regions (hands pressing opposite walls) are clipped by a large box whose edges are removed
afterwards; degenerate regions (a point, a segment) become pairs of opposite rows.

Glossary: beta generator weights (unit force rays, scaled so the weight is 1 in the
projection), E (4, m) force and z-moment rows, L (2, m) map to the COM (x, y), u = (x, y).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy.optimize import nnls

from trajectory import _solvers
from trajectory._memo import Remembered
from trajectory._types import GRAVITY, TOL, BoolArray, FloatArray
from trajectory.contacts import ContactPhase, gravity_wrench
from trajectory.polytope import Halfspaces

_EMPTY_A = np.array([[0.0, 0.0, 0.0]])
_EMPTY_B = np.array([-1.0])
_UNIT_WEIGHT = np.array([0.0, 0.0, 1.0, 0.0])
# daqp's proximal weight for the primal support LP (an LP needs a proximal term in daqp;
# the iterations converge to the LP's exact optimum whatever its size)
_PRIMAL_PROXIMAL = 1e-3


def _projection_data(phase: ContactPhase) -> tuple[FloatArray, FloatArray, FloatArray]:
    """E (4, m), L (2, m) about the contact centroid o (3,)."""
    gens = phase.wrench_generators
    pts = np.vstack([c.points for c in phase.contacts])
    origin = pts.mean(axis=0)
    forces = gens[:, :3]
    torques = gens[:, 3:] - np.cross(origin, forces)
    E = np.vstack([forces.T, torques[:, 2]])
    L = np.vstack([-torques[:, 1], torques[:, 0]])
    return E, L, origin


class _Support:
    """Support function of the projected polygon.

    Primal: max theta' L beta s.t. E beta = e, 1' beta <= B, beta >= 0 (B bounds the total
    contact force, in body weights, so the LP is always bounded). Solved through its
    5-variable dual, min e'y + B zeta s.t. E'y + zeta 1 >= L' theta, zeta >= 0, as a
    slightly regularised QP; the primal point comes from the multipliers and is certified
    by the duality gap, otherwise the primal LP is solved instead (daqp's proximal LP, and
    HiGHS when that fails). ``last_bound_active`` tells whether the force bound shaped the
    answer (then it is an artefact of B).

    The dual's answer is left uncertified where the primal optimum is degenerate (a vertex
    held by two generators: the dual optimum is then a face, and daqp's point on it misses
    dual feasibility by about 1e-6): 60 % of the support calls of a flat walk. The primal LP
    through daqp answers those in 0.2 ms against HiGHS' 3 ms through scipy, within 1e-10
    of HiGHS' optimum on the same calls.
    """

    def __init__(self, E: FloatArray, L: FloatArray, bound: float) -> None:
        m = E.shape[1]
        self.L = L
        self.E = E
        self.m = m
        self.bound = bound
        self.H = np.eye(5) * 1e-9
        self.f = np.array([0.0, 0.0, 1.0, 0.0, bound])
        self.A = np.hstack([E.T, np.ones((m, 1))])
        self.upper = np.full(5 + m, _solvers.INF)
        self.lower = np.concatenate([np.full(4, -_solvers.INF), np.zeros(1), np.zeros(m)])
        self.sense = np.zeros(5 + m, dtype=np.int32)
        self.LT = np.ascontiguousarray(L.T)
        self.calls = 0
        self.fallbacks = 0
        self.last_bound_active = False
        # the primal LP for daqp: beta (m,) >= 0, E beta = e (4 rows), 1' beta <= B
        self.primal_H = np.zeros((m, m))
        self.primal_A = np.vstack([E, np.ones((1, m))])
        self.primal_upper = np.concatenate([np.full(m, _solvers.INF), _UNIT_WEIGHT, [bound]])
        self.primal_lower = np.concatenate([np.zeros(m), _UNIT_WEIGHT, [-_solvers.INF]])
        self.primal_sense = np.zeros(m + 5, dtype=np.int32)
        self.primal_sense[m : m + 4] = _solvers.EQUALITY

    def __call__(self, theta: FloatArray) -> FloatArray | None:
        """Extreme point (2,) in direction theta (2,), or None when the region is empty."""
        self.calls += 1
        rhs = self.LT @ theta
        self.lower[5:] = rhs
        x, _, flag, lam = _solvers.solve_raw(
            self.H, self.f, self.A, self.upper, self.lower, self.sense, eps_prox=0.0
        )
        if flag == 1:
            beta = -lam[5:]
            out: FloatArray = self.L @ beta
            value = float(theta @ out)
            res = self.E @ beta - _UNIT_WEIGHT
            if (
                float(res @ res) <= 1e-14
                and beta.min() >= -1e-7
                and beta.sum() <= self.bound * (1.0 + 1e-9)
                and x[4] >= -1e-6
                and (self.A @ x - rhs).min() >= -1e-6
                and abs(float(self.f @ x) - value) <= 1e-7 * max(1.0, abs(value))
            ):
                self.last_bound_active = bool(x[4] > 1e-9)
                return out
        return self._fallback(theta)

    def _fallback(self, theta: FloatArray) -> FloatArray | None:
        """Primal LP, used only when the fast dual answer is not certified: daqp's proximal
        LP when it answers a feasible optimum, else HiGHS."""
        self.fallbacks += 1
        cost = -(self.LT @ theta)
        beta, _, flag, lam = _solvers.solve_raw(
            self.primal_H,
            cost,
            self.primal_A,
            self.primal_upper,
            self.primal_lower,
            self.primal_sense,
            eps_prox=_PRIMAL_PROXIMAL,
        )
        if flag == 1:
            res = self.E @ beta - _UNIT_WEIGHT
            if (
                float(res @ res) <= 1e-14
                and beta.min() >= -1e-9
                and beta.sum() <= self.bound * (1.0 + 1e-9)
            ):
                self.last_bound_active = abs(float(lam[self.m + 4])) > 1e-9
                out: FloatArray = self.L @ beta
                return out
        return self._highs(theta)

    def _highs(self, theta: FloatArray) -> FloatArray | None:
        """The primal LP with HiGHS (through scipy)."""
        from scipy.optimize import linprog

        res = linprog(
            -(self.L.T @ theta),
            A_ub=np.ones((1, self.m)),
            b_ub=np.array([self.bound]),
            A_eq=self.E,
            b_eq=_UNIT_WEIGHT,
            bounds=(0.0, None),
            method="highs",
        )
        if res.status != 0:
            return None
        marginal = float(res.ineqlin.marginals[0]) if res.ineqlin is not None else 0.0
        self.last_bound_active = abs(marginal) > 1e-9
        point: FloatArray = self.L @ res.x
        return point


def _ccw_hull(points: FloatArray, tol: float) -> FloatArray:
    """Vertices (k, 2) of the convex hull in counter-clockwise order (monotone chain)."""
    order = np.lexsort((points[:, 1], points[:, 0]))
    srt = points[order]
    keep = [srt[0]]
    for p in srt[1:]:
        if np.linalg.norm(p - keep[-1]) > tol:
            keep.append(p)
    pts = np.array(keep)
    if pts.shape[0] <= 2:
        return pts

    def cross(o: FloatArray, a: FloatArray, b: FloatArray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list[FloatArray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[FloatArray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


_Edges = tuple[FloatArray, FloatArray]


def _project_polygon(support: _Support, tol: float) -> _Edges | None:
    """True edges (normals (k, 2), offsets (k,)) of the projected polygon; None if empty.

    Edges whose supporting LP was shaped by the force bound are artefacts and dropped.
    Degenerate polygons (a point, a segment, a line) come back as pairs of opposite rows.
    """
    axes = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    found = []
    for d in axes:
        p = support(d)
        if p is None:
            return None
        found.append(p)
    verts = _ccw_hull(np.array(found), tol)
    if verts.shape[0] == 1:
        return _point_rows(verts[0])
    if verts.shape[0] == 2:
        seg = _try_segment(support, verts[0], verts[1], tol)
        if seg is None or isinstance(seg, tuple):
            return seg
        verts = seg
    return _refine(support, verts, tol)


def _try_segment(
    support: _Support, p: FloatArray, q: FloatArray, tol: float
) -> _Edges | FloatArray | None:
    """Rows of the segment pq if the region is that segment, else the enlarged hull."""
    d = (q - p) / np.linalg.norm(q - p)
    n = np.array([d[1], -d[0]])
    extra = []
    for s in (n, -n):
        r = support(s)
        if r is None:
            return None
        if float(s @ (r - p)) > tol:
            extra.append(r)
    if extra:
        verts = _ccw_hull(np.vstack([p, q, *extra]), tol)
        if verts.shape[0] >= 3:
            return verts
    normals = [n, -n]
    offsets = [float(n @ p), -float(n @ p)]
    for s, end in ((d, q), (-d, p)):
        support(s)
        if not support.last_bound_active:
            normals.append(s)
            offsets.append(float(s @ end))
    return np.array(normals), np.array(offsets)


def _refine(support: _Support, verts: FloatArray, tol: float) -> _Edges | None:
    """Bretl-Lall refinement: query each unconfirmed edge normal until all are exact."""
    pts = [(float(x), float(y)) for x, y in verts]
    conf = [False] * len(pts)
    artefact = [False] * len(pts)
    queries = 0
    while queries < 300:
        try:
            i = conf.index(False)
        except ValueError:
            break
        n_v = len(pts)
        ax, ay = pts[i]
        bx, by = pts[(i + 1) % n_v]
        ex, ey = bx - ax, by - ay
        length = math.hypot(ex, ey)
        if length <= 1e-12:
            pts.pop(i)
            conf.pop(i)
            artefact.pop(i)
            continue
        normal = np.array([ey / length, -ex / length])
        queries += 1
        r = support(normal)
        if r is None:
            return None
        rx, ry = float(r[0]), float(r[1])
        gain = normal[0] * (rx - ax) + normal[1] * (ry - ay)
        if gain <= tol:
            conf[i] = True
            artefact[i] = support.last_bound_active
            continue
        pts.insert(i + 1, (rx, ry))
        conf.insert(i + 1, False)
        artefact.insert(i + 1, False)
        conf[i] = False
        _prune(pts, conf, artefact, i + 1)
    keep = [k for k in range(len(pts)) if not artefact[k]]
    v = np.array(pts)
    nxt = np.roll(v, -1, axis=0)
    e = nxt - v
    normals = np.stack([e[:, 1], -e[:, 0]], axis=1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.einsum("ij,ij->i", normals, v)
    return normals[keep], offsets[keep]


def _turn(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _prune(pts: list[tuple[float, float]], conf: list[bool], art: list[bool], k: int) -> None:
    """Drop the neighbours of the new vertex pts[k] that are no longer strictly convex."""
    while len(pts) > 3:
        n = len(pts)
        k %= n
        before = (k - 1) % n
        if _turn(pts[(k - 2) % n], pts[before], pts[k]) <= 1e-14:
            pts.pop(before)
            conf.pop(before)
            art.pop(before)
            k = k - 1 if before < k else k
            conf[(k - 1) % len(pts)] = False
            continue
        after = (k + 1) % n
        if _turn(pts[k], pts[after], pts[(k + 2) % n]) <= 1e-14:
            pts.pop(after)
            conf.pop(after)
            art.pop(after)
            k = k - 1 if after < k else k
            conf[k % len(pts)] = False
            continue
        break


def _point_rows(p: FloatArray) -> _Edges:
    n = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    return n, n @ p


_POLYGONS_KEPT = 512  # phases whose polygon is remembered (a plan's states, a few times over)
_POLYGONS: Remembered[Halfspaces] = Remembered(_POLYGONS_KEPT)


def _phase_key(phase: ContactPhase) -> bytes:
    """A digest of what :func:`project_polygon` reads: the phase's wrench generators, its
    contact points and the tolerances of the projection."""
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.array([TOL.force_bound, TOL.polygon]).tobytes())
    for array in (phase.wrench_generators, *(c.points for c in phase.contacts)):
        a = np.ascontiguousarray(array, dtype=np.float64)
        digest.update(str(a.shape).encode())
        digest.update(a.tobytes())
    return digest.digest()


def equilibrium_polygon(phase: ContactPhase) -> Halfspaces:
    """2D static-equilibrium region of the COM (x, y) as Halfspaces with unit rows, world frame.

    :func:`project_polygon`, remembered by content for the last ``_POLYGONS_KEPT`` phases
    (a plan asks again for its states' polygons: contact checks, 2PAC, the motion); the
    answer is read-only."""
    key = _phase_key(phase)
    return _POLYGONS.get(key, lambda: project_polygon(phase))


def project_polygon(phase: ContactPhase) -> Halfspaces:
    """:func:`equilibrium_polygon` computed anew (no memory: for benchmarks)."""
    if not phase.contacts:
        return Halfspaces(_EMPTY_A[:, :2], _EMPTY_B)
    E, L, origin = _projection_data(phase)
    support = _Support(E, L, TOL.force_bound)
    edges = _project_polygon(support, TOL.polygon)
    if edges is None:
        return Halfspaces(_EMPTY_A[:, :2], _EMPTY_B)
    normals, offsets = edges
    return Halfspaces(normals, offsets + normals @ origin[:2])


def equilibrium_polytope(phase: ContactPhase) -> tuple[FloatArray, FloatArray]:
    """COM static-equilibrium polytope (Eq. 2): c (3,) is in equilibrium iff A @ c <= b.

    A (k, 3) with unit rows and a zero z column, b (k,) in metres, world frame. An empty set
    of contacts (or an infeasible one) gives the single row 0 <= -1; k = 0 means every COM.
    """
    if not isinstance(phase, ContactPhase):
        raise ValueError(f"phase: expected a ContactPhase, got {type(phase).__name__}")
    poly = equilibrium_polygon(phase)
    A = np.hstack([poly.A, np.zeros((poly.A.shape[0], 1))])
    return A, poly.b.copy()


def equilibrium_halfspaces(phase: ContactPhase) -> Halfspaces:
    """``equilibrium_polytope`` as a Halfspaces value."""
    return Halfspaces(*equilibrium_polytope(phase))


def is_static_equilibrium(phase: ContactPhase, com: FloatArray) -> bool | BoolArray:
    """Static equilibrium test: com (3,) -> bool, com (n, 3) -> (n,) bool array."""
    c = np.asarray(com, dtype=np.float64)
    if c.shape[-1:] != (3,) or c.ndim not in (1, 2):
        raise ValueError(f"com: expected shape (3,) or (n, 3), got {c.shape}")
    poly = equilibrium_halfspaces(phase)
    inside = poly.contains(c, TOL.membership * 100)
    if c.ndim == 1:
        return bool(inside)
    return np.asarray(inside, dtype=bool)


@dataclass(frozen=True, slots=True, eq=False)
class EquilibriumMargin:
    """Result of the robustness LP (Eq. 12, Del Prete et al. 2016).

    feasible : the wrench can be produced with non-negative generator weights.
    margin : largest achievable minimum generator weight, N (negative when infeasible,
        -inf when the wrench cannot be produced at all, inf when internal forces make it
        unbounded).
    weights : (m,) generator weights in N (nan when unsolved), in the phase's generator order.
    """

    feasible: bool
    margin: float
    weights: FloatArray


_MARGIN_CAP = 1e7
_WEIGHT_FLOOR = -1e5


def equilibrium_margin(
    phase: ContactPhase, com: FloatArray, acc: FloatArray | None = None
) -> EquilibriumMargin:
    """Robustness LP: maximise b0 s.t. G beta = w(c, a), beta >= b0 (Eq. 12 with a margin).

    com (3,) metres, acc (3,) m/s^2 or None for static equilibrium; world frame.
    """
    c = np.asarray(com, dtype=np.float64)
    if c.shape != (3,):
        raise ValueError(f"com: expected shape (3,), got {c.shape}")
    a = None if acc is None else np.asarray(acc, dtype=np.float64).reshape(1, 3)
    return _margin(phase, c, a)


def _margin(phase: ContactPhase, com: FloatArray, acc: FloatArray | None) -> EquilibriumMargin:
    G = phase.wrench_generators
    m = G.shape[0]
    if m == 0:
        return EquilibriumMargin(False, -math.inf, np.zeros(0))
    return _wrench_margin(G, gravity_wrench(phase.mass, com, acc)[0], phase.mass)


def _wrench_margin(G: FloatArray, w: FloatArray, mass: float) -> EquilibriumMargin:
    """The robustness LP of the generators ``G`` (m, 6) for the wrench ``w`` (6,) of a body
    of ``mass`` kg: its dual when the duality gap certifies it, else the primal."""
    fast = _margin_dual(G, w, mass * GRAVITY)
    if fast is not None:
        return fast
    return _margin_primal(G, w, mass)


def margins_at(
    phase: ContactPhase, coms: FloatArray, accs: FloatArray
) -> tuple[BoolArray, FloatArray]:
    """:func:`equilibrium_margin` at each of n samples, COM positions (n, 3) m and
    accelerations (n, 3) m/s^2 (world frame): whether Eq. 1 holds (n,) and the margin (n,) N,
    the same answers as one call per sample (the same operations), the gravity wrenches
    computed at once (a curve's collocation samples)."""
    c = np.asarray(coms, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(accs, dtype=np.float64).reshape(-1, 3)
    if a.shape != c.shape:
        raise ValueError(f"accs: expected shape {c.shape}, got {a.shape}")
    G = phase.wrench_generators
    feasible = np.zeros(len(c), dtype=np.bool_)
    margins = np.full(len(c), -math.inf)
    if G.shape[0] == 0:
        return feasible, margins
    for i, w in enumerate(gravity_wrench(phase.mass, c, a)):
        result = _wrench_margin(G, w, phase.mass)
        feasible[i], margins[i] = result.feasible, result.margin
    return feasible, margins


EQ1_TOLERANCE = 1e-4
"""N per kg of body mass (1e-5 body weights: 9 mN on HyQ): how far a sample may miss Eq. 1
and still count as holding it (:func:`holds_at`). Round-off, not physics: where the
dynamic COM QP's linearisation is nearly exact, its answers miss Eq. 1 by 1e-7 to 1e-6
body weights at a sample or three, and an exact check paid a whole further round of the QP
for that (the walks of the quadruped, HyQ and the hexapod: three solves instead of two). A
first round misses it by 1e-5 to 1e-4 body weights and is still solved again."""


def holds_at(
    phase: ContactPhase, coms: FloatArray, accs: FloatArray, tolerance: float = EQ1_TOLERANCE
) -> tuple[BoolArray, FloatArray]:
    """Whether Eq. 1 holds within ``tolerance`` N per kg at each of n samples (COM positions
    and accelerations, (n, 3) each, world frame), and :func:`margins_at`'s margins (n,) N.

    A sample holds when its margin is at least -``tolerance`` times the mass or, where no
    generator weights give its wrench at all (margin -inf: a cone short of full rank, two
    point feet, whose wrenches have no torque about the line between them), when the wrench
    lies within that distance (N, N m) of the cone."""
    feasible, margins = margins_at(phase, coms, accs)
    limit = tolerance * phase.mass
    holds = feasible | (margins >= -limit)
    G = phase.wrench_generators
    unreached = np.flatnonzero(np.isneginf(margins))
    if unreached.size and G.shape[0]:
        c = np.asarray(coms, dtype=np.float64).reshape(-1, 3)[unreached]
        a = np.asarray(accs, dtype=np.float64).reshape(-1, 3)[unreached]
        for k, w in zip(unreached, gravity_wrench(phase.mass, c, a), strict=True):
            holds[k] = float(nnls(G.T, w)[1]) <= limit
    return holds, margins


def holds(
    phase: ContactPhase,
    coms: FloatArray,
    accs: FloatArray,
    tolerance: float = EQ1_TOLERANCE,
    weights: FloatArray | None = None,
) -> BoolArray:
    """:func:`holds_at`'s answers (n,) alone, most without its LP: the samples
    :func:`settled_by_weights` settles hold, the others take the LP."""
    c = np.asarray(coms, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(accs, dtype=np.float64).reshape(-1, 3)
    out = settled_by_weights(phase, c, a, weights)
    rest = np.flatnonzero(~out)
    if rest.size:
        out[rest] = holds_at(phase, c[rest], a[rest], tolerance)[0]
    return out


def settled_by_weights(
    phase: ContactPhase, coms: FloatArray, accs: FloatArray, weights: FloatArray | None = None
) -> BoolArray:
    """(n,) whether each sample (COM positions and accelerations, (n, 3) each) holds Eq. 1
    by nonnegative generator weights that give its wrench (to ``QUICK_RESIDUAL``): its LP
    margin is at least their smallest. Tried: the least-norm weights of the sample's wrench
    and, given ``weights`` (n, m) in body weights (a QP's, for a wrench near each sample's),
    those corrected by least norm to it. False says only that neither settles it."""
    c = np.asarray(coms, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(accs, dtype=np.float64).reshape(-1, 3)
    G = phase.wrench_generators
    if G.shape[0] == 0 or c.shape[0] == 0:
        return np.zeros(c.shape[0], dtype=np.bool_)
    wrenches = gravity_wrench(phase.mass, c, a) / (phase.mass * GRAVITY)
    inverse = _least_norm(G)  # (6, m)
    found = _exact_and_nonnegative(G, wrenches, wrenches @ inverse)
    if weights is not None:
        given = np.asarray(weights, dtype=np.float64).reshape(c.shape[0], G.shape[0])
        corrected = given + (wrenches - given @ G) @ inverse
        found |= _exact_and_nonnegative(G, wrenches, corrected)
    return found


QUICK_RESIDUAL = 1e-9
"""Body weights: how far generator weights may miss a sample's wrench and still show that it
holds Eq. 1 without the LP (:func:`holds`); far below ``EQ1_TOLERANCE`` (1e-5 body weights).
On the hexapod's walk 82 % of the checked samples hold by their least-norm weights, every
one of them holding by the LP too."""


def _exact_and_nonnegative(G: FloatArray, wrenches: FloatArray, weights: FloatArray) -> BoolArray:
    """(n,) whether each row of ``weights`` (n, m) is nonnegative and gives the wrench (a row
    of ``wrenches`` (n, 6), body weights) through ``G`` (m, 6) to ``QUICK_RESIDUAL``."""
    miss = np.abs(weights @ G - wrenches).max(axis=1)
    return np.asarray((weights.min(axis=1) >= 0.0) & (miss <= QUICK_RESIDUAL))


_GENERATOR_DATA_KEPT = 512  # generator sets whose LP data are kept (a plan's phases)
_LEAST_NORM: dict[int, tuple[FloatArray, FloatArray]] = {}
_DUAL_ROWS: dict[int, tuple[FloatArray, tuple[FloatArray, ...]]] = {}
Made = TypeVar("Made")


def _per_generators(
    memory: dict[int, tuple[FloatArray, Made]], G: FloatArray, make: Callable[[FloatArray], Made]
) -> Made:
    """``make(G)``, remembered in ``memory`` per read-only generators ``G`` (m, 6) (a phase's,
    asked at every sample of a curve; a writeable ``G`` may change: made again)."""
    if G.flags.writeable:
        return make(G)
    hit = memory.get(id(G))
    if hit is not None and hit[0] is G:
        return hit[1]
    value = make(G)
    if len(memory) >= _GENERATOR_DATA_KEPT:
        memory.clear()
    memory[id(G)] = (G, value)
    return value


def _least_norm(G: FloatArray) -> FloatArray:
    """(6, m): w @ it is the least-norm weights beta (m,) with G' beta = w for a wrench w
    (6,) that the generators ``G`` (m, 6) span (remembered per ``G``)."""
    return _per_generators(
        _LEAST_NORM, G, lambda g: np.asarray(np.linalg.pinv(g.T).T, dtype=np.float64)
    )


def _dual_rows(G: FloatArray) -> tuple[FloatArray, ...]:
    """The constant data of :func:`_margin_dual`'s LP for the generators ``G`` (m, 6): its
    Hessian (6, 6) (a tiny proximal term), rows [G; sum of G's rows] (m + 1, 6), upper and
    lower bounds (m + 1,) and the equality flags (m + 1,), remembered per ``G``. Not to be
    modified: they stay writable only because daqp's interface takes writable buffers (it
    reads them)."""
    return _per_generators(_DUAL_ROWS, G, _make_dual_rows)


def _make_dual_rows(G: FloatArray) -> tuple[FloatArray, ...]:
    m = G.shape[0]
    hessian = np.eye(6) * 1e-9
    A = np.vstack([G, G.sum(axis=0)])
    upper = np.concatenate([np.full(m, _solvers.INF), [1.0]])
    lower = np.concatenate([np.zeros(m), [1.0]])
    eq = np.zeros(m + 1, dtype=bool)
    eq[m] = True
    return hessian, A, upper, lower, eq


def _margin_dual(G: FloatArray, w: FloatArray, weight: float) -> EquilibriumMargin | None:
    """Dual of the robustness LP (6 variables): min w'y s.t. G'y >= 0, (G 1)'y = 1.

    The primal weights are the multipliers; the answer is returned only when the duality
    gap certifies it, else None. Wrenches are scaled by the weight for conditioning.
    """
    m = G.shape[0]
    ws = w / weight
    hessian, A, upper, lower, eq = _dual_rows(G)
    res = _solvers.solve(hessian, ws, A, upper, lower, eq, eps_prox=0.0)
    if not res.ok:
        return None
    lam = -res.dual
    b0 = float(lam[m])
    weights = lam[:m] + b0
    miss = G.T @ weights - ws
    residual = math.sqrt(float(miss @ miss))
    gap = abs(b0 - float(res.x @ ws))
    if residual > 1e-6 or gap > 1e-6 or float(lam[:m].min()) < -1e-7:
        return None
    if float((G @ res.x).min()) < -1e-6:
        return None
    return EquilibriumMargin(b0 >= -1e-9, b0 * weight, weights * weight)


def _margin_primal(G: FloatArray, w: FloatArray, mass: float) -> EquilibriumMargin:
    m = G.shape[0]
    # variables (beta (m), b0); rows: G beta = w (6), beta - b0 >= 0 (m)
    n = m + 1
    A = np.zeros((6 + m, n))
    A[:6, :m] = G.T
    A[6:, :m] = np.eye(m)
    A[6:, m] = -1.0
    upper = np.concatenate([np.full(m, _solvers.INF), [_MARGIN_CAP], w, np.full(m, _solvers.INF)])
    lower = np.concatenate([np.full(m, _WEIGHT_FLOOR), [-_solvers.INF], w, np.zeros(m)])
    eq = np.zeros(upper.shape[0], dtype=bool)
    eq[n : n + 6] = True
    f = np.zeros(n)
    f[m] = -1.0
    res = _solvers.solve(np.zeros((n, n)), f, A, upper, lower, eq)
    if not res.ok:
        return EquilibriumMargin(False, -math.inf, np.full(m, np.nan))
    b0 = float(res.x[m])
    if b0 >= 0.999 * _MARGIN_CAP:
        b0 = math.inf
    return EquilibriumMargin(b0 >= -1e-9 * mass * GRAVITY, b0, res.x[:m].copy())
