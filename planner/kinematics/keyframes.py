"""Whole-body keyframes along a COM trajectory (2PAC section 7.2), and swing-foot arcs.

Each keyframe solves inverse kinematics (one compiled problem per track, only its COM and
swing targets moved), warm-started from the previous keyframe or where the two previous
ones lead at constant velocity: stance contacts held (contact tier), the COM on its curve
(COM tier), the swing effector on its path (effector tier) and a posture pull below all of
them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from planner.kinematics.ik import IkProblem
from planner.kinematics.model import (
    frame_id,
    frame_placements,
    has_free_flyer_root,
    scratch_data,
)
from planner.kinematics.tasks import (
    ComTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    Priority,
    TargetTask,
    Task,
)

FloatArray = NDArray[np.float64]
ComPath = Callable[[float], ArrayLike] | tuple[ArrayLike, ArrayLike]
SwingPath = Callable[[float], ArrayLike]


@dataclass(frozen=True, slots=True)
class KeyframeTrack:
    """Keyframes of :func:`track_com`, batch on axis 0.

    ``times`` (k,) s; ``configurations`` (k, nq); ``contact_errors`` (k,) the largest stance
    position error (m) and ``contact_angle_errors`` (k,) the largest stance angular error
    (rad); ``com_errors`` (k,) m; ``swing_errors`` (k,) m (NaN without a swing path);
    ``success`` (k,) whether every task of that keyframe was within tolerance.
    """

    times: FloatArray
    configurations: FloatArray
    contact_errors: FloatArray
    contact_angle_errors: FloatArray
    com_errors: FloatArray
    swing_errors: FloatArray
    success: NDArray[np.bool_]

    def __post_init__(self) -> None:
        for name in self.__slots__:
            getattr(self, name).flags.writeable = False

    @property
    def all_success(self) -> bool:
        """True when every keyframe succeeded."""
        return bool(self.success.all())


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


def hold_contacts(
    model: pin.Model, q: ArrayLike, frames: Sequence[int | str], data: pin.Data | None = None
) -> list[FramePlacementTask]:
    """Contact-tier placement tasks holding ``frames`` where configuration ``q`` puts them."""
    poses = frame_placements(model, np.asarray(q, dtype=np.float64), frames, data)
    return [
        FramePlacementTask(f, pose, Priority.CONTACT) for f, pose in zip(frames, poses, strict=True)
    ]


def _com_function(com: ComPath) -> tuple[Callable[[float], FloatArray], float | None, float | None]:
    if callable(com):

        def evaluate(t: float) -> FloatArray:
            return np.asarray(com(t), dtype=np.float64).reshape(3)

        return evaluate, None, None
    times = np.asarray(com[0], dtype=np.float64)
    points = np.asarray(com[1], dtype=np.float64)
    if times.ndim != 1 or points.shape != (times.size, 3) or times.size == 0:
        raise ValueError("COM samples must be times (n,) and points (n, 3)")
    if np.any(np.diff(times) <= 0):
        raise ValueError("COM sample times must increase strictly")

    def interpolate(t: float) -> FloatArray:
        return np.array([np.interp(t, times, points[:, k]) for k in range(3)])

    return interpolate, float(times[0]), float(times[-1])


def track_com(
    model: pin.Model,
    q_start: ArrayLike,
    com: ComPath,
    *,
    stance: Sequence[TargetTask],
    swing_frame: int | str | None = None,
    swing: SwingPath | None = None,
    reference: ArrayLike | None = None,
    posture_weights: float | ArrayLike = 1.0,
    t_start: float | None = None,
    t_end: float | None = None,
    rate: float = 30.0,
    com_axes: tuple[bool, bool, bool] = (True, True, True),
    data: pin.Data | None = None,
    max_iterations: int = 50,
    tolerance: float = 1e-4,
    angular_tolerance: float = 1e-3,
    predict: bool = False,
) -> KeyframeTrack:
    """Keyframes following ``com`` while holding ``stance`` and moving ``swing_frame``.

    ``com`` is a callable ``t -> (3,)`` (m, world) or samples ``(times (n,), points (n, 3))``
    interpolated linearly. ``stance`` are the contact tasks to hold (see :func:`hold_contacts`).
    ``swing`` maps ``t`` to a position (3,) or a pose (4, 4) of ``swing_frame`` (see
    :func:`swing_trajectory`). ``reference`` (nq,) is the posture pulled toward (``q_start`` by
    default; root dofs get weight 0 unless ``posture_weights`` is an (nv,) array). Times run
    from ``t_start`` to ``t_end`` at ``rate`` Hz (defaults: the sample range). Each keyframe
    is warm-started from the previous one (with ``predict``, moved on at the velocity of the
    last two: fewer iterations on a smooth path); a failed keyframe is kept (best effort) and
    flagged.

    Raises ValueError on malformed input (including a missing time range for a callable).
    """
    q = np.array(q_start, dtype=np.float64)
    if q.shape != (model.nq,):
        raise ValueError(f"q_start must be ({model.nq},)")
    com_at, t0_default, t1_default = _com_function(com)
    t0 = t_start if t_start is not None else t0_default
    t1 = t_end if t_end is not None else t1_default
    if t0 is None or t1 is None:
        raise ValueError("t_start and t_end are required when com is a callable")
    if (swing is None) != (swing_frame is None):
        raise ValueError("swing and swing_frame go together")
    swing_id = frame_id(model, swing_frame) if swing_frame is not None else -1
    times = keyframe_times(t0, t1, rate)
    ref = q.copy() if reference is None else np.asarray(reference, dtype=np.float64)
    weights = np.asarray(posture_weights, dtype=np.float64)
    if weights.ndim == 0:
        weights = np.full(model.nv, float(weights))
        if has_free_flyer_root(model):
            weights[:6] = 0.0
    posture = PostureTask(ref, weights, gain=0.3)
    d = scratch_data(model) if data is None else data

    k = times.size
    configurations = np.zeros((k, model.nq))
    contact_err, contact_ang, com_err = np.zeros(k), np.zeros(k), np.zeros(k)
    swing_err = np.full(k, np.nan)
    success = np.zeros(k, dtype=bool)
    n_stance = len(stance)
    # One problem for the whole track: only the COM and swing targets move between keyframes.
    tasks: list[Task] = [*stance, ComTask(com_at(float(times[0])), com_axes)]
    if swing is not None:
        first = np.asarray(swing(float(times[0])), dtype=np.float64)
        if first.shape == (4, 4):
            tasks.append(FramePlacementTask(swing_id, first, Priority.EFFECTOR))
        else:
            tasks.append(
                FramePositionTask(swing_id, first.reshape(3), np.zeros(3), Priority.EFFECTOR)
            )
    tasks.append(posture)
    problem = IkProblem(
        model, tasks, data=d, tolerance=tolerance, angular_tolerance=angular_tolerance
    )
    for i, t in enumerate(times):
        if i:
            problem.set_target(n_stance, com_at(float(t)))
            if swing is not None:
                target = np.asarray(swing(float(t)), dtype=np.float64)
                problem.set_target(
                    n_stance + 1, target if target.shape == (4, 4) else target.reshape(3)
                )
        guess = q
        if predict and i >= 2:  # constant-velocity prediction from the two previous keyframes
            velocity = pin.difference(model, configurations[i - 2], configurations[i - 1])
            guess = pin.integrate(model, q, velocity)
        result = problem.solve(guess, max_iterations)
        q = np.array(result.q)
        configurations[i] = q
        res = result.residuals
        if n_stance:
            contact_err[i] = res[:n_stance, 0].max()
            contact_ang[i] = res[:n_stance, 1].max()
        com_err[i] = res[n_stance, 0]
        if swing is not None:
            swing_err[i] = res[n_stance + 1, 0]
        success[i] = result.success
    return KeyframeTrack(
        times, configurations, contact_err, contact_ang, com_err, swing_err, success
    )


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
