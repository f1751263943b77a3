"""Contact states: a whole-body configuration plus the limbs in contact, oldest contact first."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _readonly(array: object, shape: tuple[int, ...] | None, name: str) -> FloatArray:
    out = np.array(array, dtype=np.float64)
    if shape is not None and out.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {out.shape}")
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True)
class LimbContact:
    """One limb in contact with the scene.

    placement : (4, 4) world pose of the limb's effector frame while in contact.
    points : (k, 3) world contact points (1 for a point contact, 4 patch corners).
    normal : (3,) unit surface normal, pointing out of the surface, world frame.
    mu : friction coefficient; surface : id of the scene surface touched (-1 if none known).
    """

    limb: str
    placement: FloatArray
    points: FloatArray
    normal: FloatArray
    mu: float
    surface: int = -1

    def __post_init__(self) -> None:
        object.__setattr__(self, "placement", _readonly(self.placement, (4, 4), "placement"))
        points = _readonly(self.points, None, "points")
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError("points must be (k, 3)")
        object.__setattr__(self, "points", points)
        normal = np.asarray(self.normal, dtype=np.float64)
        object.__setattr__(self, "normal", _readonly(normal / np.linalg.norm(normal), (3,), "n"))
        if not self.mu > 0:
            raise ValueError("mu must be positive")

    @property
    def position(self) -> FloatArray:
        """(3,) world position of the effector frame origin."""
        return np.asarray(self.placement[:3, 3])


@dataclass(frozen=True, slots=True)
class ContactState:
    """A whole-body configuration and its active contacts, oldest first.

    q : (nq,) Pinocchio configuration: root position, root quaternion [x, y, z, w], joints.
    """

    q: FloatArray
    contacts: tuple[LimbContact, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _readonly(self.q, None, "q"))
        limbs = [c.limb for c in self.contacts]
        if len(set(limbs)) != len(limbs):
            raise ValueError("a limb appears twice in the contacts")

    @property
    def limbs(self) -> tuple[str, ...]:
        """Limbs in contact, oldest first."""
        return tuple(c.limb for c in self.contacts)

    def contact(self, limb: str) -> LimbContact | None:
        """The contact of ``limb``, or None if it is free."""
        for c in self.contacts:
            if c.limb == limb:
                return c
        return None

    def with_contact(self, contact: LimbContact, q: FloatArray | None = None) -> ContactState:
        """A new state with ``contact`` added last (replacing any contact of the same limb)."""
        kept = tuple(c for c in self.contacts if c.limb != contact.limb)
        return ContactState(self.q if q is None else q, (*kept, contact))

    def without(self, limb: str, q: FloatArray | None = None) -> ContactState:
        """A new state with ``limb``'s contact removed."""
        kept = tuple(c for c in self.contacts if c.limb != limb)
        return ContactState(self.q if q is None else q, kept)

    def differs_by_one(self, other: ContactState) -> bool:
        """True when exactly one contact is added or removed between the two states."""
        mine, theirs = set(self.limbs), set(other.limbs)
        if len(mine ^ theirs) != 1:
            return False
        for limb in mine & theirs:
            a, b = self.contact(limb), other.contact(limb)
            assert a is not None and b is not None
            if not np.allclose(a.placement, b.placement, atol=1e-6):
                return False
        return True
