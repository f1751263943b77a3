"""Rigid transforms and quaternions in Gecko's conventions.

Quaternions are [x, y, z, w] (Pinocchio's order), world frame z up. A pose is a 4x4 homogeneous
matrix; batches carry the batch on axis 0: (n, 4, 4).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def normalize_quaternion(quat: FloatArray) -> FloatArray:
    """Unit quaternion(s) [x, y, z, w]; (4,) or (n, 4). Raises ValueError on a zero quaternion."""
    q = np.asarray(quat, dtype=np.float64)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12) or not np.all(np.isfinite(q)):
        raise ValueError("quaternion must be finite and non-zero")
    return np.asarray(q / norm, dtype=np.float64)


def quaternion_to_matrix(quat: FloatArray) -> FloatArray:
    """Rotation matrices (…, 3, 3) from unit quaternions (…, 4) [x, y, z, w]."""
    q = np.asarray(quat, dtype=np.float64)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - z * w),
            2 * (x * z + y * w),
            2 * (x * y + z * w),
            1 - 2 * (x * x + z * z),
            2 * (y * z - x * w),
            2 * (x * z - y * w),
            2 * (y * z + x * w),
            1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return np.asarray(out.reshape((*q.shape[:-1], 3, 3)), dtype=np.float64)


def matrix_to_quaternion(rotation: FloatArray) -> FloatArray:
    """Unit quaternion [x, y, z, w] (w >= 0) of a (3, 3) rotation matrix."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    out = np.array(q, dtype=np.float64)
    if out[3] < 0:
        out = -out
    return np.asarray(out / np.linalg.norm(out), dtype=np.float64)


def pose_matrix(position: FloatArray, rotation: FloatArray | None = None) -> FloatArray:
    """4x4 pose from a (3,) position and an optional (3, 3) rotation (identity by default)."""
    out = np.eye(4)
    out[:3, 3] = position
    if rotation is not None:
        out[:3, :3] = rotation
    return out


def poses_from(positions: FloatArray, rotations: FloatArray) -> FloatArray:
    """(n, 4, 4) poses from (n, 3) positions and (n, 3, 3) rotations."""
    n = len(positions)
    out = np.zeros((n, 4, 4))
    out[:, :3, :3] = rotations
    out[:, :3, 3] = positions
    out[:, 3, 3] = 1.0
    return out


def yaw_matrix(yaw: FloatArray) -> FloatArray:
    """(…, 3, 3) rotations about world z by ``yaw`` radians."""
    c, s = np.cos(yaw), np.sin(yaw)
    zeros, ones = np.zeros_like(c), np.ones_like(c)
    out = np.stack([c, -s, zeros, s, c, zeros, zeros, zeros, ones], axis=-1)
    return np.asarray(out.reshape((*np.shape(yaw), 3, 3)), dtype=np.float64)


def rotation_between(a: FloatArray, b: FloatArray) -> FloatArray:
    """Smallest (3, 3) rotation taking unit vector ``a`` onto unit vector ``b``."""
    a = np.asarray(a, dtype=np.float64) / np.linalg.norm(a)
    b = np.asarray(b, dtype=np.float64) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.asarray(2.0 * np.outer(axis, axis) - np.eye(3), dtype=np.float64)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.asarray(np.eye(3) + vx + vx @ vx / (1.0 + c), dtype=np.float64)
