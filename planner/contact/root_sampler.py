"""Root pose sampler (anchor section 1, ``RbprmShooter``), batched and seeded.

A candidate picks a surface triangle allowed for a required limb (area-weighted, mixed with a
uniform pick so small treads get drawn too), a uniform point in it and an orientation within
the bounds, then places the root so that the limb's reference contact centre (from ``q_ref``)
lands on the point. Candidates whose trunk collides are pushed out along the triangle normal;
the rest are kept only if the reachability condition holds.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.contact.reachability import ReachabilityChecker
from planner.poses import poses_from

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class OrientationBounds:
    """Bounds (rad) of the root's yaw (about world z), pitch (y) and roll (x); R = Rz Ry Rx."""

    yaw: tuple[float, float] = (-np.pi, np.pi)
    pitch: tuple[float, float] = (-0.05, 0.05)
    roll: tuple[float, float] = (-0.05, 0.05)

    def __post_init__(self) -> None:
        for name in ("yaw", "pitch", "roll"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ValueError(f"{name} bounds must satisfy low <= high")


def euler_matrices(yaw: FloatArray, pitch: FloatArray, roll: FloatArray) -> FloatArray:
    """(n, 3, 3) rotations Rz(yaw) Ry(pitch) Rx(roll) of (n,) angles in radians."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    out = np.stack(
        [
            cy * cp,
            cy * sp * sr - sy * cr,
            cy * sp * cr + sy * sr,
            sy * cp,
            sy * sp * sr + cy * cr,
            sy * sp * cr - cy * sr,
            -sp,
            cp * sr,
            cp * cr,
        ],
        axis=-1,
    )
    return np.asarray(out.reshape(-1, 3, 3), dtype=np.float64)


@dataclass(frozen=True, slots=True)
class _Triangles:
    vertices: FloatArray  # (t, 3, 3)
    normals: FloatArray  # (t, 3)
    areas: FloatArray  # (t,)
    limbs: tuple[IntArray, ...]  # per triangle: indices into required_limbs allowed there


def _triangles(checker: ReachabilityChecker) -> _Triangles:
    scene = checker.scene
    verts, normals, areas, limbs = [], [], [], []
    for surface in scene.surfaces:
        allowed = np.array(
            [
                k
                for k, name in enumerate(checker.required_limbs)
                if surface.kind in checker.allowed_kinds[name]
            ],
            dtype=np.int64,
        )
        if len(allowed) == 0:
            continue
        tv = np.asarray(surface.triangle_vertices, dtype=np.float64)
        cross = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        keep = area > 1e-12
        verts.append(tv[keep])
        normals.append(cross[keep] / (2.0 * area[keep, None]))
        areas.append(area[keep])
        limbs.extend([allowed] * int(keep.sum()))
    if not verts:
        empty = np.zeros((0, 3))
        return _Triangles(np.zeros((0, 3, 3)), empty, np.zeros(0), ())
    return _Triangles(
        np.concatenate(verts), np.concatenate(normals), np.concatenate(areas), tuple(limbs)
    )


_CACHE: weakref.WeakKeyDictionary[ReachabilityChecker, _Triangles] = weakref.WeakKeyDictionary()


def _cached_triangles(checker: ReachabilityChecker) -> _Triangles:
    """The checker's seed triangles, computed once per checker (checkers are immutable)."""
    tris = _CACHE.get(checker)
    if tris is None:
        tris = _triangles(checker)
        _CACHE[checker] = tris
    return tris


def sample_root_poses(
    checker: ReachabilityChecker,
    n: int,
    *,
    rng: np.random.Generator,
    orientation_bounds: OrientationBounds | None = None,
    near: FloatArray | None = None,
    near_radius: float = 1.0,
    area_weighted: float = 0.5,
    push_step: float = 0.05,
    pushes: int = 6,
    max_rounds: int = 20,
) -> FloatArray:
    """Up to ``n`` valid root poses (m, 4, 4), world frame, m <= n (fewer when the rounds run out).

    Each round draws ``4 n`` (at least 32) candidates: a triangle is picked area-weighted with
    probability ``area_weighted``, else uniformly; a uniform point in it; yaw/pitch/roll uniform
    within ``orientation_bounds``; the root placed so a random allowed required limb's reference
    contact centre sits on the point. Trunk collisions are pushed out along the triangle normal
    by ``push_step`` (m) up to ``pushes`` times. With ``near`` (3,), only triangles within
    ``near_radius`` (m) of it are used and points farther away are rejected. Deterministic for
    a given ``rng`` state.
    """
    bounds = OrientationBounds() if orientation_bounds is None else orientation_bounds
    tris = _cached_triangles(checker)
    if n <= 0 or len(tris.areas) == 0 or not checker.required_limbs:
        return np.zeros((0, 4, 4))
    candidates = np.arange(len(tris.areas))
    centre = None
    if near is not None:
        centre = np.asarray(near, dtype=np.float64).reshape(3)
        middle = tris.vertices.mean(axis=1)
        reach = np.linalg.norm(tris.vertices - middle[:, None], axis=2).max(axis=1)
        close = np.linalg.norm(middle - centre, axis=1) - reach <= near_radius
        candidates = candidates[close]
        if len(candidates) == 0:
            return np.zeros((0, 4, 4))
    weights = tris.areas[candidates] / tris.areas[candidates].sum()
    offsets = np.stack([checker.offsets[name] for name in checker.required_limbs])
    out: list[FloatArray] = []
    found = 0
    batch = max(32, 4 * n)
    for _ in range(max_rounds):
        by_area = rng.random(batch) < area_weighted
        pick = np.where(
            by_area,
            rng.choice(candidates, size=batch, p=weights),
            rng.choice(candidates, size=batch),
        )
        r1, r2 = rng.random(batch), rng.random(batch)
        s = np.sqrt(r1)
        tv = tris.vertices[pick]
        points = (
            (1.0 - s)[:, None] * tv[:, 0]
            + (s * (1.0 - r2))[:, None] * tv[:, 1]
            + (s * r2)[:, None] * tv[:, 2]
        )
        rotations = euler_matrices(
            rng.uniform(*bounds.yaw, size=batch),
            rng.uniform(*bounds.pitch, size=batch),
            rng.uniform(*bounds.roll, size=batch),
        )
        u = rng.random(batch)
        limb = np.array(
            [tris.limbs[t][int(x * len(tris.limbs[t]))] for t, x in zip(pick, u, strict=True)],
            dtype=np.int64,
        )
        roots = points - np.einsum("nij,nj->ni", rotations, offsets[limb])
        poses = poses_from(roots, rotations)
        keep = np.ones(batch, dtype=bool)
        if centre is not None:
            keep = np.linalg.norm(points - centre, axis=1) <= near_radius
        normals = tris.normals[pick]
        pending = np.flatnonzero(keep)
        for _ in range(pushes + 1):
            if len(pending) == 0:
                break
            hit = ~checker.trunk_free(poses[pending])
            pending = pending[hit]
            poses[pending, :3, 3] += push_step * normals[pending]
        keep[pending] = False
        idx = np.flatnonzero(keep)
        if len(idx):
            keep[idx] = checker.valid(poses[idx])
        good = poses[keep][: n - found]
        out.append(good)
        found += len(good)
        if found >= n:
            break
    return np.concatenate(out) if out else np.zeros((0, 4, 4))
