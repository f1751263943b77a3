"""Kinematic COM constraints of a phase (Eq. 3-4): per-effector half-spaces moved to the world."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trajectory._types import FloatArray, as_float_array
from trajectory.polytope import Halfspaces, stack

_IDENTITY = np.eye(3)


@dataclass(frozen=True, slots=True, eq=False)
class EffectorConstraint:
    """COM half-spaces of one effector: A (m, 3) @ c_effector <= b (m,), effector frame.

    rotation (3, 3) and position (3,) give the effector pose in the world frame, so that
    c_world = rotation @ c_effector + position.
    """

    halfspaces: Halfspaces
    rotation: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        if not isinstance(self.halfspaces, Halfspaces) or self.halfspaces.dim != 3:
            raise ValueError("halfspaces: expected 3D Halfspaces")
        rot = as_float_array(self.rotation, (3, 3), "rotation")
        # np.allclose(rot @ rot.T, I, atol=1e-6) spelled out (a plan builds thousands)
        close = np.abs(rot @ rot.T - _IDENTITY) <= 1e-6 + 1e-5 * _IDENTITY
        if not close.all() or np.linalg.det(rot) < 0:
            raise ValueError("rotation: must be a proper rotation matrix")
        object.__setattr__(self, "rotation", rot)
        object.__setattr__(self, "position", as_float_array(self.position, (3,), "position"))

    def world(self) -> Halfspaces:
        """The same half-spaces on the world-frame COM."""
        return to_world(self.halfspaces, self.rotation, self.position)


def to_world(local: Halfspaces, rotation: FloatArray, position: FloatArray) -> Halfspaces:
    """A R^T c <= b + A R^T p: effector-frame half-spaces on the world COM."""
    K = local.A @ rotation.T
    return Halfspaces(K, local.b + K @ position)


def kinematic_polytope(constraints: Sequence[EffectorConstraint]) -> Halfspaces:
    """K c <= k of a phase (Eq. 4): stacked world-frame rows of every active effector."""
    return stack([c.world() for c in constraints])
