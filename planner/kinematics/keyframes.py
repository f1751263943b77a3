"""Keyframe times and swing-effector arcs (the whole-body tracking is ``planner.motion``)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def keyframe_times(t_start: float, t_end: float, rate: float = 30.0) -> FloatArray:
    """Times (k,) from ``t_start`` every ``1 / rate`` s, ending exactly at ``t_end``."""
    if not (math.isfinite(t_start) and math.isfinite(t_end)) or t_end < t_start:
        raise ValueError("need finite t_start <= t_end")
    if not rate > 0:
        raise ValueError("rate must be positive")
    count = math.floor((t_end - t_start) * rate + 1e-9)
    times = t_start + np.arange(count + 1) / rate
    if t_end - times[-1] > 1e-9:
        times = np.append(times, t_end)
    else:
        times[-1] = t_end
    return np.asarray(times, dtype=np.float64)


def _cubic_bezier(control: FloatArray, s: FloatArray) -> FloatArray:
    u = 1.0 - s
    basis = np.stack([u**3, 3 * u * u * s, 3 * u * s * s, s**3], axis=1)
    return np.asarray(basis @ control, dtype=np.float64)


def swing_arc(
    start: ArrayLike,
    end: ArrayLike,
    s: ArrayLike,
    *,
    lift: float = 0.1,
    normal_in_frame: ArrayLike = (0.0, 0.0, 1.0),
) -> FloatArray:
    """Positions (n, 3) of a swing arc between two contact poses (4, 4) at normalised times
    ``s`` (n,) in [0, 1].

    A cubic Bezier leaving ``start`` along its contact normal (``normal_in_frame`` rotated to
    the world) and arriving at ``end`` along its own; between equal normals it rises ``lift``
    (m) above the chord at s = 0.5.
    """
    p0, p3, n0, n3, ss = _arc_inputs(start, end, s, normal_in_frame)
    if not lift >= 0:
        raise ValueError("lift must be non-negative")
    reach = 4.0 * lift / 3.0
    control = np.stack([p0, p0 + reach * n0, p3 + reach * n3, p3])
    return _cubic_bezier(control, ss)


def _arc_inputs(
    start: ArrayLike, end: ArrayLike, s: ArrayLike, normal_in_frame: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    axis = np.asarray(normal_in_frame, dtype=np.float64)
    ss = np.atleast_1d(np.asarray(s, dtype=np.float64))
    if a.shape != (4, 4) or b.shape != (4, 4) or axis.shape != (3,):
        raise ValueError("start and end must be (4, 4) poses, normal_in_frame (3,)")
    if ss.ndim != 1 or np.any(ss < 0.0) or np.any(ss > 1.0):
        raise ValueError("s must be (n,) values in [0, 1]")
    axis = axis / np.linalg.norm(axis)
    return a[:3, 3], b[:3, 3], a[:3, :3] @ axis, b[:3, :3] @ axis, ss


def minimum_jerk(tau: FloatArray) -> FloatArray:
    """Minimum-jerk time scaling 10 tau^3 - 15 tau^4 + 6 tau^5 of tau in [0, 1]."""
    t = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return np.asarray(t**3 * (10.0 - 15.0 * t + 6.0 * t * t), dtype=np.float64)


def swing_trajectory(
    start: ArrayLike,
    end: ArrayLike,
    t_start: float,
    t_end: float,
    *,
    lift: float = 0.1,
    normal_in_frame: ArrayLike = (0.0, 0.0, 1.0),
) -> Callable[[float], FloatArray]:
    """Effector pose (4, 4) as a function of time: :func:`swing_arc` timed by
    :func:`minimum_jerk` (zero velocity at both ends), rotation interpolated along the
    geodesic. Times outside [t_start, t_end] give the end poses."""
    if not t_end > t_start:
        raise ValueError("need t_end > t_start")
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    p0, p3, n0, n3, _ = _arc_inputs(a, b, np.zeros(1), normal_in_frame)
    if not lift >= 0:
        raise ValueError("lift must be non-negative")
    reach = 4.0 * lift / 3.0
    control = np.stack([p0, p0 + reach * n0, p3 + reach * n3, p3])  # as in swing_arc
    r0 = a[:3, :3]
    delta = np.asarray(pin.log3(r0.T @ b[:3, :3]), dtype=np.float64)
    duration = t_end - t_start

    def pose(t: float) -> FloatArray:
        tau = min(max((t - t_start) / duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)  # minimum_jerk, scalar
        u = 1.0 - s
        out = np.eye(4)
        out[:3, :3] = r0 @ pin.exp3(s * delta)
        out[:3, 3] = np.array([u**3, 3.0 * u * u * s, 3.0 * u * s * s, s**3]) @ control
        return out

    return pose


def clearing_swing_trajectory(
    start: ArrayLike,
    end: ArrayLike,
    t_start: float,
    t_end: float,
    *,
    rise: float,
    descend: float,
    normal_in_frame: ArrayLike = (0.0, 0.0, 1.0),
    rise_share: float = 0.2,
) -> Callable[[float], FloatArray]:
    """Effector pose (4, 4) as a function of time along a box-shaped swing: up ``rise`` m
    along the start's contact normal, across in a straight line to ``descend`` m above the
    end along its normal, and down onto it. With tau the share of [t_start, t_end] gone by,
    the rise runs over tau in [0, 2 r], the crossing over [r, 1 - r] and the descent over
    [1 - 2 r], 1] (r = ``rise_share``, each leg a minimum-jerk profile: zero velocity and
    acceleration at both ends, the corners rounded by the overlaps), so an effector next to
    a wall or a ledge goes up before it moves over. Rotation interpolated along the geodesic
    with the crossing. Times outside [t_start, t_end] give the end poses."""
    if not t_end > t_start:
        raise ValueError("need t_end > t_start")
    if not (rise >= 0.0 and descend >= 0.0):
        raise ValueError("rise and descend must be non-negative")
    if not 0.0 < rise_share < 0.5:
        raise ValueError("rise_share must be in (0, 0.5)")
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    p0, p3, n0, n3, _ = _arc_inputs(a, b, np.zeros(1), normal_in_frame)
    top0, top3 = p0 + rise * n0, p3 + descend * n3
    r0 = a[:3, :3]
    delta = np.asarray(pin.log3(r0.T @ b[:3, :3]), dtype=np.float64)
    duration = t_end - t_start
    share = rise_share

    def jerk(x: float) -> float:
        x = min(max(x, 0.0), 1.0)
        return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)  # minimum_jerk, scalar

    def pose(t: float) -> FloatArray:
        tau = min(max((t - t_start) / duration, 0.0), 1.0)
        across = jerk((tau - share) / (1.0 - 2.0 * share))
        up = jerk(tau / (2.0 * share))
        down = jerk((tau - 1.0 + 2.0 * share) / (2.0 * share))
        out = np.eye(4)
        out[:3, :3] = r0 @ pin.exp3(across * delta)
        out[:3, 3] = (1.0 - across) * (p0 + up * (top0 - p0)) + across * (top3 + down * (p3 - top3))
        return out

    return pose
