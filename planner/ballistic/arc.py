"""Parabola arcs: evaluation, bounded-gap sampling, trunk collision and the search over t.

Glossary (per jump, SI units, world frame, z up):

- ``tau`` flight time in [0, T] (s); ``s`` = xdot tau horizontal distance in [0, D] (m);
  ``sigma`` = s / D = tau / T the horizontal fraction in [0, 1].
- ``xdot`` horizontal speed, ``vz0`` vertical takeoff speed (m/s); the speed at tau is
  sqrt(xdot^2 + (vz0 - g tau)^2).
- ``L(tau)`` arc length flown up to tau (m), in closed form:
  L(tau) = (F(vz0) - F(vz0 - g tau)) / g,  F(w) = (w sqrt(a^2 + w^2) + a^2 asinh(w / a)) / 2,
  a = xdot.
- ``z(sigma; t)`` = z0 + Z sigma^2 + t D sigma (1 - sigma): with the end points fixed the height
  at a given horizontal fraction is affine and non-decreasing in t = tan(alpha). The horizontal
  position and the SLERPed orientation at sigma do not depend on t at all.

The trunk is checked through an injected ``collides_many(poses (n, 4, 4)) -> (n,) bool`` (True
where the trunk at that root pose collides). Samples are spaced by arc length, at most
``max_gap`` metres apart along the arc (so also in a straight line): with a trunk model inflated
by max_gap / 2 the discrete check is conservative for the root's path.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.ballistic.steering import GRAVITY, Jump, jump_at
from planner.poses import quaternion_to_matrix

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

TrunkCollision = Callable[[FloatArray], BoolArray]
"""collides_many(poses (n, 4, 4) world frame) -> (n,) bool, True where the trunk collides."""


# --------------------------------------------------------------------------------------------
# Evaluation


def position_at_time(jump: Jump, tau: FloatArray | float) -> FloatArray:
    """Root positions (m, 3) at flight times tau (m,) (s)."""
    return jump.position(np.asarray(tau, dtype=np.float64))


def velocity_at_time(jump: Jump, tau: FloatArray | float) -> FloatArray:
    """Root velocities (m, 3) at flight times tau (m,) (s)."""
    return jump.velocity(np.asarray(tau, dtype=np.float64))


def position_at_distance(jump: Jump, s: FloatArray | float) -> FloatArray:
    """Root positions (m, 3) at horizontal distances s (m,) from the takeoff point (m)."""
    return jump.position(np.asarray(s, dtype=np.float64) / jump.xdot)


def apex(jump: Jump) -> tuple[FloatArray, float]:
    """Highest point (3,) of the flight and its time (s) (an end point if it is not inside)."""
    tau = float(np.clip(jump.v0[2] / jump.g, 0.0, jump.duration))
    return jump.position(tau), tau


def heights_at_fraction(
    p0: FloatArray, p1: FloatArray, sigma: FloatArray, t: FloatArray | float
) -> FloatArray:
    """z(sigma; t) (m) for one pair p0, p1 (3,) at fractions sigma; broadcasts sigma and t."""
    d = float(np.hypot(p1[0] - p0[0], p1[1] - p0[1]))
    z = float(p1[2] - p0[2])
    sig = np.asarray(sigma, dtype=np.float64)
    return np.asarray(p0[2] + z * sig**2 + np.asarray(t) * d * sig * (1.0 - sig), dtype=np.float64)


# --------------------------------------------------------------------------------------------
# Arc length and sampling


def _primitive(w: FloatArray, a: FloatArray) -> FloatArray:
    root = np.sqrt(a * a + w * w)
    return np.asarray(0.5 * (w * root + a * a * np.arcsinh(w / a)), dtype=np.float64)


def arc_length(
    xdot: FloatArray, vz0: FloatArray, tau: FloatArray, g: float = GRAVITY
) -> FloatArray:
    """Arc length (m) flown from takeoff to time tau; elementwise, broadcasting."""
    a = np.asarray(xdot, dtype=np.float64)
    w0 = np.asarray(vz0, dtype=np.float64)
    tt = np.asarray(tau, dtype=np.float64)
    return np.asarray((_primitive(w0, a) - _primitive(w0 - g * tt, a)) / g, dtype=np.float64)


def sample_times(
    xdot: FloatArray,
    vz0: FloatArray,
    duration: FloatArray,
    max_gap: float,
    g: float = GRAVITY,
) -> tuple[FloatArray, IntArray]:
    """Flight times for E arcs, equally spaced in arc length, at most ``max_gap`` m apart.

    xdot, vz0, duration : (E,). Returns ``times`` (M,) concatenated per arc (each starts at 0
    and ends at its duration) and ``offsets`` (E + 1,): arc e owns times[offsets[e]:offsets[e+1]].
    The arc-length inversion is a safeguarded Newton iteration (bracketed, bisection fallback).
    """
    if not max_gap > 0:
        raise ValueError("max_gap must be positive")
    a = np.asarray(xdot, dtype=np.float64).reshape(-1)
    w0 = np.asarray(vz0, dtype=np.float64).reshape(-1)
    big_t = np.asarray(duration, dtype=np.float64).reshape(-1)
    total = arc_length(a, w0, big_t, g)
    # Aim slightly below the gap so that rounding in the inversion cannot break the bound.
    segments = np.maximum(1, np.ceil(total / (0.999 * max_gap))).astype(np.int64)
    counts = segments + 1
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    arc = np.repeat(np.arange(len(a)), counts)
    k = np.arange(offsets[-1]) - np.repeat(offsets[:-1], counts)
    frac = k / np.repeat(segments, counts)
    target = frac * np.repeat(total, counts)
    aa, ww, tt = a[arc], w0[arc], big_t[arc]
    lo = np.zeros_like(target)
    hi = tt.copy()
    tau = frac * tt
    f0 = _primitive(ww, aa)
    for _ in range(60):
        value = (f0 - _primitive(ww - g * tau, aa)) / g - target
        if np.all(np.abs(value) <= 1e-6 * max_gap):
            break
        lo = np.where(value <= 0, tau, lo)
        hi = np.where(value > 0, tau, hi)
        speed = np.sqrt(aa * aa + (ww - g * tau) ** 2)
        step = tau - value / speed
        inside = (step >= lo) & (step <= hi)
        tau = np.where(inside, step, 0.5 * (lo + hi))
    tau[offsets[:-1]] = 0.0
    tau[offsets[1:] - 1] = big_t
    return np.asarray(tau, dtype=np.float64), offsets


def jump_sample_times(jump: Jump, max_gap: float) -> FloatArray:
    """Flight times (m,) along one jump, at most ``max_gap`` m apart along the arc."""
    times, _ = sample_times(
        np.array([jump.xdot]), np.array([jump.v0[2]]), np.array([jump.duration]), max_gap, jump.g
    )
    return times


# --------------------------------------------------------------------------------------------
# Orientation and poses


def slerp(q0: FloatArray, q1: FloatArray, frac: FloatArray) -> FloatArray:
    """Row-wise SLERP of unit quaternions [x, y, z, w]: q0, q1 (M, 4) or (4,), frac (M,).

    Takes the shorter arc (q1 is negated when q0 . q1 < 0); falls back to a normalised lerp
    when the quaternions are nearly equal.
    """
    f = np.asarray(frac, dtype=np.float64).reshape(-1)
    a = np.broadcast_to(np.asarray(q0, dtype=np.float64), (len(f), 4))
    b = np.broadcast_to(np.asarray(q1, dtype=np.float64), (len(f), 4))
    dot = np.einsum("ij,ij->i", a, b)
    b = np.where(dot[:, None] < 0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    near = sin < 1e-9
    safe = np.where(near, 1.0, sin)
    wa = np.where(near, 1.0 - f, np.sin((1.0 - f) * theta) / safe)
    wb = np.where(near, f, np.sin(f * theta) / safe)
    out = wa[:, None] * a + wb[:, None] * b
    return np.asarray(out / np.linalg.norm(out, axis=1, keepdims=True), dtype=np.float64)


def _poses(positions: FloatArray, quats: FloatArray) -> FloatArray:
    out = np.zeros((len(positions), 4, 4))
    out[:, :3, :3] = quaternion_to_matrix(quats)
    out[:, :3, 3] = positions
    out[:, 3, 3] = 1.0
    return out


def arc_poses(jump: Jump, q0: FloatArray, q1: FloatArray, times: FloatArray) -> FloatArray:
    """Trunk poses (m, 4, 4) along a jump at flight times (m,), orientation SLERPed q0 -> q1."""
    tau = np.asarray(times, dtype=np.float64).reshape(-1)
    return _poses(jump.position(tau), slerp(q0, q1, tau / jump.duration))


def sample_arc(
    jump: Jump, q0: FloatArray, q1: FloatArray, max_gap: float
) -> tuple[FloatArray, FloatArray]:
    """Bounded-gap samples of one jump: times (m,) and poses (m, 4, 4)."""
    times = jump_sample_times(jump, max_gap)
    return times, arc_poses(jump, q0, q1, times)


# --------------------------------------------------------------------------------------------
# Collision


def arcs_collision_free(
    p0: FloatArray,
    v0: FloatArray,
    duration: FloatArray,
    q0: FloatArray,
    q1: FloatArray,
    collides_many: TrunkCollision,
    max_gap: float,
    g: float = GRAVITY,
    chunk: int = 200_000,
) -> BoolArray:
    """(E,) True where the trunk is free at every bounded-gap sample of arc e.

    p0, v0 : (E, 3); duration : (E,); q0, q1 : (E, 4) end orientations. Poses of many arcs go
    to ``collides_many`` together, at most about ``chunk`` per call.
    """
    p = np.asarray(p0, dtype=np.float64).reshape(-1, 3)
    v = np.asarray(v0, dtype=np.float64).reshape(-1, 3)
    big_t = np.asarray(duration, dtype=np.float64).reshape(-1)
    n_arcs = len(p)
    free = np.ones(n_arcs, dtype=bool)
    if n_arcs == 0:
        return free
    xdot = np.hypot(v[:, 0], v[:, 1])
    times, offsets = sample_times(xdot, v[:, 2], big_t, max_gap, g)
    counts = np.diff(offsets)
    arc = np.repeat(np.arange(n_arcs), counts)
    start = 0
    while start < n_arcs:
        # Whole arcs per call, about ``chunk`` poses.
        stop = int(np.searchsorted(offsets, offsets[start] + chunk, side="right")) - 1
        stop = min(max(stop, start + 1), n_arcs)
        sl = slice(int(offsets[start]), int(offsets[stop]))
        tau = times[sl]
        e = arc[sl]
        pos = p[e] + v[e] * tau[:, None]
        pos[:, 2] -= 0.5 * g * tau**2
        quats = slerp(np.asarray(q0, np.float64)[e], np.asarray(q1, np.float64)[e], tau / big_t[e])
        hit = np.asarray(collides_many(_poses(pos, quats)), dtype=bool)
        collided = np.zeros(n_arcs, dtype=bool)
        np.logical_or.at(collided, e, hit)
        free &= ~collided
        start = stop
    return free


@dataclass(frozen=True, slots=True)
class ArcSearch:
    """Outcome of ``search_collision_free``.

    ok : a collision-free parabola was found; jump : it (None otherwise). t : its slope
    (NaN if none). rounds : full-arc checks made. poses_checked : poses sent to collides_many.
    bounds : (2,) the final [lo, hi] of t the interval reasoning had narrowed to.
    """

    ok: bool
    jump: Jump | None
    t: float
    rounds: int
    poses_checked: int
    bounds: FloatArray


def _fraction_poses(
    p0: FloatArray,
    p1: FloatArray,
    q0: FloatArray,
    q1: FloatArray,
    sigma: FloatArray,
    t: FloatArray,
) -> FloatArray:
    """Poses at horizontal fractions sigma (m,) on the parabolas of slopes t (m,)."""
    pos = p0 + (p1 - p0) * sigma[:, None]
    pos[:, 2] = heights_at_fraction(p0, p1, sigma, t)
    return _poses(pos, slerp(q0, q1, sigma))


def search_collision_free(
    p0: FloatArray,
    p1: FloatArray,
    q0: FloatArray,
    q1: FloatArray,
    t_range: tuple[float, float],
    t_preferred: float,
    collides_many: TrunkCollision,
    max_gap: float,
    g: float = GRAVITY,
    max_rounds: int = 8,
) -> ArcSearch:
    """Find t in ``t_range`` nearest ``t_preferred`` whose arc p0 -> p1 is collision-free.

    Interval reasoning on z(sigma; t), affine and non-decreasing in t at each horizontal
    fraction sigma (pose otherwise independent of t). Each round checks the full arc at the
    current t (bounded gap); for every colliding sample sigma_i it tests that column at the
    current bounds [L, U]: if the trunk is free there at U the obstacle is below, and bisection
    on t in (t, U] finds the lowest verified-free slope tau_i, so L := max(L, tau_i); if it is
    free at L (obstacle above), bisection in [L, t) gives sigma_i and U := min(U, sigma_i); if it
    collides at both ends, no t in [L, U] frees that column (under the assumption below) and the
    search fails. The next round starts at clip(t_preferred, L, U).

    Assumption: within the range, each column's free set is one interval of t (obstacles are
    above or below the arc, not floating in between at some column). The answer is always
    verified on the full bounded-gap arc, so it is sound; the assumption only affects
    completeness. The bisection stops at a vertical resolution of max_gap / 4.
    """
    a = np.asarray(p0, dtype=np.float64).reshape(3)
    b = np.asarray(p1, dtype=np.float64).reshape(3)
    qa = np.asarray(q0, dtype=np.float64).reshape(4)
    qb = np.asarray(q1, dtype=np.float64).reshape(4)
    lower, upper = float(t_range[0]), float(t_range[1])
    if not lower <= upper:
        raise ValueError("t_range must be (lo, hi) with lo <= hi")
    d = float(np.hypot(b[0] - a[0], b[1] - a[1]))
    z_tol = 0.25 * max_gap
    checked = 0
    rounds = 0
    while rounds < max_rounds and lower <= upper:
        t = float(np.clip(t_preferred, lower, upper))
        rounds += 1
        jump = jump_at(a, b, t, g)
        times, poses = sample_arc(jump, qa, qb, max_gap)
        hit = np.asarray(collides_many(poses), dtype=bool)
        checked += len(poses)
        if not hit.any():
            return ArcSearch(True, jump, t, rounds, checked, np.array([lower, upper]))
        sigma = times[hit] / jump.duration
        m = len(sigma)
        ends = np.concatenate([np.full(m, upper), np.full(m, lower)])
        end_hit = np.asarray(
            collides_many(_fraction_poses(a, b, qa, qb, np.tile(sigma, 2), ends)), dtype=bool
        )
        checked += 2 * m
        free_up = ~end_hit[:m] & (upper > t)
        free_down = ~end_hit[m:] & (lower < t) & ~free_up
        if not np.all(free_up | free_down):
            return ArcSearch(False, None, float("nan"), rounds, checked, np.array([lower, upper]))
        # Bisection per column, all columns at once: bracket (colliding, free) slopes.
        bad = np.full(m, t)
        good = np.where(free_up, upper, lower)
        span = d * sigma * (1.0 - sigma)
        while np.any(span * np.abs(good - bad) > z_tol):
            mid = 0.5 * (bad + good)
            mid_hit = np.asarray(
                collides_many(_fraction_poses(a, b, qa, qb, sigma, mid)), dtype=bool
            )
            checked += m
            bad = np.where(mid_hit, mid, bad)
            good = np.where(mid_hit, good, mid)
        if free_up.any():
            lower = max(lower, float(good[free_up].max()))
        if free_down.any():
            upper = min(upper, float(good[free_down].min()))
    return ArcSearch(False, None, float("nan"), rounds, checked, np.array([lower, upper]))
