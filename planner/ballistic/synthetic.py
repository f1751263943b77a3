"""Synthetic stand-ins until real scenes exist: horizontal platforms and a sphere-chain trunk.

``PlatformSampler`` implements ``roadmap.NodeSampler`` for scenes made of horizontal rectangles
(area-weighted, seeded); ``BoxWorld`` answers ``collides_many`` for a trunk made of spheres
fixed in the root frame against axis-aligned boxes. Both are exact and vectorised, meant for
tests and benchmarks, not for production scenes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.ballistic.roadmap import RoadmapNodes

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _frozen(value: object) -> FloatArray:
    out = np.array(value, dtype=np.float64)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True)
class Platforms:
    """Horizontal rectangles: lo, hi (P, 2) x-y corners (m), top (P,) heights (m), world frame.

    thickness : slab depth (m) below each top, used when the platforms are turned into boxes.
    """

    lo: FloatArray
    hi: FloatArray
    top: FloatArray
    thickness: float = 0.2

    def __post_init__(self) -> None:
        for name in ("lo", "hi", "top"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        if self.lo.shape != self.hi.shape or self.lo.ndim != 2 or self.lo.shape[1] != 2:
            raise ValueError("lo and hi must both be (P, 2)")
        if self.top.shape != (self.lo.shape[0],) or np.any(self.hi <= self.lo):
            raise ValueError("top must be (P,) and every rectangle non-empty")

    def areas(self) -> FloatArray:
        """(P,) areas (m^2)."""
        size = self.hi - self.lo
        return np.asarray(size[:, 0] * size[:, 1], dtype=np.float64)

    def boxes(self) -> tuple[FloatArray, FloatArray]:
        """Axis-aligned slabs (lo (P, 3), hi (P, 3)) of the platforms."""
        lo = np.column_stack([self.lo, self.top - self.thickness])
        hi = np.column_stack([self.hi, self.top])
        return lo, hi


def yaw_quaternions(yaw: FloatArray) -> FloatArray:
    """(n, 4) quaternions [x, y, z, w] of rotations by yaw (n,) rad about world z."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    zeros = np.zeros_like(half)
    return np.asarray(np.column_stack([zeros, zeros, np.sin(half), np.cos(half)]), np.float64)


@dataclass(frozen=True, slots=True)
class PlatformSampler:
    """Root poses standing on platforms: area-weighted uniform points, yaw ~ U[-pi, pi].

    root_height : root above the surface (m). mu : friction of every surface. Every node has
    one support contact under the root, kept as opaque contact data ``support_point`` (n, 3).
    The cone axis is +z (a single horizontal contact).
    """

    platforms: Platforms
    root_height: float = 0.5
    mu: float = 1.0
    margin: float = 0.0
    """Keep points this far (m) inside each rectangle's edges."""

    def sample(self, n: int, *, rng: np.random.Generator) -> RoadmapNodes:
        """n nodes (never fewer: no rejection needed on rectangles)."""
        weights = self.platforms.areas()
        which = rng.choice(len(weights), size=n, p=weights / weights.sum())
        lo = self.platforms.lo[which] + self.margin
        hi = self.platforms.hi[which] - self.margin
        xy = lo + (hi - lo) * rng.random((n, 2))
        support = np.column_stack([xy, self.platforms.top[which]])
        positions = support + np.array([0.0, 0.0, self.root_height])
        yaw = rng.uniform(-np.pi, np.pi, size=n)
        return RoadmapNodes(
            positions=positions,
            orientations=yaw_quaternions(yaw),
            cone_axes=np.tile([0.0, 0.0, 1.0], (n, 1)),
            mus=np.full(n, self.mu),
            contacts={"support_point": support},
        )


@dataclass(frozen=True, slots=True)
class BoxWorld:
    """Spheres fixed in the root frame against axis-aligned boxes.

    centres : (m, 3) sphere centres in the root frame (m); radius : sphere radius (m).
    box_lo, box_hi : (k, 3) box corners, world frame (m).
    """

    centres: FloatArray
    radius: float
    box_lo: FloatArray
    box_hi: FloatArray

    def __post_init__(self) -> None:
        for name in ("centres", "box_lo", "box_hi"):
            object.__setattr__(self, name, _frozen(getattr(self, name)).reshape(-1, 3))

    def inflated(self, extra: float) -> BoxWorld:
        """The same world with the spheres' radius grown by ``extra`` (m)."""
        return BoxWorld(self.centres, self.radius + extra, self.box_lo, self.box_hi)

    def __call__(self, poses: FloatArray) -> BoolArray:
        """collides_many: (n,) True where some sphere of the trunk at pose i touches a box."""
        p = np.asarray(poses, dtype=np.float64)
        hit = np.zeros(len(p), dtype=bool)
        if len(self.box_lo) == 0 or len(p) == 0:
            return hit
        world = np.einsum("nij,mj->nmi", p[:, :3, :3], self.centres) + p[:, None, :3, 3]
        pts = world.reshape(-1, 1, 3)
        gap = np.maximum(np.maximum(self.box_lo - pts, pts - self.box_hi), 0.0)  # (n m, k, 3)
        touch = np.einsum("pki,pki->pk", gap, gap) <= self.radius**2
        hit = touch.any(axis=1).reshape(len(p), -1).any(axis=1)
        return np.asarray(hit, dtype=bool)
