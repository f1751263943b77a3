"""Convex collision primitives shared by scenes, characters and planners.

Every shape is expressed in its own frame; ``offset`` is the 4x4 homogeneous pose of the shape
in the frame of whatever carries it (a character's root, a limb link). Units are metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _frozen(array: object, shape: tuple[int, ...] | None = None, name: str = "array") -> FloatArray:
    out = np.array(array, dtype=np.float64)
    if shape is not None and out.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} must be finite")
    out.flags.writeable = False
    return out


def _identity() -> FloatArray:
    return _frozen(np.eye(4), (4, 4), "offset")


@dataclass(frozen=True, slots=True)
class Box:
    """Axis-aligned box in its own frame.

    half_extents : (3,) metres, strictly positive.
    offset : (4, 4) pose of the box centre in the carrier's frame.
    """

    half_extents: FloatArray
    offset: FloatArray = field(default_factory=_identity)

    def __post_init__(self) -> None:
        object.__setattr__(self, "half_extents", _frozen(self.half_extents, (3,), "half_extents"))
        object.__setattr__(self, "offset", _frozen(self.offset, (4, 4), "offset"))
        if np.any(self.half_extents <= 0):
            raise ValueError("half_extents must be strictly positive")

    def vertices(self) -> FloatArray:
        """(8, 3) corners in the carrier's frame."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = signs * self.half_extents
        return np.asarray(local @ self.offset[:3, :3].T + self.offset[:3, 3], dtype=np.float64)


@dataclass(frozen=True, slots=True)
class Capsule:
    """Capsule along its local z axis.

    radius : metres; half_length : half the length of the segment between the two sphere centres.
    offset : (4, 4) pose in the carrier's frame.
    """

    radius: float
    half_length: float
    offset: FloatArray = field(default_factory=_identity)

    def __post_init__(self) -> None:
        if not (self.radius > 0 and self.half_length >= 0):
            raise ValueError("capsule needs radius > 0 and half_length >= 0")
        object.__setattr__(self, "offset", _frozen(self.offset, (4, 4), "offset"))


@dataclass(frozen=True, slots=True)
class ConvexPolytope:
    """A convex polytope given both as vertices and as half-spaces ``A x <= b``.

    vertices : (n, 3) hull vertices; A : (m, 3) outward unit normals; b : (m,) offsets.
    offset : (4, 4) pose in the carrier's frame (vertices/half-spaces are in the local frame).
    """

    vertices: FloatArray
    A: FloatArray
    b: FloatArray
    offset: FloatArray = field(default_factory=_identity)

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", _frozen(self.vertices, None, "vertices"))
        object.__setattr__(self, "A", _frozen(self.A, None, "A"))
        object.__setattr__(self, "b", _frozen(self.b, None, "b"))
        object.__setattr__(self, "offset", _frozen(self.offset, (4, 4), "offset"))
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or len(self.vertices) < 4:
            raise ValueError("vertices must be (n, 3) with n >= 4")
        if self.A.ndim != 2 or self.A.shape[1] != 3 or self.b.shape != (self.A.shape[0],):
            raise ValueError("half-spaces must be A (m, 3) and b (m,)")

    @staticmethod
    def from_points(points: FloatArray, offset: FloatArray | None = None) -> ConvexPolytope:
        """Convex hull of (n, 3) points (n >= 4, not coplanar)."""
        from scipy.spatial import ConvexHull

        hull = ConvexHull(np.asarray(points, dtype=np.float64))
        eq = hull.equations  # (m, 4): n . x + d <= 0 inside
        normals = eq[:, :3]
        return ConvexPolytope(
            vertices=hull.points[hull.vertices],
            A=normals,
            b=-eq[:, 3],
            offset=np.eye(4) if offset is None else offset,
        )

    def contains(self, points: FloatArray, tolerance: float = 1e-9) -> NDArray[np.bool_]:
        """(n,) mask of the (n, 3) points, given in the local frame, inside the polytope."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        return np.asarray(np.all(pts @ self.A.T <= self.b + tolerance, axis=1))


Shape = Box | Capsule | ConvexPolytope
