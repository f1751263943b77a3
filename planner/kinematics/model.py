"""Kinematic utilities over a Pinocchio model with a free-flyer root.

Configurations are Pinocchio's: ``q`` is (nq,) with the root position in ``q[0:3]`` (metres,
world frame) and the root quaternion [x, y, z, w] in ``q[3:7]``; velocities and steps are (nv,).
Poses are 4x4 homogeneous matrices in the world frame.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# Pinocchio marks "no limit" with +-DBL_MAX; anything beyond this counts as unbounded.
_UNBOUNDED = 1e100


def frame_id(model: pin.Model, frame: int | str) -> int:
    """Index of a frame given by name or index. Raises ValueError if there is no such frame."""
    if isinstance(frame, str):
        if not model.existFrame(frame):
            raise ValueError(f"model has no frame named {frame!r}")
        return int(model.getFrameId(frame))
    index = int(frame)
    if not 0 <= index < model.nframes:
        raise ValueError(f"frame index {index} out of range [0, {model.nframes})")
    return index


def joint_id(model: pin.Model, joint: int | str) -> int:
    """Index of a joint given by name or index. Raises ValueError if there is no such joint."""
    if isinstance(joint, str):
        if not model.existJointName(joint):
            raise ValueError(f"model has no joint named {joint!r}")
        return int(model.getJointId(joint))
    index = int(joint)
    if not 0 < index < model.njoints:
        raise ValueError(f"joint index {index} out of range [1, {model.njoints})")
    return index


def has_free_flyer_root(model: pin.Model) -> bool:
    """True when joint 1 is a free flyer (root dofs: q[0:7], v[0:6])."""
    return bool(model.njoints > 1 and model.joints[1].shortname() == "JointModelFreeFlyer")


def joint_dofs(model: pin.Model, joint: int | str) -> IntArray:
    """Velocity indices (k,) of one joint."""
    j = joint_id(model, joint)
    start = int(model.idx_vs[j])
    return np.arange(start, start + int(model.nvs[j]), dtype=np.int64)


def limb_dofs(model: pin.Model, root_joint: int | str, effector_frame: int | str) -> IntArray:
    """Read-only velocity indices (k,) of the chain from ``root_joint`` down to ``effector_frame``.

    Raises ValueError if ``root_joint`` is not an ancestor of the effector frame.
    """
    root = joint_id(model, root_joint)
    fid = frame_id(model, effector_frame)
    layout = _layout(model)
    key = (root, fid)
    cached = layout.limbs.get(key)
    if cached is not None:
        return cached
    chain = [int(j) for j in model.supports[int(layout.frame_parent[fid])]]
    if root not in chain:
        name = model.frames[fid].name
        raise ValueError(f"joint {model.names[root]!r} does not move frame {name!r}")
    parts = [
        np.arange(layout.idx_v[j], layout.idx_v[j] + layout.nvs[j])
        for j in chain[chain.index(root) :]
    ]
    dofs = np.concatenate(parts).astype(np.int64)
    dofs.flags.writeable = False
    layout.limbs[key] = dofs
    return dofs


def limb_reach(
    model: pin.Model, root_joint: int | str, effector_frame: int | str, offset: FloatArray
) -> float:
    """m, the farthest the point ``offset`` (3,) of ``effector_frame`` (its frame) can be from
    the origin of ``root_joint`` whatever the chain's joints do: the sum of the distances
    between consecutive joint origins down the chain, and from the last one to that point
    (an upper bound: joint limits and the chain's angles only shorten it).

    Raises ValueError if ``root_joint`` is not an ancestor of the effector frame.
    """
    root = joint_id(model, root_joint)
    fid = frame_id(model, effector_frame)
    frame = model.frames[fid]
    joint = int(frame.parentJoint)
    point = frame.placement.act(np.asarray(offset, dtype=np.float64))
    total = float(np.linalg.norm(point))
    while joint != root:
        if joint == 0:
            raise ValueError(f"joint {model.names[root]!r} does not move frame {frame.name!r}")
        total += float(np.linalg.norm(model.jointPlacements[joint].translation))
        joint = int(model.parents[joint])
    return total


def frame_support_dofs(model: pin.Model, frame: int | str) -> IntArray:
    """Read-only velocity indices (k,) of every joint that moves ``frame`` (root included)."""
    return frames_support_dofs(model, (frame,))[0]


def frames_support_dofs(model: pin.Model, frames: Sequence[int | str]) -> list[IntArray]:
    """:func:`frame_support_dofs` of each of ``frames``, the model's tables checked once (an
    IK problem asks for every task's frame)."""
    layout = _layout(model)
    parents = layout.frame_parent
    return [_support_of_joint(model, layout, int(parents[frame_id(model, f)])) for f in frames]


@dataclass(frozen=True, slots=True)
class _Layout:
    """Index tables of one model, computed once (pybind element access costs ~1 us each)."""

    size: tuple[int, int, int, int]  # nq, nv, njoints, nframes: a cheap staleness check
    limits: bytes  # the lower then upper position limits of every joint: the other check
    bounded_v: IntArray
    bounded_q: IntArray
    lower: FloatArray
    upper: FloatArray
    idx_v: IntArray  # (njoints,)
    nvs: IntArray  # (njoints,)
    frame_parent: IntArray  # (nframes,)
    supports: dict[int, IntArray] = field(default_factory=dict)  # joint -> support dofs
    limbs: dict[tuple[int, int], IntArray] = field(default_factory=dict)  # (root, frame) -> dofs


# id(model) -> (weak reference to the model, layout); the reference guards against id reuse.
_LAYOUTS: dict[int, tuple[weakref.ref[pin.Model], _Layout]] = {}


def _layout(model: pin.Model) -> _Layout:
    """Cached index tables of ``model``, rebuilt when its sizes or joint limits change."""
    size = (int(model.nq), int(model.nv), int(model.njoints), int(model.nframes))
    lower_all = np.asarray(model.lowerPositionLimit, dtype=np.float64)
    upper_all = np.asarray(model.upperPositionLimit, dtype=np.float64)
    limits = lower_all.tobytes() + upper_all.tobytes()  # compared as bytes: ~4 us less a call
    entry = _LAYOUTS.get(id(model))
    if entry is not None and entry[0]() is model:
        cached = entry[1]
        if cached.size == size and cached.limits == limits:
            return cached
    nqs = np.array(list(model.nqs), dtype=np.int64)
    nvs = np.array(list(model.nvs), dtype=np.int64)
    idx_q = np.array(list(model.idx_qs), dtype=np.int64)
    idx_v = np.array(list(model.idx_vs), dtype=np.int64)
    lower, upper = lower_all.copy(), upper_all.copy()
    one = (nqs == 1) & (nvs == 1)
    one[0] = False
    qi, vi = idx_q[one], idx_v[one]
    keep = (np.abs(lower[qi]) < _UNBOUNDED) & (np.abs(upper[qi]) < _UNBOUNDED)
    keep &= lower[qi] <= upper[qi]
    qi, vi = qi[keep], vi[keep]
    for arr in (qi, vi):
        arr.flags.writeable = False
    lo, hi = lower[qi], upper[qi]
    lo.flags.writeable = False
    hi.flags.writeable = False
    parents = np.array([int(f.parentJoint) for f in model.frames], dtype=np.int64)
    layout = _Layout(size, limits, vi, qi, lo, hi, idx_v, nvs, parents)
    for key in [k for k, (ref, _) in _LAYOUTS.items() if ref() is None]:
        del _LAYOUTS[key]
    _LAYOUTS[id(model)] = (weakref.ref(model), layout)
    return layout


_SCRATCH = threading.local()


def scratch_data(model: pin.Model) -> pin.Data:
    """A ``pin.Data`` for ``model`` reused by this thread (creating one costs ~1 ms on Talos).

    Functions taking ``data=None`` use it; its contents are overwritten by every call.
    """
    cache: dict[int, tuple[weakref.ref[pin.Model], pin.Data]] | None = getattr(
        _SCRATCH, "cache", None
    )
    if cache is None:
        cache = {}
        _SCRATCH.cache = cache
    entry = cache.get(id(model))
    if entry is not None and entry[0]() is model:
        return entry[1]
    for key in [k for k, (ref, _) in cache.items() if ref() is None]:
        del cache[key]
    data = model.createData()
    cache[id(model)] = (weakref.ref(model), data)
    return data


_POOL = threading.local()
_DEFAULT_GJK_GUESS = coal.DistanceRequest().cached_gjk_guess  # (3,) a new request's
_DEFAULT_SUPPORT_HINT = coal.DistanceRequest().cached_support_func_guess  # (2,) int32
_POOL_KEPT = 4  # idle pin.Data (pin.GeometryData) kept per model (geometry model) and thread


def _idle(owner: Any, pool: str) -> list[Any]:
    """This thread's idle objects of ``owner`` (a model) in the pool named ``pool``."""
    pools: dict[int, tuple[weakref.ref[Any], list[Any]]] | None = getattr(_POOL, pool, None)
    if pools is None:
        pools = {}
        setattr(_POOL, pool, pools)
    entry = pools.get(id(owner))
    if entry is None or entry[0]() is not owner:
        for key in [k for k, (ref, _) in pools.items() if ref() is None]:
            del pools[key]
        entry = (weakref.ref(owner), [])
        pools[id(owner)] = entry
    return entry[1]


@contextmanager
def borrowed_data(model: pin.Model) -> Iterator[pin.Data]:
    """A ``pin.Data`` for ``model`` that is this block's alone, taken from this thread's
    idle ones and given back at the end of the block (creating one costs ~1 ms, a Twister
    step needs two). Like :func:`scratch_data`, its contents are whatever the last user
    left: every user computes the kinematics it reads."""
    idle = _idle(model, "data")
    data = idle.pop() if idle else model.createData()
    try:
        yield data
    finally:
        if len(idle) < _POOL_KEPT:
            idle.append(data)


def signed_geometry_data(geometry: pin.GeometryModel) -> pin.GeometryData:
    """A new ``pin.GeometryData`` of ``geometry`` whose distance requests are signed."""
    geometry_data = pin.GeometryData(geometry)
    for request in geometry_data.distanceRequests:
        request.enable_signed_distance = True
    return geometry_data


@contextmanager
def borrowed_geometry_data(geometry: pin.GeometryModel) -> Iterator[pin.GeometryData]:
    """A ``pin.GeometryData`` for ``geometry`` with signed distance requests, this block's
    alone, like :func:`borrowed_data` (creating one costs 0.4 to 1 ms, a Twister step's
    motion needs two). Its placements and results are whatever the last user left: every
    user updates the placements it reads. Each distance query leaves its GJK guess and
    support hint in its request, and coal starts the next query of that pair from them: a
    data taken from the pool has them set back (0.2 to 0.5 ms), so that an answer does not
    depend on the queries an earlier plan made (they moved keyframes by up to 1.3 mm)."""
    idle = _idle(geometry, "geometry_data")
    if idle:
        geometry_data = idle.pop()
        for request in geometry_data.distanceRequests:
            request.cached_gjk_guess = _DEFAULT_GJK_GUESS
            request.cached_support_func_guess = _DEFAULT_SUPPORT_HINT
    else:
        geometry_data = signed_geometry_data(geometry)
    try:
        yield geometry_data
    finally:
        if len(idle) < _POOL_KEPT:
            idle.append(geometry_data)


def _support_of_joint(model: pin.Model, layout: _Layout, joint: int) -> IntArray:
    cached = layout.supports.get(joint)
    if cached is None:
        joints = [int(j) for j in model.supports[joint] if int(j) > 0]
        parts = [np.arange(layout.idx_v[j], layout.idx_v[j] + layout.nvs[j]) for j in joints]
        cached = np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)
        cached.flags.writeable = False
        layout.supports[joint] = cached
    return cached


def bounded_dofs(model: pin.Model) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """Joints with finite position limits, one dof each (revolute or prismatic).

    Returns read-only ``(v_index, q_index, lower, upper)``, each (k,): velocity and
    configuration indices and the limits (rad or m). Multi-dof joints (free flyer, spherical)
    and continuous joints count as unbounded. Cached per model object.
    """
    layout = _layout(model)
    return layout.bounded_v, layout.bounded_q, layout.lower, layout.upper


def clamp_to_limits(model: pin.Model, q: FloatArray) -> FloatArray:
    """Copy of ``q`` (nq,): bounded joints clipped into their limits, quaternions normalised."""
    _, qi, lo, hi = bounded_dofs(model)
    out = np.array(q, dtype=np.float64)
    out[qi] = np.clip(out[qi], lo, hi)
    return np.asarray(pin.normalize(model, out), dtype=np.float64)


def within_limits(model: pin.Model, q: FloatArray, tol: float = 1e-9) -> bool:
    """True when every bounded joint of ``q`` (nq,) lies within its limits (+- tol)."""
    _, qi, lo, hi = bounded_dofs(model)
    v = np.asarray(q, dtype=np.float64)[qi]
    return bool(np.all(v >= lo - tol) and np.all(v <= hi + tol))


def frame_placement(
    model: pin.Model, q: FloatArray, frame: int | str, data: pin.Data | None = None
) -> FloatArray:
    """World pose (4, 4) of ``frame`` at configuration ``q`` (nq,)."""
    d = scratch_data(model) if data is None else data
    fid = frame_id(model, frame)
    pin.forwardKinematics(model, d, np.asarray(q, dtype=np.float64))
    return np.array(pin.updateFramePlacement(model, d, fid).homogeneous, dtype=np.float64)


def frame_placements(
    model: pin.Model, q: FloatArray, frames: Sequence[int | str], data: pin.Data | None = None
) -> FloatArray:
    """World poses (n, 4, 4) of ``frames`` at configuration ``q`` (nq,)."""
    d = scratch_data(model) if data is None else data
    pin.forwardKinematics(model, d, np.asarray(q, dtype=np.float64))
    out = np.zeros((len(frames), 4, 4))
    for k, frame in enumerate(frames):
        out[k] = pin.updateFramePlacement(model, d, frame_id(model, frame)).homogeneous
    return out


def com_position(model: pin.Model, q: FloatArray, data: pin.Data | None = None) -> FloatArray:
    """Centre of mass (3,) in metres, world frame, at configuration ``q`` (nq,)."""
    d = scratch_data(model) if data is None else data
    return np.array(pin.centerOfMass(model, d, np.asarray(q, dtype=np.float64)), dtype=np.float64)


def configuration_from(
    model: pin.Model,
    root_position: FloatArray,
    root_quaternion: FloatArray,
    joints: Mapping[str, float] | None = None,
) -> FloatArray:
    """Pinocchio ``q`` (nq,) from a root position (3,) m, a quaternion (4,) [x, y, z, w] and
    joint values by name (rad or m; missing joints take their neutral value).

    The quaternion is normalised. Raises ValueError for a model without a free-flyer root, a
    zero quaternion, an unknown joint name or a joint with more than one dof.
    """
    if not has_free_flyer_root(model):
        raise ValueError("model root must be a free flyer (pin.JointModelFreeFlyer)")
    position = np.asarray(root_position, dtype=np.float64)
    quat = np.asarray(root_quaternion, dtype=np.float64)
    if position.shape != (3,) or quat.shape != (4,):
        raise ValueError("root_position must be (3,) and root_quaternion (4,) [x, y, z, w]")
    norm = float(np.linalg.norm(quat))
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError("root_quaternion must be finite and non-zero")
    q = np.asarray(pin.neutral(model), dtype=np.float64).copy()
    q[0:3] = position
    q[3:7] = quat / norm
    for name, value in (joints or {}).items():
        j = joint_id(model, name)
        iq, nq = int(model.idx_qs[j]), int(model.nqs[j])
        if int(model.nvs[j]) != 1:
            raise ValueError(f"joint {name!r} has {int(model.nvs[j])} dofs; expected one")
        if nq == 1:
            q[iq] = float(value)
        else:  # continuous joint stored as (cos, sin)
            q[iq : iq + 2] = np.cos(value), np.sin(value)
    return q


def configuration_parts(
    model: pin.Model, q: FloatArray
) -> tuple[FloatArray, FloatArray, dict[str, float]]:
    """Split ``q`` (nq,) into root position (3,), unit quaternion (4,) [x, y, z, w] and the
    values of every one-dof joint by name (continuous joints as an angle in (-pi, pi])."""
    if not has_free_flyer_root(model):
        raise ValueError("model root must be a free flyer (pin.JointModelFreeFlyer)")
    qq = np.asarray(q, dtype=np.float64)
    quat = qq[3:7] / np.linalg.norm(qq[3:7])
    joints: dict[str, float] = {}
    for j in range(2, model.njoints):
        if int(model.nvs[j]) != 1:
            continue
        iq, nq = int(model.idx_qs[j]), int(model.nqs[j])
        value = qq[iq] if nq == 1 else np.arctan2(qq[iq + 1], qq[iq])
        joints[str(model.names[j])] = float(value)
    return qq[0:3].copy(), np.asarray(quat, dtype=np.float64), joints
