"""Motion output shared by the planners: timed keyframes, contact phases and COM segments."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # annotation only: planner.contact imports this module
    from planner.contact.state import LimbContact

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Keyframe:
    """The whole body at time ``t`` (seconds from the motion's start).

    q : (nq,) Pinocchio configuration (root position, root quaternion [x, y, z, w], joints).
    contacts : limbs in contact at ``t``.
    """

    t: float
    q: FloatArray
    contacts: tuple[str, ...]


def root_speed(a: Keyframe, b: Keyframe) -> float:
    """m/s, the root's mean speed from keyframe ``a`` to keyframe ``b``."""
    distance = float(np.linalg.norm(np.asarray(b.q[:3]) - np.asarray(a.q[:3])))
    return distance / max(b.t - a.t, 1e-9)


@dataclass(frozen=True, slots=True)
class Phase:
    """A time interval [t0, t1] during which the contacts do not change."""

    t0: float
    t1: float
    contacts: tuple[LimbContact, ...]


@dataclass(frozen=True, slots=True)
class ComSegment:
    """One Bezier piece of the COM curve over [t0, t1]; control_points (d + 1, 3), metres."""

    t0: float
    t1: float
    control_points: FloatArray
