"""Whole-body inverse kinematics: weighted, damped least squares with joint-limit clamping.

Each iteration linearises every task, weights its rows by tier (``tasks.TIER_WEIGHTS``) and
solves ``min ||Jw dq - ew||^2 + lam ||dq - dq0||^2`` over the active dofs, where ``dq0`` is the
posture step and ``lam`` a Levenberg-Marquardt damping proportional to the squared weighted
error (Sugihara 2011). The posture therefore acts in the damped null space of the tasks and
leaves the fixed point as the errors vanish. Steps are always taken; the damping grows while
the weighted error grows, and the best iterate is kept. Joints whose step would cross a limit
are fixed at the limit and the step re-solved (the clamping loop of Baerlocher and Boulic
2004), so iterates never leave the limits. The solver is deterministic.

Glossary: ``q`` (nq,) configuration, ``dq`` (nv,) step, ``J`` task Jacobian (rows, nv),
``e`` task error (rows,) with ``J dq ~ e``, ``w`` row weight, ``merit`` = ``||w e||^2``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import lapack

from planner.kinematics.model import (
    bounded_dofs,
    frame_id,
    frames_support_dofs,
    has_free_flyer_root,
    scratch_data,
)
from planner.kinematics.tasks import (
    TIER_WEIGHTS,
    ComTask,
    ContactNormalTask,
    FrameAxisTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    TargetTask,
    Task,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_BASE_DAMPING = 1e-10  # damping floor, relative to a unit-weight COM row
_LM_DAMPING = 3e-4  # damping per unit of merit
_MAX_CLAMP_ROUNDS = 8
_PATIENCE = 10  # iterations in a row not improving the best merit by _MIN_PROGRESS: give up
_MIN_PROGRESS = 1e-3
_SETTLED_STEP = 1e-12  # rad or m: a step this small at the least damping moves nothing: stop

_PLACEMENT, _POSITION, _NORMAL, _COM, _AXIS = 0, 1, 2, 3, 4


@dataclass(frozen=True, slots=True)
class IkResult:
    """Outcome of :func:`solve_ik`.

    ``q`` (nq,) is the best configuration found (finite, within joint limits); ``success`` is
    True when every task other than posture is within tolerance; ``residuals`` (n_tasks, 2)
    holds per task, in input order, the linear error (m) and the angular error (rad) at ``q``
    (posture: the weighted joint-space distance to the reference, then 0); ``iterations``
    counts linearisations after the first.
    """

    q: FloatArray
    success: bool
    iterations: int
    residuals: FloatArray

    def __post_init__(self) -> None:
        self.q.flags.writeable = False
        self.residuals.flags.writeable = False


@dataclass(slots=True)
class _Compiled:
    """A task prepared for the loop."""

    index: int  # position in the caller's task list
    kind: int
    fid: int
    weight: float
    rows: int  # rows contributed to the stacked system (0 when no active dof moves it)
    target_se3: pin.SE3 | None
    target: FloatArray
    offset: FloatArray
    axis: FloatArray
    normal: FloatArray
    tangents: FloatArray  # (2, 3) basis orthogonal to the normal
    axes: NDArray[np.bool_]
    has_offset: bool = False


def _tangent_basis(normal: FloatArray) -> FloatArray:
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = _cross(normal, helper)
    t1 /= math.sqrt(float(t1 @ t1))
    return np.stack([t1, _cross(normal, t1)])


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of two (3,) vectors (np.cross costs ~10 us of overhead)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rotation_to(a: FloatArray, n: FloatArray, tangents: FloatArray) -> tuple[FloatArray, float]:
    """Rotation vector (3,) taking unit ``a`` onto unit ``n`` by the shortest arc, and its angle."""
    u = _cross(a, n)
    s = math.sqrt(float(u @ u))
    c = float(a @ n)
    angle = math.atan2(s, c)
    if s > 1e-12:
        return u * (angle / s), angle
    if c > 0.0:
        return np.zeros(3), 0.0
    return tangents[0] * math.pi, math.pi


def resolve_active(model: pin.Model, active: ArrayLike | None, lock_root: bool) -> IntArray:
    """Sorted velocity indices (k,) allowed to move, from a bool mask (nv,) or an index array;
    ``lock_root`` removes the free-flyer root's dofs (no effect on a fixed-base model)."""
    if active is None:
        mask = np.ones(model.nv, dtype=bool)
    else:
        arr = np.asarray(active)
        if arr.dtype == np.bool_:
            if arr.shape != (model.nv,):
                raise ValueError(f"active mask must have shape ({model.nv},), got {arr.shape}")
            mask = arr.copy()
        else:
            idx = arr.astype(np.int64).ravel()
            if idx.size and (idx.min() < 0 or idx.max() >= model.nv):
                raise ValueError(f"active dof indices must lie in [0, {model.nv})")
            mask = np.zeros(model.nv, dtype=bool)
            mask[idx] = True
    if lock_root and has_free_flyer_root(model):
        start = int(model.idx_vs[1])
        mask[start : start + int(model.nvs[1])] = False
    return np.flatnonzero(mask).astype(np.int64)


def _compile(
    model: pin.Model,
    index: int,
    task: TargetTask,
    active_mask: NDArray[np.bool_],
    support: IntArray | None,
) -> _Compiled:
    """The task ``index`` compiled; ``support``: the velocity indices that move its frame
    (:func:`frames_support_dofs`; None for a COM task)."""
    zeros = np.zeros(3)
    no_tangents = np.zeros((2, 3))
    axes = np.ones(3, dtype=bool)
    weight = TIER_WEIGHTS[task.priority] * task.weight
    if isinstance(task, ComTask):
        axes = np.array(task.axes, dtype=bool)
        rows = int(axes.sum()) if active_mask.any() else 0
        return _Compiled(
            index,
            _COM,
            -1,
            weight,
            rows,
            None,
            np.asarray(task.target),
            zeros,
            zeros,
            zeros,
            no_tangents,
            axes,
        )
    fid = frame_id(model, task.frame)
    assert support is not None
    coupled = bool(active_mask[support].any())
    if isinstance(task, FramePlacementTask):
        se3 = pin.SE3(task.target[:3, :3].copy(), task.target[:3, 3].copy())
        return _Compiled(
            index,
            _PLACEMENT,
            fid,
            weight,
            6 if coupled else 0,
            se3,
            task.target[:3, 3].copy(),
            zeros,
            zeros,
            zeros,
            no_tangents,
            axes,
        )
    if isinstance(task, FrameAxisTask):
        return _Compiled(
            index,
            _AXIS,
            fid,
            weight,
            2 if coupled else 0,
            None,
            zeros,
            zeros,
            np.asarray(task.axis),
            np.asarray(task.direction),
            _tangent_basis(np.asarray(task.direction)),
            axes,
        )
    has_offset = bool(task.offset.any())
    if isinstance(task, FramePositionTask):
        return _Compiled(
            index,
            _POSITION,
            fid,
            weight,
            3 if coupled else 0,
            None,
            np.asarray(task.target),
            np.asarray(task.offset),
            zeros,
            zeros,
            no_tangents,
            axes,
            has_offset,
        )
    return _Compiled(
        index,
        _NORMAL,
        fid,
        weight,
        5 if coupled else 0,
        None,
        np.asarray(task.target),
        np.asarray(task.offset),
        np.asarray(task.axis),
        np.asarray(task.normal),
        _tangent_basis(np.asarray(task.normal)),
        axes,
        has_offset,
    )


def _validate_q(model: pin.Model, q0: ArrayLike) -> FloatArray:
    q = np.array(q0, dtype=np.float64)
    if q.shape != (model.nq,) or not np.isfinite(q).all():
        raise ValueError(f"q0 must be a finite ({model.nq},) configuration")
    return q


def _validate_tasks(model: pin.Model, tasks: Sequence[Task]) -> None:
    kinds = (
        FramePlacementTask,
        FramePositionTask,
        ContactNormalTask,
        FrameAxisTask,
        ComTask,
        PostureTask,
    )
    for t in tasks:
        if not isinstance(t, kinds):
            raise TypeError(f"not an IK task: {type(t).__name__}")
    postures = [t for t in tasks if isinstance(t, PostureTask)]
    if len(postures) > 1:
        raise ValueError("at most one PostureTask")
    for p in postures:
        if p.reference.shape != (model.nq,):
            raise ValueError(f"posture reference must be ({model.nq},)")
        weights = np.asarray(p.weights)
        if weights.ndim == 1 and weights.shape != (model.nv,):
            raise ValueError(f"posture weights must be a scalar or ({model.nv},)")


def solve_ik(
    model: pin.Model,
    q0: ArrayLike,
    tasks: Sequence[Task],
    *,
    data: pin.Data | None = None,
    active: ArrayLike | None = None,
    lock_root: bool = False,
    max_iterations: int = 100,
    tolerance: float = 1e-4,
    angular_tolerance: float = 1e-3,
    max_step: float = 0.5,
) -> IkResult:
    """Move ``q0`` (nq,) until every task holds, within joint limits.

    ``active`` (bool mask (nv,) or velocity indices) selects the dofs allowed to move (all by
    default); ``lock_root`` also freezes the free-flyer root. ``tolerance`` (m) and
    ``angular_tolerance`` (rad) define success for each non-posture task; ``max_step`` bounds
    the largest step component (rad or m) per iteration. ``q0`` is first clipped into the
    joint limits. ``data`` is scratch space (a per-thread cached one when None). An
    unreachable target never raises: the result has ``success=False`` and the best ``q``.

    Raises ValueError on malformed input (shapes, unknown frames, several PostureTasks) and
    TypeError on an object that is not a task.
    """
    q = _validate_q(model, q0)
    problem = IkProblem(
        model,
        tasks,
        data=data,
        active=active,
        lock_root=lock_root,
        tolerance=tolerance,
        angular_tolerance=angular_tolerance,
        max_step=max_step,
    )
    return problem.solve(q, max_iterations)


class IkProblem:
    """A :func:`solve_ik` problem compiled once and solved many times, its targets movable in
    between (keyframes along a trajectory): ``solve(q0)`` equals ``solve_ik`` on the tasks
    with their current targets. Arguments as for :func:`solve_ik`. Not thread-safe.
    """

    def __init__(
        self,
        model: pin.Model,
        tasks: Sequence[Task],
        *,
        data: pin.Data | None = None,
        active: ArrayLike | None = None,
        lock_root: bool = False,
        tolerance: float = 1e-4,
        angular_tolerance: float = 1e-3,
        max_step: float = 0.5,
    ) -> None:
        _validate_tasks(model, tasks)
        if tolerance <= 0 or angular_tolerance <= 0 or max_step <= 0:
            raise ValueError("need positive tolerances and max_step")
        act = resolve_active(model, active, lock_root)
        mask = np.zeros(model.nv, dtype=bool)
        mask[act] = True
        targeted = [(i, t) for i, t in enumerate(tasks) if not isinstance(t, PostureTask)]
        framed = [t.frame for _, t in targeted if not isinstance(t, ComTask)]
        supports = iter(frames_support_dofs(model, framed))
        compiled = [
            _compile(model, i, t, mask, None if isinstance(t, ComTask) else next(supports))
            for i, t in targeted
        ]
        self._by_index = {c.index: c for c in compiled}
        posture_index = next((i for i, t in enumerate(tasks) if isinstance(t, PostureTask)), -1)
        posture = tasks[posture_index] if posture_index >= 0 else None
        assert posture is None or isinstance(posture, PostureTask)
        self.model = model
        self.max_step = max_step
        self._solver = _Solver(
            model,
            scratch_data(model) if data is None else data,
            compiled,
            posture,
            posture_index,
            len(tasks),
            act,
            tolerance,
            angular_tolerance,
        )

    def set_target(self, index: int, target: ArrayLike) -> None:
        """Move the target of task ``index`` (its position in the task list): a pose (4, 4)
        for a FramePlacementTask, a point (3,) otherwise (the COM, or where a frame point
        goes; a ContactNormalTask keeps its normal), the direction (3,) of a FrameAxisTask.
        Raises ValueError on a malformed target and on a PostureTask."""
        c = self._by_index.get(index)
        if c is None:
            raise ValueError(f"task {index} has no target to move")
        t = np.array(target, dtype=np.float64)
        if not np.all(np.isfinite(t)):
            raise ValueError("target must be finite")
        if c.kind == _PLACEMENT:
            rotation = t[:3, :3] if t.shape == (4, 4) else np.zeros((3, 3))
            if t.shape != (4, 4) or np.abs(rotation.T @ rotation - np.eye(3)).max() > 1e-6:
                raise ValueError("placement target must be a (4, 4) pose")
            c.target_se3 = pin.SE3(rotation.copy(), t[:3, 3].copy())
            c.target = t[:3, 3].copy()
            return
        if t.shape != (3,):
            raise ValueError("target must be (3,)")
        if c.kind == _AXIS:
            norm = float(np.linalg.norm(t))
            if norm < 1e-9:
                raise ValueError("an axis task's direction must be non-zero")
            c.normal = t / norm
            c.tangents = _tangent_basis(c.normal)
            return
        c.target = t

    def solve(self, q0: ArrayLike, max_iterations: int = 100) -> IkResult:
        """Move ``q0`` (nq,) until every task holds (see :func:`solve_ik`)."""
        if max_iterations < 0:
            raise ValueError("need max_iterations >= 0")
        q = _validate_q(self.model, q0)
        return self._solver.run(q, max_iterations, self.max_step)


class _Solver:
    """Buffers and the iteration of one :func:`solve_ik` call."""

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        compiled: list[_Compiled],
        posture: PostureTask | None,
        posture_index: int,
        n_tasks: int,
        act: IntArray,
        tolerance: float,
        angular_tolerance: float,
    ) -> None:
        self.model, self.data, self.compiled = model, data, compiled
        self.posture, self.posture_index, self.n_tasks = posture, posture_index, n_tasks
        self.act = act
        self.all_active = act.size == model.nv
        self.tolerance, self.angular_tolerance = tolerance, angular_tolerance
        self.need_com = any(c.kind == _COM for c in compiled)
        n_rows = sum(c.rows for c in compiled)
        self.jw = np.zeros((n_rows, act.size))
        self.ew = np.zeros(n_rows)
        vb, qb, lo, hi = bounded_dofs(model)
        pos_in_act = np.full(model.nv, -1, dtype=np.int64)
        pos_in_act[act] = np.arange(act.size)
        sel = pos_in_act[vb] >= 0
        self.qb_all, self.lo_all, self.hi_all = qb, lo, hi
        self.b_act, self.b_q = pos_in_act[vb][sel], qb[sel]
        self.b_lo, self.b_hi = lo[sel], hi[sel]
        self.residuals: FloatArray | None = None
        self.posture_diff = np.zeros(model.nv)  # difference(q, reference) at the last evaluate
        self.checked = np.array([c.index for c in compiled], dtype=np.int64)
        self.pull = np.zeros(act.size)
        self.posture_weights = np.zeros(model.nv)
        if posture is not None:
            self.posture_weights = np.broadcast_to(np.asarray(posture.weights), (model.nv,))
            self.pull = posture.gain * self.posture_weights[act]

    def evaluate(self, q: FloatArray) -> tuple[float, bool, FloatArray]:
        """Linearise every task at ``q`` into ``jw``/``ew``; merit, success flag, residuals.

        Tasks no active dof can move keep the residual of the first evaluation.
        """
        model, d = self.model, self.data
        pin.computeJointJacobians(model, d, q)
        pin.updateFramePlacements(model, d)
        jcom = pin.jacobianCenterOfMass(model, d, False) if self.need_com else None
        first = self.residuals is None
        residuals = np.zeros((self.n_tasks, 2)) if self.residuals is None else self.residuals.copy()
        r0 = 0
        for c in self.compiled:
            if not c.rows and not first:
                continue
            r1 = r0 + c.rows
            lin, ang = _linearise(
                model,
                d,
                c,
                jcom,
                self.jw[r0:r1],
                self.ew[r0:r1],
                None if self.all_active else self.act,
            )
            residuals[c.index, 0], residuals[c.index, 1] = lin, ang
            r0 = r1
        if self.posture is not None:
            self.posture_diff = pin.difference(model, q, self.posture.reference)
            weighted = self.posture_weights * self.posture_diff
            residuals[self.posture_index, 0] = math.sqrt(float(weighted @ weighted))
        self.residuals = residuals
        ok = bool(
            (residuals[self.checked, 0] <= self.tolerance).all()
            and (residuals[self.checked, 1] <= self.angular_tolerance).all()
        )
        return float(self.ew @ self.ew), ok, residuals

    def run(self, q_init: FloatArray, max_iterations: int, max_step: float) -> IkResult:
        model, act = self.model, self.act
        self.residuals = None
        q = q_init.copy()
        q[self.qb_all] = np.minimum(np.maximum(q[self.qb_all], self.lo_all), self.hi_all)
        q = np.asarray(pin.normalize(model, q), dtype=np.float64)
        merit, ok, residuals = self.evaluate(q)
        best_q, best_merit, best_ok, best_residuals = q, merit, ok, residuals
        scale, stall, iterations = 1.0, 0, 0
        while not ok and iterations < max_iterations and act.size:
            iterations += 1
            dq0 = self.pull * self.posture_diff[act] / scale
            lam = scale * (_BASE_DAMPING + _LM_DAMPING * merit)
            step = _clamped_step(
                self.jw,
                self.ew,
                lam,
                dq0,
                self.b_act,
                self.b_lo - q[self.b_q],
                self.b_hi - q[self.b_q],
            )
            biggest = float(np.abs(step).max())
            if not math.isfinite(biggest) or (biggest < _SETTLED_STEP and scale == 1.0):
                break
            if biggest > max_step:
                step *= max_step / biggest
            v = np.zeros(model.nv)
            v[act] = step
            q = np.asarray(pin.integrate(model, q, v), dtype=np.float64)
            q[self.b_q] = np.minimum(np.maximum(q[self.b_q], self.b_lo), self.b_hi)
            merit_new, ok, residuals = self.evaluate(q)
            # Damping grows while the error grows (divergence guard) and relaxes otherwise.
            scale = scale * 10.0 if merit_new > 2.0 * merit else max(scale * 0.5, 1.0)
            merit = merit_new
            stall = 0 if merit < best_merit * (1.0 - _MIN_PROGRESS) else stall + 1
            if ok or merit < best_merit:
                best_q, best_merit, best_ok, best_residuals = q, merit, ok, residuals
            if stall >= _PATIENCE:
                break
        return IkResult(q=best_q, success=best_ok, iterations=iterations, residuals=best_residuals)


def _linearise(
    model: pin.Model,
    d: pin.Data,
    c: _Compiled,
    jcom: FloatArray | None,
    out_j: FloatArray,
    out_e: FloatArray,
    act: IntArray | None,
) -> tuple[float, float]:
    """Write the weighted rows ``w J`` (r, n_active) and error ``w e`` (r,), with ``J dq ~ e``,
    into ``out_j`` and ``out_e`` (nothing when the task has no rows); return the linear (m) and
    angular (rad) errors. ``act`` selects Jacobian columns (None: all)."""
    w = c.weight
    if c.kind == _COM:
        assert jcom is not None
        e = (c.target - d.com[0])[c.axes]
        _store(jcom[c.axes], e, w, out_j, out_e, act)
        return math.sqrt(float(e @ e)), 0.0
    placement = d.oMf[c.fid]
    if c.kind == _PLACEMENT:
        assert c.target_se3 is not None
        err_pose = placement.actInv(c.target_se3)
        e = pin.log6(err_pose).vector
        dp = c.target - placement.translation
        if c.rows:
            j_local = pin.getFrameJacobian(model, d, c.fid, pin.LOCAL)
            _store(pin.Jlog6(err_pose.inverse()) @ j_local, e, w, out_j, out_e, act)
        return math.sqrt(float(dp @ dp)), math.sqrt(float(e[3:] @ e[3:]))
    if c.kind == _AXIS:
        r, ang = _rotation_to(placement.rotation @ c.axis, c.normal, c.tangents)
        if c.rows:
            j = pin.getFrameJacobian(model, d, c.fid, pin.LOCAL_WORLD_ALIGNED)
            if act is not None:
                j = j[:, act]
            np.multiply(c.tangents @ j[3:], w, out=out_j)
            np.multiply(c.tangents @ r, w, out=out_e)
        return 0.0, ang
    if c.kind == _POSITION and not c.has_offset:  # the common case, kept short
        e_pos = c.target - placement.translation
        lin = math.sqrt(float(e_pos @ e_pos))
        if c.rows:
            j = pin.getFrameJacobian(model, d, c.fid, pin.LOCAL_WORLD_ALIGNED)
            np.multiply(j[:3] if act is None else j[:3, act], w, out=out_j)
            np.multiply(e_pos, w, out=out_e)
        return lin, 0.0
    rotation = placement.rotation
    lever = rotation @ c.offset
    e_pos = c.target - placement.translation - lever
    lin = math.sqrt(float(e_pos @ e_pos))
    ang = 0.0
    if c.kind == _NORMAL:
        r, ang = _rotation_to(rotation @ c.axis, c.normal, c.tangents)
    if not c.rows:
        return lin, ang
    j = pin.getFrameJacobian(model, d, c.fid, pin.LOCAL_WORLD_ALIGNED)
    if act is not None:
        j = j[:, act]
    j_pos = j[:3] - _skew(lever) @ j[3:] if c.has_offset else j[:3]
    np.multiply(j_pos, w, out=out_j[:3])
    np.multiply(e_pos, w, out=out_e[:3])
    if c.kind == _NORMAL:
        np.multiply(c.tangents @ j[3:], w, out=out_j[3:])
        np.multiply(c.tangents @ r, w, out=out_e[3:])
    return lin, ang


def _store(
    j: FloatArray,
    e: FloatArray,
    w: float,
    out_j: FloatArray,
    out_e: FloatArray,
    act: IntArray | None,
) -> None:
    if out_j.shape[0] == 0:
        return
    np.multiply(j if act is None else j[:, act], w, out=out_j)
    np.multiply(e, w, out=out_e)


def _regularised_step(jw: FloatArray, ew: FloatArray, lam: float, dq0: FloatArray) -> FloatArray:
    """argmin over dq of ||jw dq - ew||^2 + lam ||dq - dq0||^2; the smaller system is solved."""
    m, n = jw.shape
    if n == 0:
        return np.zeros(0)
    if m == 0:
        return dq0.copy()
    residual = ew - jw @ dq0
    if m <= n:
        lhs = jw @ jw.T
        lhs.flat[:: m + 1] += lam
        return dq0 + jw.T @ _spd_solve(lhs, residual)
    lhs = jw.T @ jw
    lhs.flat[:: n + 1] += lam
    return dq0 + _spd_solve(lhs, jw.T @ residual)


def _spd_solve(lhs: FloatArray, rhs: FloatArray) -> FloatArray:
    """Solve ``lhs x = rhs`` for a symmetric positive definite ``lhs`` (least squares if not)."""
    _, x, info = lapack.dposv(lhs, rhs)
    if info == 0:
        return np.asarray(x, dtype=np.float64)
    return np.asarray(np.linalg.lstsq(lhs, rhs, rcond=None)[0], dtype=np.float64)


def _clamped_step(
    jw: FloatArray,
    ew: FloatArray,
    lam: float,
    dq0: FloatArray,
    b_act: IntArray,
    lo_step: FloatArray,
    hi_step: FloatArray,
) -> FloatArray:
    """Regularised step keeping bounded dofs (positions ``b_act``) in [lo_step, hi_step]: dofs
    that would cross are fixed at their bound and the others re-solved."""
    step = _regularised_step(jw, ew, lam, dq0)
    sb = step[b_act]
    over = (sb < lo_step) | (sb > hi_step)
    if not over.any():
        return step
    free = np.ones(jw.shape[1], dtype=bool)
    for _ in range(_MAX_CLAMP_ROUNDS):
        newly = b_act[over]
        step[newly] = np.minimum(np.maximum(sb[over], lo_step[over]), hi_step[over])
        free[newly] = False
        fixed = ~free
        step[free] = _regularised_step(jw[:, free], ew - jw[:, fixed] @ step[fixed], lam, dq0[free])
        sb = step[b_act]
        over = ((sb < lo_step) | (sb > hi_step)) & free[b_act]
        if not over.any():
            break
    step[b_act] = np.minimum(np.maximum(step[b_act], lo_step), hi_step)
    return step
