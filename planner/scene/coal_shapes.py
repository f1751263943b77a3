"""Conversion of Gecko's shared primitives (Box, Capsule, ConvexPolytope) to coal geometry.

coal geometries are cached per shape object (identity), since a character's trunk shape is
queried thousands of times per plan. Transforms: a shape at ``pose`` sits at
``pose @ shape.offset`` in the world frame.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

import coal
import numpy as np
from numpy.typing import NDArray

from planner.shapes import Box, Capsule, ConvexPolytope, Shape

FloatArray = NDArray[np.float64]

_CACHE_SIZE = 1024
_cache: OrderedDict[int, tuple[Shape, Any]] = OrderedDict()
_lock = threading.Lock()


def _build(shape: Shape) -> Any:
    if isinstance(shape, Box):
        sides = 2.0 * shape.half_extents
        return coal.Box(float(sides[0]), float(sides[1]), float(sides[2]))
    if isinstance(shape, Capsule):
        return coal.Capsule(float(shape.radius), 2.0 * float(shape.half_length))
    if isinstance(shape, ConvexPolytope):
        points = coal.StdVec_Vec3s()
        for vertex in np.asarray(shape.vertices, dtype=np.float64):
            points.append(vertex)
        return coal.Convex.convexHull(points, False, None)
    raise TypeError(f"unsupported shape type {type(shape).__name__}")


def coal_geometry(shape: Shape) -> Any:
    """The coal collision geometry of ``shape`` in its own frame (cached per object)."""
    key = id(shape)
    with _lock:
        hit = _cache.get(key)
        if hit is not None and hit[0] is shape:
            _cache.move_to_end(key)
            return hit[1]
    geometry = _build(shape)
    with _lock:
        _cache[key] = (shape, geometry)
        _cache.move_to_end(key)
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return geometry


def to_transform(matrix: FloatArray) -> Any:
    """coal.Transform3s of a (4, 4) homogeneous pose."""
    m = np.asarray(matrix, dtype=np.float64)
    return coal.Transform3s(np.ascontiguousarray(m[:3, :3]), np.ascontiguousarray(m[:3, 3]))


def shape_world_matrix(shape: Shape, pose: FloatArray) -> FloatArray:
    """(4, 4) world pose of the shape's own frame: ``pose @ shape.offset``."""
    return np.asarray(np.asarray(pose, dtype=np.float64) @ shape.offset, dtype=np.float64)


def world_halfspaces(
    shape: Box | ConvexPolytope, pose: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Half-spaces ``A x <= b`` (A (m, 3), b (m,)) of a convex shape placed at ``pose``, world."""
    if isinstance(shape, Box):
        h = shape.half_extents
        a_local = np.vstack([np.eye(3), -np.eye(3)])
        b_local = np.concatenate([h, h])
    else:
        a_local = np.asarray(shape.A, dtype=np.float64)
        b_local = np.asarray(shape.b, dtype=np.float64)
    world = shape_world_matrix(shape, pose)
    rotation, translation = world[:3, :3], world[:3, 3]
    a_world = a_local @ rotation.T
    return np.asarray(a_world, dtype=np.float64), np.asarray(b_local + a_world @ translation)
