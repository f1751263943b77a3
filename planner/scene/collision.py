"""Collision world: a coal BVH of the scene mesh (cached on disk), plus optional obstacles.

Queries take a shared primitive (Box, Capsule, ConvexPolytope) and a (4, 4) world pose of its
carrier; the shape sits at ``pose @ shape.offset``. The BVH is a triangle soup: a shape wholly
inside a closed mesh touches no triangle and does not collide.

The BVH cache stores coal's own binary format under ``<cache_dir>/<content hash>-coal<version>
.bvh``, written atomically; an unreadable file is rebuilt.
"""

from __future__ import annotations

import os
import tempfile
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import numpy as np
from numpy.typing import NDArray

from planner.scene import geometry2d as g2
from planner.scene.affordance import Surface
from planner.scene.coal_shapes import (
    coal_geometry,
    shape_world_matrix,
    to_transform,
    world_halfspaces,
)
from planner.shapes import Box, ConvexPolytope, Shape

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_COAL_VERSION = getattr(coal, "__version__", "unknown")


def bvh_cache_path(cache_dir: Path, content_hash: str) -> Path:
    """Where the BVH of the mesh with this content hash is cached."""
    return Path(cache_dir) / f"{content_hash}-coal{_COAL_VERSION}.bvh"


# coal's binary BVH file: a header, then per triangle 3 indices and per vertex 3 doubles
# (8 bytes each), and a binary tree of 2 n - 1 OBBRSS nodes of 256 bytes for n triangles.
_BVH_HEADER_BYTES = 256
_BVH_BYTES_PER_TRIANGLE = 3 * 8 + 2 * 256
_BVH_BYTES_PER_VERTEX = 3 * 8


def bvh_cache_bytes(triangles: int, vertices: int) -> int:
    """About how many bytes the cached BVH of a mesh of this size takes on disk (coal 3's
    format: within a few hundred bytes), known before building it; ~550 bytes a triangle."""
    return (
        _BVH_HEADER_BYTES + _BVH_BYTES_PER_TRIANGLE * triangles + _BVH_BYTES_PER_VERTEX * vertices
    )


def build_bvh(vertices: FloatArray, faces: NDArray[np.int64]) -> Any:
    """A coal.BVHModelOBBRSS of the (n, 3) vertices and (m, 3) faces."""
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(vertices))
    bvh.addVertices(np.ascontiguousarray(vertices, dtype=np.float64))
    bvh.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    bvh.endModel()
    return bvh


def load_or_build_bvh(
    vertices: FloatArray,
    faces: NDArray[np.int64],
    content_hash: str,
    cache_dir: Path | None,
) -> tuple[Any, bool]:
    """(BVH, loaded_from_cache). Without a cache_dir the BVH is always built."""
    if cache_dir is None:
        return build_bvh(vertices, faces), False
    path = bvh_cache_path(cache_dir, content_hash)
    if path.is_file():
        bvh = coal.BVHModelOBBRSS()
        try:
            bvh.loadFromBinary(str(path))
        except Exception:
            bvh = None
        if bvh is not None and bvh.num_tris == len(faces) and bvh.num_vertices == len(vertices):
            return bvh, True
    bvh = build_bvh(vertices, faces)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".bvh-", dir=path.parent)
    os.close(fd)
    try:
        bvh.saveToBinary(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return bvh, False


@dataclass(frozen=True, slots=True, eq=False)
class ContactRegion:
    """Where a convex shape meets a surface, in the surface plane (world frame).

    polygon : (k, 3) the largest connected piece, counter-clockwise about the surface normal.
    centroid : (3,) area centroid of the whole intersection (all pieces, holes removed);
        equal to the polygon's centroid in the usual single-piece case.
    area : m^2 of the whole intersection. pieces : every clipped loop (holes clockwise).
    Unpacks as ``polygon, centroid = region``.
    """

    polygon: FloatArray
    centroid: FloatArray
    area: float
    pieces: tuple[FloatArray, ...]

    def __iter__(self) -> Iterator[FloatArray]:
        yield self.polygon
        yield self.centroid


def contact_region(
    shape: Box | ConvexPolytope, pose: FloatArray, surface: Surface, min_area: float = 1e-10
) -> ContactRegion | None:
    """Intersection of a convex shape at ``pose`` with a surface, in the surface plane.

    Returns None when the plane section of the shape misses the surface (or the overlap has
    at most ``min_area`` m^2).
    """
    if not isinstance(shape, Box | ConvexPolytope):
        raise TypeError("contact_region needs a Box or a ConvexPolytope")
    a_world, b_world = world_halfspaces(shape, pose)
    u, v = surface.basis[0], surface.basis[1]
    a2 = np.stack([a_world @ u, a_world @ v], axis=1)
    b2 = b_world - a_world @ surface.centroid
    scale = np.linalg.norm(a_world, axis=1)
    parallel = np.linalg.norm(a2, axis=1) <= 1e-12 * np.maximum(scale, 1e-300)
    if np.any(b2[parallel] < 0.0):
        return None
    a2, b2 = a2[~parallel], b2[~parallel]
    pieces: list[FloatArray] = []
    total_area = 0.0
    total_moment = np.zeros(2)
    best: FloatArray | None = None
    best_area = 0.0
    for loop in surface.polygons_2d():
        clipped = g2.clip_halfplanes(loop, a2, b2)
        if len(clipped) < 3:
            continue
        area, moment = g2.area_moments(clipped)
        if area == 0.0:
            continue
        pieces.append(clipped)
        total_area += area
        total_moment += moment
        if area > best_area:
            best, best_area = clipped, area
    if best is None or total_area <= min_area:
        return None
    return ContactRegion(
        polygon=_lift(surface, best),
        centroid=_lift(surface, total_moment / total_area)[0],
        area=float(total_area),
        pieces=tuple(_lift(surface, p) for p in pieces),
    )


def _lift(surface: Surface, coords: FloatArray) -> FloatArray:
    out = surface.from_plane(coords)
    out.flags.writeable = False
    return out


class _Scratch(threading.local):
    """Per-thread reusable coal request/result/transform objects and collision functors."""

    def __init__(self) -> None:
        self.collision_request = coal.CollisionRequest()
        self.collision_result = coal.CollisionResult()
        self.distance_request = coal.DistanceRequest()
        self.distance_result = coal.DistanceResult()
        self.transform = coal.Transform3s()
        self.functors: dict[int, tuple[Any, Any]] = {}


def _mesh_box(bvh: Any) -> tuple[FloatArray, FloatArray]:
    """Corners (3,) low and high of the box of ``bvh``'s vertices (read, not modified)."""
    vertices = np.asarray(bvh.vertices(), dtype=np.float64).reshape(-1, 3)
    if len(vertices) == 0:
        return np.full(3, np.inf), np.full(3, -np.inf)
    return vertices.min(axis=0), vertices.max(axis=0)


def _world_box(
    mesh: tuple[FloatArray, FloatArray], obstacles: Sequence[tuple[Any, Any]]
) -> tuple[FloatArray, FloatArray]:
    """Corners (3,) low and high of a box around the ``mesh`` box and the bounding balls of
    the ``obstacles`` (coal geometry, coal.Transform3s)."""
    low, high = mesh
    for geometry, transform in obstacles:
        geometry.computeLocalAABB()
        centre = transform.transform(np.asarray(geometry.aabb_center, dtype=np.float64))
        radius = float(geometry.aabb_radius)
        low = np.minimum(low, centre - radius)
        high = np.maximum(high, centre + radius)
    return low, high


class CollisionWorld:
    """A scene BVH plus extra convex obstacles; immutable once built, safe across threads.

    Build it with ``Scene`` (or ``CollisionWorld(bvh)``); ``with_obstacles`` returns a new world
    that shares the BVH (and ``mesh_box``, the box of its vertices, computed once). ``from_cache``
    tells whether the BVH came from the disk cache.
    """

    __slots__ = ("_box", "_bvh", "_identity", "_mesh_box", "_obstacles", "_scratch", "from_cache")

    def __init__(
        self,
        bvh: Any,
        obstacles: Sequence[tuple[Any, Any]] = (),
        *,
        from_cache: bool = False,
        mesh_box: tuple[FloatArray, FloatArray] | None = None,
    ) -> None:
        self._bvh = bvh
        self._identity = coal.Transform3s()
        self._obstacles: tuple[tuple[Any, Any], ...] = tuple(obstacles)
        self._scratch = _Scratch()
        self.from_cache = from_cache
        self._mesh_box = _mesh_box(bvh) if mesh_box is None else mesh_box
        self._box = _world_box(self._mesh_box, self._obstacles)

    @property
    def bvh(self) -> Any:
        """The coal.BVHModelOBBRSS of the scene mesh (do not modify)."""
        return self._bvh

    @property
    def triangle_count(self) -> int:
        return int(self._bvh.num_tris)

    @property
    def obstacle_count(self) -> int:
        return len(self._obstacles)

    def with_obstacles(self, obstacles: Sequence[tuple[Shape, FloatArray]]) -> CollisionWorld:
        """A new world with extra convex obstacles (shape, (4, 4) world pose of its carrier)."""
        extra = [
            (coal_geometry(shape), to_transform(shape_world_matrix(shape, pose)))
            for shape, pose in obstacles
        ]
        return CollisionWorld(
            self._bvh,
            (*self._obstacles, *extra),
            from_cache=self.from_cache,
            mesh_box=self._mesh_box,
        )

    add_obstacles = with_obstacles

    def _transform(self, matrix: FloatArray) -> Any:
        transform = self._scratch.transform
        transform.setRotation(matrix[:3, :3])
        transform.setTranslation(matrix[:3, 3])
        return transform

    def _functor(self, geometry: Any) -> Any:
        functors = self._scratch.functors
        hit = functors.get(id(geometry))
        if hit is None or hit[0] is not geometry:
            if len(functors) > 256:
                functors.clear()
            hit = (geometry, coal.ComputeCollision(self._bvh, geometry))
            functors[id(geometry)] = hit
        return hit[1]

    def beyond(self, centres: FloatArray, radii: FloatArray) -> NDArray[np.bool_]:
        """(n,) whether each ball (centres (n, 3) world frame, radii (n,) m) lies wholly
        outside the box around the mesh and every obstacle: a shape inside such a ball
        touches nothing of this world."""
        low, high = self._box
        c = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
        r = np.asarray(radii, dtype=np.float64).reshape(-1, 1)
        return np.asarray(np.any((c - r > high) | (c + r < low), axis=1), dtype=np.bool_)

    def _collide(self, geometry: Any, matrix: FloatArray) -> bool:
        scratch = self._scratch
        request, result = scratch.collision_request, scratch.collision_result
        transform = self._transform(matrix)
        result.clear()
        if self._functor(geometry)(self._identity, transform, request, result):
            return True
        for other, other_tf in self._obstacles:
            result.clear()
            if coal.collide(other, other_tf, geometry, transform, request, result):
                return True
        return False

    def _distance(self, geometry: Any, matrix: FloatArray) -> float:
        request = self._scratch.distance_request
        result = self._scratch.distance_result
        transform = self._transform(matrix)
        best = np.inf
        for other, other_tf in ((self._bvh, self._identity), *self._obstacles):
            result.clear()
            best = min(
                best, float(coal.distance(other, other_tf, geometry, transform, request, result))
            )
        return float(best)

    def push_direction(self, geometry: Any, matrix: FloatArray) -> FloatArray | None:
        """Unit direction (3,) that takes a coal ``geometry`` at the world ``matrix`` (4, 4)
        out of what it touches (the mean contact normal, pointing from the scene and the
        obstacles into the geometry); None when it touches nothing."""
        request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, 64)
        transform = to_transform(matrix)
        total = np.zeros(3)
        for other, other_tf in ((self._bvh, self._identity), *self._obstacles):
            result = coal.CollisionResult()
            if coal.collide(other, other_tf, geometry, transform, request, result):
                for contact in result.getContacts():
                    total += np.asarray(contact.normal, dtype=np.float64)
        norm = float(np.linalg.norm(total))
        if norm < 1e-9:
            return None
        return np.asarray(total / norm, dtype=np.float64)

    def collides(self, shape: Shape, pose: FloatArray) -> bool:
        """Whether ``shape`` at the (4, 4) carrier pose touches the scene or an obstacle."""
        return self._collide(coal_geometry(shape), shape_world_matrix(shape, pose))

    def collides_many(self, shape: Shape, poses: FloatArray) -> BoolArray:
        """(n,) collision flags for (n, 4, 4) carrier poses."""
        geometry = coal_geometry(shape)
        matrices = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4) @ shape.offset
        return np.fromiter(
            (self._collide(geometry, m) for m in matrices), dtype=bool, count=len(matrices)
        )

    def distance(self, shape: Shape, pose: FloatArray) -> float:
        """Distance (m) from ``shape`` at the carrier pose to the nearest object.

        Negative values are coal's penetration estimate when the shape cuts a triangle.
        """
        return self._distance(coal_geometry(shape), shape_world_matrix(shape, pose))

    def distance_many(self, shape: Shape, poses: FloatArray) -> FloatArray:
        """(n,) distances for (n, 4, 4) carrier poses."""
        geometry = coal_geometry(shape)
        matrices = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4) @ shape.offset
        return np.fromiter(
            (self._distance(geometry, m) for m in matrices), dtype=np.float64, count=len(matrices)
        )

    def colliding_triangles(
        self, shape: Shape, pose: FloatArray, max_contacts: int = 1000
    ) -> NDArray[np.int64]:
        """Sorted unique scene face ids that ``shape`` at the carrier pose touches."""
        request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, max_contacts)
        result = coal.CollisionResult()
        transform = to_transform(shape_world_matrix(shape, pose))
        coal.collide(self._bvh, self._identity, coal_geometry(shape), transform, request, result)
        ids = [contact.b1 for contact in result.getContacts()]
        return np.unique(np.asarray(ids, dtype=np.int64))

    def contact_region(
        self, shape: Box | ConvexPolytope, pose: FloatArray, surface: Surface
    ) -> ContactRegion | None:
        """Where a convex shape at the carrier pose meets ``surface`` (see ``contact_region``)."""
        return contact_region(shape, pose, surface)
