"""Inverse-kinematics tasks: what a frame, the centre of mass or the posture should do.

Every target is in the world frame (metres, radians). A task's ``priority`` picks a weight tier
(contacts > centre of mass > swing effectors > posture); ``weight`` scales it within the tier.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class Priority(enum.IntEnum):
    """Weight tiers, highest first. Posture regularisation always ranks below all of them."""

    CONTACT = 0
    COM = 1
    EFFECTOR = 2


# Residual weight of each tier. Squared ratios of about 1e3 and 1e2 make a conflicting lower
# tier leak into a higher one about that much less; steeper ratios ill-condition the normal
# equations and slow convergence.
TIER_WEIGHTS: dict[Priority, float] = {
    Priority.CONTACT: 30.0,
    Priority.COM: 1.0,
    Priority.EFFECTOR: 0.1,
}


def _vector(value: object, size: int, name: str) -> FloatArray:
    out = np.array(value, dtype=np.float64)
    if out.shape != (size,) or not np.isfinite(out).all():
        raise ValueError(f"{name} must be a finite ({size},) array, got shape {out.shape}")
    out.flags.writeable = False
    return out


def _unit(value: object, name: str) -> FloatArray:
    """``value`` as a read-only unit (3,) vector; ValueError naming ``name`` if zero."""
    v = np.array(_vector(value, 3, name))
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:
        raise ValueError(f"{name} must be non-zero")
    v /= norm
    v.flags.writeable = False
    return v


def _check_weight(weight: float) -> None:
    if not (np.isfinite(weight) and weight > 0.0):
        raise ValueError(f"weight must be finite and positive, got {weight}")


@dataclass(frozen=True, slots=True)
class FramePlacementTask:
    """Bring ``frame`` to the world pose ``target`` (4, 4): 6 rows, error log6 in the frame."""

    frame: int | str
    target: FloatArray
    priority: Priority = Priority.CONTACT
    weight: float = 1.0

    def __post_init__(self) -> None:
        target = np.array(self.target, dtype=np.float64)
        if target.shape != (4, 4) or not np.all(np.isfinite(target)):
            raise ValueError("target must be a finite (4, 4) pose")
        rotation = target[:3, :3]
        if np.abs(rotation.T @ rotation - np.eye(3)).max() > 1e-6 or np.linalg.det(rotation) < 0:
            raise ValueError("target rotation must be orthonormal with determinant +1")
        target.flags.writeable = False
        object.__setattr__(self, "target", target)
        _check_weight(self.weight)


@dataclass(frozen=True, slots=True)
class FramePositionTask:
    """Bring the point ``offset`` (3,) of ``frame`` (frame coordinates) to ``target`` (3,)."""

    frame: int | str
    target: FloatArray
    offset: FloatArray = field(default_factory=lambda: np.zeros(3))
    priority: Priority = Priority.EFFECTOR
    weight: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", _vector(self.target, 3, "target"))
        object.__setattr__(self, "offset", _vector(self.offset, 3, "offset"))
        _check_weight(self.weight)


@dataclass(frozen=True, slots=True)
class ContactNormalTask:
    """Put the point ``offset`` of ``frame`` on ``target`` (3,) with the frame axis ``axis``
    (3,) (frame coordinates) along the world ``normal`` (3,): 5 rows, yaw about the normal free.

    ``axis`` and ``normal`` are normalised here.
    """

    frame: int | str
    target: FloatArray
    normal: FloatArray
    axis: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    offset: FloatArray = field(default_factory=lambda: np.zeros(3))
    priority: Priority = Priority.CONTACT
    weight: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", _vector(self.target, 3, "target"))
        object.__setattr__(self, "offset", _vector(self.offset, 3, "offset"))
        for name in ("normal", "axis"):
            object.__setattr__(self, name, _unit(getattr(self, name), name))
        _check_weight(self.weight)


@dataclass(frozen=True, slots=True)
class FrameAxisTask:
    """Turn the axis ``axis`` (3,) of ``frame`` (frame coordinates) along the world
    ``direction`` (3,): 2 rows, the turn about ``direction`` and the frame's position free (a
    trunk kept upright whatever its yaw). Both vectors are normalised here."""

    frame: int | str
    direction: FloatArray
    axis: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    priority: Priority = Priority.EFFECTOR
    weight: float = 1.0

    def __post_init__(self) -> None:
        for name in ("direction", "axis"):
            object.__setattr__(self, name, _unit(getattr(self, name), name))
        _check_weight(self.weight)


@dataclass(frozen=True, slots=True)
class ComTask:
    """Bring the centre of mass to ``target`` (3,) along the selected world ``axes``
    (e.g. ``(True, True, False)`` for x and y only)."""

    target: FloatArray
    axes: tuple[bool, bool, bool] = (True, True, True)
    priority: Priority = Priority.COM
    weight: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", _vector(self.target, 3, "target"))
        if len(self.axes) != 3 or not any(self.axes):
            raise ValueError("axes must be three booleans, at least one True")
        object.__setattr__(self, "axes", tuple(bool(a) for a in self.axes))
        _check_weight(self.weight)


@dataclass(frozen=True, slots=True)
class PostureTask:
    """Regularise toward ``reference`` (nq,), below every other task.

    Each iteration proposes the step ``gain * weights * difference(q, reference)``, which the
    solver follows only in the null space of the other tasks. ``weights`` is a scalar or (nv,)
    per-dof weights in [0, 1] (0 leaves a dof free, e.g. the root); ``gain`` is in (0, 1].
    """

    reference: FloatArray
    weights: float | FloatArray = 1.0
    gain: float = 0.5

    def __post_init__(self) -> None:
        reference = np.array(self.reference, dtype=np.float64)
        if reference.ndim != 1 or not np.all(np.isfinite(reference)):
            raise ValueError("reference must be a finite (nq,) configuration")
        reference.flags.writeable = False
        object.__setattr__(self, "reference", reference)
        weights = np.array(self.weights, dtype=np.float64)
        if weights.ndim > 1 or not np.all((weights >= 0.0) & (weights <= 1.0)):
            raise ValueError("weights must be a scalar or (nv,) array with values in [0, 1]")
        weights.flags.writeable = False
        object.__setattr__(self, "weights", weights)
        if not 0.0 < self.gain <= 1.0:
            raise ValueError(f"gain must be in (0, 1], got {self.gain}")


TargetTask = FramePlacementTask | FramePositionTask | ContactNormalTask | FrameAxisTask | ComTask
Task = TargetTask | PostureTask
