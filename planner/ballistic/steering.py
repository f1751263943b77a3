"""Closed-form parabola steering between root positions, batched over candidate pairs.

A jump from p0 to p1 lies in the vertical plane through both points. With the end points fixed
the only unknown is the takeoff angle alpha; we use t = tan(alpha). Every constraint (takeoff
and landing speed bounds, takeoff velocity in the takeoff cone, minus the landing velocity in
the landing cone) is a polynomial inequality of degree <= 2 in t, so the feasible set of t is a
finite union of intervals, computed exactly from the roots (see ``steer``). A cone meets the
plane in a convex wedge, so in exact arithmetic the set is one interval; ``n_components``
reports it if rounding ever splits it. Reference: the jump
paper (``../shared/papers/ballistic-jump-planner.txt``) and the design brief
``../shared/research/ballistic-planner-anchor.md`` sections 1, 2 and 8.

Glossary (all per pair, SI units, world frame, z up, gravity (0, 0, -g)):

- ``D`` horizontal distance hypot(dx, dy) (m); ``Z`` = z1 - z0 (m); ``r`` = hypot(D, Z).
- ``u`` (3,) horizontal unit direction from p0 to p1.
- ``t`` = tan(alpha), alpha the takeoff angle above the horizontal.
- ``xdot`` horizontal speed, constant in flight: xdot^2 = g D^2 / (2 (D t - Z)) (m/s).
- ``t_imp`` = 2 Z / D - t, the slope of the velocity at landing.
- ``V0`` = xdot (u + t e_z) takeoff velocity; ``Vimp`` = xdot (u + t_imp e_z) landing velocity.
- ``T`` = D / xdot = sqrt(2 (D t - Z) / g) flight time (s).
- ``n_h`` = n . u, ``n_z`` = n . e_z for a cone axis n; ``c`` = cos(atan(mu)) = 1 / sqrt(1 + mu^2).
- ``V_eff^2`` = min(v0max^2, vimpmax^2 + 2 g Z): both speed bounds are |V0|^2 <= bound.

Constraints, for D > 0:

- takeoff speed  |V0|^2 <= v^2  <=>  g D^2 t^2 - 2 D v^2 t + g D^2 + 2 Z v^2 <= 0 (v = v0max);
  any solution has D t > Z, so the chord condition t > Z / D is implied.
- landing speed  |Vimp|^2 <= w^2  <=>  the same with v^2 = w^2 + 2 g Z.
- ``u + t e_z`` in cone (n, mu)  <=>  n_h + t n_z >= 0  and
  (n_z^2 - c^2) t^2 + 2 n_h n_z t + n_h^2 - c^2 >= 0.
- ``-Vimp`` in cone (n1, mu1)  <=>  the cone test with axis -n1 at t_imp = 2 Z / D - t.

Force closure: the jump paper (section 3) declares configurations whose summed contact normal
vanishes invalid for the centroidal cone. We follow the paper and reject them (reason
``FORCE_CLOSURE``), signalled by a zero cone axis, which is what ``cones.centroidal_cone``
returns in that case. Treating the cone as the whole space (the 2017 authors' code) would accept
any takeoff direction from a configuration whose real wrench cone is not checked here at all;
rejecting is the conservative choice and keeps Kc a subset of the true cone.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

GRAVITY = 9.81
"""Default gravity magnitude (m/s^2)."""


class SteerFailure(enum.IntEnum):
    """Why a pair could not be steered (first failing reason in this order); OK on success."""

    OK = 0
    VERTICAL = 1  # D = 0: the vertical plane is undefined.
    FORCE_CLOSURE = 2  # a zero cone axis (summed normals vanish) at either end.
    TAKEOFF_SPEED = 3  # v0max^2 < g (Z + r): out of range for the takeoff bound alone.
    LANDING_SPEED = 4  # vimpmax^2 < g (r - Z): out of range for the landing bound alone.
    TAKEOFF_CONE_MISSES_PLANE = 5  # no direction of the plane's forward half lies in cone 0.
    LANDING_CONE_MISSES_PLANE = 6  # no landing direction of the plane lies in cone 1.
    EMPTY_INTERVAL = 7  # each constraint alone is satisfiable, all together are not (or too thin).
    NUMERIC = 8  # the chosen parabola failed the direct re-check of a bound.


class Choice(enum.Enum):
    """Which t to take in the feasible set.

    MIN_ENERGY: t* = (Z + r) / D (least |V0| and |Vimp|), clipped into the feasible set.
    MIN_TIME: the lowest feasible t (the flight time grows with t).
    MAX_CLEARANCE: the highest feasible t (z(s; t) grows with t at every s).
    MID: the midpoint of the widest feasible interval (the authors' code).
    """

    MIN_ENERGY = "min_energy"
    MIN_TIME = "min_time"
    MAX_CLEARANCE = "max_clearance"
    MID = "mid"


@dataclass(frozen=True, slots=True)
class SteerTolerances:
    """Numerical margins of the steering (all dimensionless unless stated)."""

    min_horizontal: float = 1e-6
    """D below this (m) is a vertical jump."""
    min_axis_norm: float = 1e-9
    """A cone axis shorter than this is the force-closure marker."""
    min_width: float = 1e-9
    """Feasible intervals narrower than this in t count as empty."""
    interior: float = 1e-6
    """The chosen t stays this fraction of the interval's width inside its ends."""
    recheck: float = 1e-9
    """Relative slack of the direct re-check of speeds and cone angles."""


def _frozen(array: object, dtype: type = np.float64) -> NDArray[Any]:
    out: NDArray[Any] = np.array(array, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True)
class Jump:
    """One parabola in the world frame.

    p0, p1 : (3,) takeoff and landing root positions (m). v0, vimp : (3,) velocities (m/s).
    t : tan of the takeoff angle. xdot : horizontal speed (m/s). duration : flight time (s).
    direction : (3,) horizontal unit vector u. apex : (3,) highest point of the flight (m).
    g : gravity magnitude (m/s^2).
    """

    p0: FloatArray
    p1: FloatArray
    v0: FloatArray
    vimp: FloatArray
    t: float
    xdot: float
    duration: float
    direction: FloatArray
    apex: FloatArray
    g: float = GRAVITY

    def position(self, time: FloatArray | float) -> FloatArray:
        """(m, 3) (or (3,)) root positions at flight times ``time`` (s)."""
        tau = np.asarray(time, dtype=np.float64)[..., None]
        gvec = np.array([0.0, 0.0, -self.g])
        return np.asarray(self.p0 + self.v0 * tau + 0.5 * gvec * tau**2, dtype=np.float64)

    def velocity(self, time: FloatArray | float) -> FloatArray:
        """(m, 3) (or (3,)) root velocities at flight times ``time`` (s)."""
        tau = np.asarray(time, dtype=np.float64)[..., None]
        gvec = np.array([0.0, 0.0, -self.g])
        return np.asarray(self.v0 + gvec * tau, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class SteerResult:
    """Batched steering outcome; rows of failed pairs hold NaN.

    ok : (N,) bool. reason : (N,) int8 ``SteerFailure`` codes.
    t : (N,) chosen tan(alpha). t_interval : (N, 2) the feasible interval (lo, hi) of t that
    contains the chosen t (the feasible set is one interval in exact arithmetic; see ``steer``).
    xdot : (N,) horizontal speed (m/s). v0, vimp : (N, 3) takeoff / landing velocities (m/s).
    duration : (N,) flight time T (s). apex : (N, 3) highest point of the flight (m).
    p0, p1 : (N, 3) the end points. direction : (N, 3) horizontal unit vectors u.
    n_components : (N,) number of disjoint feasible intervals found (1 on success, normally).
    """

    ok: BoolArray
    reason: NDArray[np.int8]
    t: FloatArray
    t_interval: FloatArray
    xdot: FloatArray
    v0: FloatArray
    vimp: FloatArray
    duration: FloatArray
    apex: FloatArray
    p0: FloatArray
    p1: FloatArray
    direction: FloatArray
    n_components: NDArray[np.int64]
    g: float = GRAVITY
    choice: Choice = field(default=Choice.MIN_ENERGY)

    def __len__(self) -> int:
        return int(self.ok.shape[0])

    def counts(self) -> dict[str, int]:
        """Number of pairs per outcome, keyed by ``SteerFailure`` name (zeros omitted)."""
        values, numbers = np.unique(self.reason, return_counts=True)
        return {SteerFailure(int(v)).name: int(k) for v, k in zip(values, numbers, strict=True)}

    def jump(self, i: int) -> Jump:
        """The i-th pair as a ``Jump``; raises ValueError if that pair failed."""
        if not self.ok[i]:
            raise ValueError(f"pair {i} failed: {SteerFailure(int(self.reason[i])).name}")
        return Jump(
            p0=self.p0[i],
            p1=self.p1[i],
            v0=self.v0[i],
            vimp=self.vimp[i],
            t=float(self.t[i]),
            xdot=float(self.xdot[i]),
            duration=float(self.duration[i]),
            direction=self.direction[i],
            apex=self.apex[i],
            g=self.g,
        )


# --------------------------------------------------------------------------------------------
# Closed forms


def min_launch_speed_sq(horizontal: FloatArray, rise: FloatArray, g: float = GRAVITY) -> FloatArray:
    """Least |V0|^2 to reach (D, Z): g (Z + sqrt(D^2 + Z^2)) (m^2/s^2); any shape."""
    d = np.asarray(horizontal, dtype=np.float64)
    z = np.asarray(rise, dtype=np.float64)
    return np.asarray(g * (z + np.hypot(d, z)), dtype=np.float64)


def range_prefilter(
    p0: FloatArray,
    p1: FloatArray,
    v0max: FloatArray | float,
    vimpmax: FloatArray | float,
    g: float = GRAVITY,
) -> BoolArray:
    """(N,) mask of pairs that the speed bounds alone allow (cones ignored).

    A jump exists for the speed bounds iff V_eff^2 >= g (Z + r), i.e. v0max^2 >= g (Z + r) and
    vimpmax^2 >= g (r - Z). Vertical pairs (D = 0) pass: the prefilter only rules out.
    """
    delta = np.asarray(p1, dtype=np.float64) - np.asarray(p0, dtype=np.float64)
    d = np.hypot(delta[..., 0], delta[..., 1])
    z = delta[..., 2]
    r = np.hypot(d, z)
    v0 = np.asarray(v0max, dtype=np.float64)
    vi = np.asarray(vimpmax, dtype=np.float64)
    return np.asarray((v0**2 >= g * (z + r)) & (vi**2 >= g * (r - z)))


@dataclass(frozen=True, slots=True)
class _Kinematics:
    xdot: FloatArray
    v0: FloatArray
    vimp: FloatArray
    duration: FloatArray
    apex: FloatArray


def _kinematics(
    p0: FloatArray, d: FloatArray, z: FloatArray, u: FloatArray, t: FloatArray, g: float
) -> _Kinematics:
    """Velocities, flight time and apex for given t (rows with D t <= Z give NaN)."""
    w = d * t - z
    with np.errstate(divide="ignore", invalid="ignore"):
        xdot = np.sqrt(g * d**2 / (2.0 * w))
        t_imp = 2.0 * z / d - t
        ez = np.array([0.0, 0.0, 1.0])
        v0 = xdot[:, None] * (u + t[:, None] * ez)
        vimp = xdot[:, None] * (u + t_imp[:, None] * ez)
        duration = np.sqrt(2.0 * w / g)
        # Highest point: the vertical speed vanishes at s* = D^2 t / (2 (D t - Z)), clipped
        # into the flight [0, D] (otherwise the highest point is an end point).
        s_star = np.clip(d**2 * t / (2.0 * w), 0.0, d)
        frac = np.divide(s_star, d, out=np.zeros_like(d), where=d > 0)
        z_star = p0[:, 2] + z * frac**2 + t * s_star * (1.0 - frac)
    apex = p0 + u * s_star[:, None]
    apex[:, 2] = z_star
    bad = ~(w > 0)
    for array in (xdot, duration):
        array[bad] = np.nan
    for array in (v0, vimp, apex):
        array[bad] = np.nan
    return _Kinematics(xdot=xdot, v0=v0, vimp=vimp, duration=duration, apex=apex)


def _geometry(p0: FloatArray, p1: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    delta = p1 - p0
    d = np.hypot(delta[:, 0], delta[:, 1])
    z = delta[:, 2]
    u = np.zeros_like(delta)
    safe = d > 0
    u[safe, 0] = delta[safe, 0] / d[safe]
    u[safe, 1] = delta[safe, 1] / d[safe]
    return d, z, u


def jump_at(p0: FloatArray, p1: FloatArray, t: float, g: float = GRAVITY) -> Jump:
    """The parabola from p0 (3,) to p1 (3,) with takeoff slope t; raises ValueError if none.

    No bound is checked here: use it to re-steer a pair at a t inside its feasible interval.
    """
    a = np.asarray(p0, dtype=np.float64).reshape(1, 3)
    b = np.asarray(p1, dtype=np.float64).reshape(1, 3)
    d, z, u = _geometry(a, b)
    if not (d[0] > 0 and d[0] * t - z[0] > 0):
        raise ValueError("no parabola: vertical pair or t <= Z / D")
    kin = _kinematics(a, d, z, u, np.array([t], dtype=np.float64), g)
    return Jump(
        p0=_frozen(a[0]),
        p1=_frozen(b[0]),
        v0=_frozen(kin.v0[0]),
        vimp=_frozen(kin.vimp[0]),
        t=float(t),
        xdot=float(kin.xdot[0]),
        duration=float(kin.duration[0]),
        direction=_frozen(u[0]),
        apex=_frozen(kin.apex[0]),
        g=g,
    )


def jumps_at(
    p0: FloatArray, p1: FloatArray, t: FloatArray, g: float = GRAVITY
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Batched (v0 (N, 3), vimp (N, 3), duration (N,), xdot (N,)) at slopes t (N,); NaN if none."""
    a = np.asarray(p0, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(p1, dtype=np.float64).reshape(-1, 3)
    d, z, u = _geometry(a, b)
    kin = _kinematics(a, d, z, u, np.asarray(t, dtype=np.float64).reshape(-1), g)
    return kin.v0, kin.vimp, kin.duration, kin.xdot


# --------------------------------------------------------------------------------------------
# Polynomial kernels


def _quadratic_roots(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """(N, 2) real roots of a t^2 + b t + c (NaN where missing); degenerate a -> linear root."""
    scale = np.maximum(np.maximum(np.abs(a), np.abs(b)), np.abs(c))
    scale = np.where(scale > 0, scale, 1.0)
    a, b, c = a / scale, b / scale, c / scale
    out = np.full((a.shape[0], 2), np.nan)
    disc = b * b - 4.0 * a * c
    quad = np.abs(a) > 1e-14
    real = quad & (disc >= 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(real, disc, 0.0))
        q = -0.5 * (b + np.where(b >= 0, sq, -sq))
        r1 = q / a
        r2 = np.where(q != 0, c / q, r1)
        out[:, 0] = np.where(real, r1, np.nan)
        out[:, 1] = np.where(real, r2, np.nan)
        lin = ~quad & (np.abs(b) > 1e-14)
        out[:, 0] = np.where(lin, -c / b, out[:, 0])
    out[~np.isfinite(out)] = np.nan
    return out


def _linear_root(p1: FloatArray, p0: FloatArray) -> FloatArray:
    """(N,) root of p1 t + p0 (NaN when p1 = 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(np.abs(p1) > 1e-14, -p0 / p1, np.nan)
    return np.asarray(root, dtype=np.float64)


def _poly(coeffs: tuple[FloatArray, ...], t: FloatArray) -> FloatArray:
    """Evaluate per-row polynomials (highest degree first, each (N,)) at t (N, S)."""
    out = np.zeros_like(t)
    for coefficient in coeffs:
        out = out * t + coefficient[:, None]
    return out


def _cone_coeffs(
    nh: FloatArray, nz: FloatArray, c: FloatArray
) -> tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray, FloatArray]]:
    """Linear (>= 0) and quadratic (>= 0) coefficients of ``u + t e_z`` in cone (n, c)."""
    lin = (nz, nh)
    quad = (nz**2 - c**2, 2.0 * nh * nz, nh**2 - c**2)
    return lin, quad


def _shift_reflect(
    quad: tuple[FloatArray, FloatArray, FloatArray], k: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Coefficients of q(k - t) from those of q(x) = A x^2 + B x + C."""
    a, b, c = quad
    return (a, -2.0 * a * k - b, a * k**2 + b * k + c)


def _recheck(
    a: FloatArray,
    b: FloatArray,
    kin: _Kinematics,
    unit0: FloatArray,
    c0: FloatArray,
    unit1: FloatArray,
    c1: FloatArray,
    vmax0: FloatArray,
    vmax1: FloatArray,
    g: float,
    slack: float,
) -> BoolArray:
    """Direct check of speeds, cones and the landing point from the velocity vectors."""
    with np.errstate(invalid="ignore"):
        s0 = np.linalg.norm(kin.v0, axis=1)
        s1 = np.linalg.norm(kin.vimp, axis=1)
        good = (s0 <= vmax0 * (1.0 + slack)) & (s1 <= vmax1 * (1.0 + slack))
        good &= np.einsum("ij,ij->i", kin.v0, unit0) >= c0 * s0 - slack * s0
        good &= -np.einsum("ij,ij->i", kin.vimp, unit1) >= c1 * s1 - slack * s1
        tau = kin.duration[:, None]
        landed = a + kin.v0 * tau + 0.5 * np.array([0.0, 0.0, -g]) * tau**2
        scale = np.maximum(1.0, np.linalg.norm(b - a, axis=1))
        good &= np.linalg.norm(landed - b, axis=1) <= 1e-9 * scale
    return np.asarray(good, dtype=bool)


def verify_jumps(
    p0: FloatArray,
    p1: FloatArray,
    t: FloatArray,
    n0: FloatArray,
    mu0: FloatArray | float,
    n1: FloatArray,
    mu1: FloatArray | float,
    *,
    v0max: FloatArray | float,
    vimpmax: FloatArray | float,
    g: float = GRAVITY,
    slack: float = 1e-9,
) -> BoolArray:
    """(N,) True where the parabola p0 -> p1 of slope t (N,) meets every bound (``steer``'s
    re-check): speeds, V0 in cone (n0, mu0), -Vimp in cone (n1, mu1), landing point.
    """
    a = _as_points(p0, "p0")
    b = _as_points(p1, "p1")
    n = a.shape[0]
    axis0 = np.broadcast_to(np.asarray(n0, dtype=np.float64), (n, 3))
    axis1 = np.broadcast_to(np.asarray(n1, dtype=np.float64), (n, 3))
    norm0 = np.linalg.norm(axis0, axis=1)
    norm1 = np.linalg.norm(axis1, axis=1)
    d, z, u = _geometry(a, b)
    ds = np.where(d > 0, d, 1.0)
    kin = _kinematics(a, ds, z, u, np.asarray(t, dtype=np.float64).reshape(-1), g)
    c0 = 1.0 / np.sqrt(1.0 + _as_rows(mu0, n, "mu0") ** 2)
    c1 = 1.0 / np.sqrt(1.0 + _as_rows(mu1, n, "mu1") ** 2)
    good = _recheck(
        a,
        b,
        kin,
        axis0 / np.where(norm0 > 0, norm0, 1.0)[:, None],
        c0,
        axis1 / np.where(norm1 > 0, norm1, 1.0)[:, None],
        c1,
        _as_rows(v0max, n, "v0max"),
        _as_rows(vimpmax, n, "vimpmax"),
        g,
        slack,
    )
    return np.asarray(good & (d > 0) & (norm0 > 0) & (norm1 > 0), dtype=bool)


@dataclass(frozen=True, slots=True)
class _Solution:
    lo: FloatArray
    hi: FloatArray
    chosen: FloatArray
    n_components: IntArray
    any_feasible: BoolArray
    cone0_alone: BoolArray
    cone1_alone: BoolArray


def _solve(
    d: FloatArray,
    z: FloatArray,
    r: FloatArray,
    u: FloatArray,
    unit0: FloatArray,
    c0: FloatArray,
    unit1: FloatArray,
    c1: FloatArray,
    v_eff2: FloatArray,
    g: float,
    choice: Choice,
    tol: SteerTolerances,
) -> _Solution:
    """Feasible set of t and the choice in it, for rows with D > 0 that pass the range test.

    Both speed bounds read |V0|^2 <= v^2 with v^2 = v0max^2 or vimpmax^2 + 2 g Z; for D t > Z
    their solution sets are nested, so the smaller v^2 (V_eff^2 > 0 here) gives the one
    quadratic g D^2 t^2 - 2 D V_eff^2 t + g D^2 + 2 Z V_eff^2 <= 0, whose solutions all have
    D t > Z.
    """
    n = d.shape[0]
    speed = (g * d**2, -2.0 * d * v_eff2, g * d**2 + 2.0 * z * v_eff2)
    # Cones (>= 0). Takeoff: u + t e_z in cone(n0). Landing: u + t_imp e_z in cone(-n1).
    lin0, quad0 = _cone_coeffs(np.einsum("ij,ij->i", unit0, u), unit0[:, 2], c0)
    k = 2.0 * z / d
    lin1_imp, quad1_imp = _cone_coeffs(-np.einsum("ij,ij->i", unit1, u), -unit1[:, 2], c1)
    lin1 = (-lin1_imp[0], lin1_imp[1] + lin1_imp[0] * k)
    quad1 = _shift_reflect(quad1_imp, k)

    roots = np.concatenate(
        [
            _quadratic_roots(*speed),
            _linear_root(*lin0)[:, None],
            _quadratic_roots(*quad0),
            _linear_root(*lin1)[:, None],
            _quadratic_roots(*quad1),
        ],
        axis=1,
    )
    roots.sort(axis=1)  # NaN last
    roots = np.where(np.isnan(roots), np.inf, roots)
    lo = np.concatenate([np.full((n, 1), -np.inf), roots], axis=1)
    hi = np.concatenate([roots, np.full((n, 1), np.inf)], axis=1)
    valid = lo < hi
    fin_lo, fin_hi = np.isfinite(lo), np.isfinite(hi)
    with np.errstate(invalid="ignore", over="ignore"):
        test = np.where(
            fin_lo & fin_hi,
            0.5 * (lo + hi),
            np.where(fin_lo, lo + 1.0, np.where(fin_hi, hi - 1.0, 0.0)),
        )
        ok_speed = _poly(speed, test) <= 0
        ok_cone0 = (_poly(lin0, test) >= 0) & (_poly(quad0, test) >= 0)
        ok_cone1 = (_poly(lin1, test) >= 0) & (_poly(quad1, test) >= 0)
    feasible = valid & ok_speed & ok_cone0 & ok_cone1

    # Merge adjacent feasible sub-intervals into components: group bounds per sub-interval.
    n_seg = lo.shape[1]
    idx = np.broadcast_to(np.arange(n_seg), (n, n_seg))
    last_gap = np.maximum.accumulate(np.where(~feasible, idx, -1), axis=1)
    next_gap = np.minimum.accumulate(np.where(~feasible, idx, n_seg)[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(n)[:, None]
    group_lo = lo[rows, np.clip(last_gap + 1, 0, n_seg - 1)]
    group_hi = hi[rows, np.clip(next_gap - 1, 0, n_seg - 1)]
    with np.errstate(invalid="ignore"):
        width = np.where(feasible, group_hi - group_lo, -np.inf)
    starts = feasible & np.concatenate([np.ones((n, 1), bool), ~feasible[:, :-1]], axis=1)

    # Choose t: the feasible point nearest to the target (or the widest component's middle).
    rows1 = np.arange(n)
    with np.errstate(invalid="ignore", divide="ignore"):
        if choice is Choice.MID:
            seg = np.argmax(width, axis=1)
        elif choice is Choice.MIN_TIME:
            seg = np.argmax(feasible, axis=1)
        elif choice is Choice.MAX_CLEARANCE:
            seg = n_seg - 1 - np.argmax(feasible[:, ::-1], axis=1)
        else:
            target = (z + r) / d
            clipped = np.clip(target[:, None], lo, hi)
            distance = np.where(feasible, np.abs(clipped - target[:, None]), np.inf)
            distance = np.where(np.isnan(distance), np.inf, distance)
            seg = np.argmin(distance, axis=1)
        glo, ghi = group_lo[rows1, seg], group_hi[rows1, seg]
        if choice is Choice.MID:
            chosen = 0.5 * (glo + ghi)
        elif choice is Choice.MIN_TIME:
            chosen = glo
        elif choice is Choice.MAX_CLEARANCE:
            chosen = ghi
        else:
            chosen = clipped[rows1, seg]
        gwidth = ghi - glo
        margin = tol.interior * gwidth
        chosen = np.clip(chosen, glo + margin, ghi - margin)
        any_feasible = feasible.any(axis=1) & np.isfinite(gwidth) & (gwidth >= tol.min_width)
    return _Solution(
        lo=glo,
        hi=ghi,
        chosen=chosen,
        n_components=starts.sum(axis=1).astype(np.int64),
        any_feasible=any_feasible,
        cone0_alone=np.asarray((valid & ok_cone0).any(axis=1), dtype=bool),
        cone1_alone=np.asarray((valid & ok_cone1).any(axis=1), dtype=bool),
    )


# --------------------------------------------------------------------------------------------
# Steering


def _as_rows(value: FloatArray | float, n: int, name: str) -> FloatArray:
    out = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    if not np.all(np.isfinite(out)) or np.any(out < 0):
        raise ValueError(f"{name} must be finite and non-negative")
    return out


def _as_points(value: FloatArray, name: str) -> FloatArray:
    out = np.asarray(value, dtype=np.float64)
    if out.ndim != 2 or out.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} must be finite")
    return out


def steer(
    p0: FloatArray,
    p1: FloatArray,
    n0: FloatArray,
    mu0: FloatArray | float,
    n1: FloatArray,
    mu1: FloatArray | float,
    *,
    v0max: FloatArray | float,
    vimpmax: FloatArray | float,
    g: float = GRAVITY,
    choice: Choice | str = Choice.MIN_ENERGY,
    tolerances: SteerTolerances = SteerTolerances(),
) -> SteerResult:
    """Steer N pairs p0 -> p1 (each (N, 3), m) in closed form.

    n0, n1 : (N, 3) takeoff / landing cone axes (normalised here; a zero axis marks force
    closure and fails with ``FORCE_CLOSURE``). mu0, mu1 : (N,) or scalar friction coefficients
    (cone half-angle atan(mu)). v0max, vimpmax : takeoff / landing speed bounds (m/s), (N,) or
    scalar. The landing test is on -Vimp (the impulse that stops the fall must lie in cone 1).

    Method: rows failing a cheap test (D = 0, force closure, the range pre-filter of either
    speed bound) get their reason at once. On the rest every constraint is a polynomial in t
    (module docstring; the two speed bounds merge into one through V_eff). All real roots are
    collected and sorted per pair; between consecutive roots each polynomial keeps its sign, so
    testing one interior point per sub-interval decides it exactly; adjacent feasible
    sub-intervals merge. A quadratic constraint may therefore contribute two intervals without
    any special case. The choice is clipped into the feasible set, kept ``interior`` times the
    width inside its ends, then V0, Vimp and the end point are re-checked directly against
    every bound; a failing row becomes ``NUMERIC``.
    """
    a = _as_points(p0, "p0")
    b = _as_points(p1, "p1")
    n = a.shape[0]
    if b.shape[0] != n:
        raise ValueError("p0 and p1 must have the same number of rows")
    axis0 = _as_points(np.broadcast_to(np.asarray(n0, dtype=np.float64), (n, 3)), "n0")
    axis1 = _as_points(np.broadcast_to(np.asarray(n1, dtype=np.float64), (n, 3)), "n1")
    m0 = _as_rows(mu0, n, "mu0")
    m1 = _as_rows(mu1, n, "mu1")
    vmax0 = _as_rows(v0max, n, "v0max")
    vmax1 = _as_rows(vimpmax, n, "vimpmax")
    if not g > 0:
        raise ValueError("g must be positive")
    choice = Choice(choice)
    tol = tolerances

    d, z, u = _geometry(a, b)
    r = np.hypot(d, z)
    norm0 = np.linalg.norm(axis0, axis=1)
    norm1 = np.linalg.norm(axis1, axis=1)
    closure = (norm0 < tol.min_axis_norm) | (norm1 < tol.min_axis_norm)
    unit0 = axis0 / np.where(norm0 > 0, norm0, 1.0)[:, None]
    unit1 = axis1 / np.where(norm1 > 0, norm1, 1.0)[:, None]
    vertical = d < tol.min_horizontal
    ds = np.where(vertical, 1.0, d)  # safe D for the algebra; those rows are masked below

    c0 = 1.0 / np.sqrt(1.0 + m0**2)
    c1 = 1.0 / np.sqrt(1.0 + m1**2)
    take_range = vmax0**2 >= g * (z + r)
    land_range = vmax1**2 >= g * (r - z)
    # The polynomial work runs only on rows that pass the cheap tests.
    live = np.flatnonzero(~vertical & ~closure & take_range & land_range)
    v_eff2 = np.minimum(vmax0**2, vmax1**2 + 2.0 * g * z)
    sol = _solve(
        d[live],
        z[live],
        r[live],
        u[live],
        unit0[live],
        c0[live],
        unit1[live],
        c1[live],
        v_eff2[live],
        g,
        choice,
        tol,
    )
    glo, ghi, chosen = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    glo[live], ghi[live], chosen[live] = sol.lo, sol.hi, sol.chosen
    n_components = np.zeros(n, dtype=np.int64)
    n_components[live] = sol.n_components
    any_feasible, cone0_alone, cone1_alone = (np.zeros(n, bool) for _ in range(3))
    any_feasible[live], cone0_alone[live], cone1_alone[live] = (
        sol.any_feasible,
        sol.cone0_alone,
        sol.cone1_alone,
    )

    # Failure reasons: the first failing test in enum order.
    reason = np.full(n, SteerFailure.OK, dtype=np.int8)
    checks = [
        (SteerFailure.EMPTY_INTERVAL, any_feasible),
        (SteerFailure.LANDING_CONE_MISSES_PLANE, cone1_alone),
        (SteerFailure.TAKEOFF_CONE_MISSES_PLANE, cone0_alone),
        (SteerFailure.LANDING_SPEED, land_range),
        (SteerFailure.TAKEOFF_SPEED, take_range),
        (SteerFailure.FORCE_CLOSURE, ~closure),
        (SteerFailure.VERTICAL, ~vertical),
    ]
    for code, passed in checks:  # later (earlier in order) reasons overwrite
        reason = np.where(passed, reason, np.int8(code))
    candidate = reason == SteerFailure.OK

    t = np.where(candidate, chosen, np.nan)
    rows = np.flatnonzero(candidate)
    sub = _kinematics(a[rows], ds[rows], z[rows], u[rows], t[rows], g)
    # Direct re-check of every bound on the chosen parabola (hpp-core PR #149).
    good = _recheck(
        a[rows],
        b[rows],
        sub,
        unit0[rows],
        c0[rows],
        unit1[rows],
        c1[rows],
        vmax0[rows],
        vmax1[rows],
        g,
        tol.recheck,
    )
    reason[rows[~good]] = SteerFailure.NUMERIC
    ok = reason == SteerFailure.OK
    keep = good

    def scatter(values: FloatArray) -> FloatArray:
        out = np.full((n, *values.shape[1:]), np.nan)
        out[rows[keep]] = values[keep]
        return np.asarray(_frozen(out))

    def masked(values: FloatArray) -> FloatArray:
        out = np.where(ok.reshape((-1,) + (1,) * (values.ndim - 1)), values, np.nan)
        return np.asarray(_frozen(out))

    interval = np.stack([glo, ghi], axis=1)
    return SteerResult(
        ok=np.asarray(_frozen(ok, np.bool_)),
        reason=np.asarray(_frozen(reason, np.int8)),
        t=masked(t),
        t_interval=masked(interval),
        xdot=scatter(sub.xdot),
        v0=scatter(sub.v0),
        vimp=scatter(sub.vimp),
        duration=scatter(sub.duration),
        apex=scatter(sub.apex),
        p0=np.asarray(_frozen(a)),
        p1=np.asarray(_frozen(b)),
        direction=np.asarray(_frozen(u)),
        n_components=np.asarray(_frozen(np.where(ok, n_components, 0), np.int64)),
        g=g,
        choice=choice,
    )
