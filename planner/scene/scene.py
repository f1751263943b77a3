"""Scene: a validated mesh with its affordance surfaces and its collision world."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from numpy.typing import NDArray

from planner.scene.affordance import AffordanceParams, Surface, SurfaceKind, extract_surfaces
from planner.scene.collision import CollisionWorld, load_or_build_bvh
from planner.scene.errors import SceneError
from planner.scene.io import validate_arrays

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_HASH_VERSION = b"gecko-scene-mesh-v1"


def content_hash(vertices: FloatArray, faces: IntArray) -> str:
    """32-hex-digit SHA-256 prefix of the float64 (n, 3) vertices and int64 (m, 3) faces."""
    v = np.ascontiguousarray(vertices, dtype="<f8")
    f = np.ascontiguousarray(faces, dtype="<i8")
    digest = hashlib.sha256(_HASH_VERSION)
    digest.update(np.array([len(v), len(f)], dtype="<i8").tobytes())
    digest.update(v.tobytes())
    digest.update(f.tobytes())
    return digest.hexdigest()[:32]


@dataclass(frozen=True, slots=True, eq=False)
class Scene:
    """A scene mesh (world frame, metres, z up) with its surfaces and collision world.

    id : the given id or the content hash. vertices (n, 3), faces (m, 3): read-only copies of
    the mesh arrays. surfaces : Support surfaces first, then Lean. face_surface : (m,) surface
    id per face, -1 where none. content_hash : hash of the mesh arrays (keys the BVH cache).
    """

    id: str
    name: str
    mesh: trimesh.Trimesh
    vertices: FloatArray
    faces: IntArray
    surfaces: tuple[Surface, ...]
    face_surface: IntArray
    collision: CollisionWorld
    params: AffordanceParams
    content_hash: str

    @property
    def bounds(self) -> FloatArray:
        """(2, 3) axis-aligned bounds: min corner, max corner."""
        return np.asarray(np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)]))

    @property
    def triangle_count(self) -> int:
        return len(self.faces)

    def surfaces_of(self, kind: SurfaceKind) -> tuple[Surface, ...]:
        """The surfaces of one kind, in id order."""
        return tuple(s for s in self.surfaces if s.kind is kind)

    def inside_solid(self, point: FloatArray) -> bool:
        """Whether ``point`` (3,) is inside a solid of the mesh: the vertical ray up from it
        crosses the mesh an odd number of times (distinct heights, so a ray through an edge
        shared by two triangles counts once). Ground running on under a staircase, or under
        a block whose bottom face was left out, is inside; ground under a table is not."""
        pz = float(np.asarray(point, dtype=np.float64).reshape(3)[2])
        heights = _vertical_crossings(self, point)
        above = np.unique(np.round(heights[heights > pz + 1e-9], 6))
        return len(above) % 2 == 1

    def height_below(self, point: FloatArray) -> float | None:
        """Height (m, world z) of the highest mesh point straight below ``point`` (3,): the
        top of whatever a body at ``point`` would stand on; None when nothing is below."""
        pz = float(np.asarray(point, dtype=np.float64).reshape(3)[2])
        heights = _vertical_crossings(self, point)
        heights = heights[heights <= pz + 1e-9]
        return float(heights.max()) if len(heights) else None

    def heights_below(self, points: FloatArray) -> FloatArray:
        """:meth:`height_below` of each of (n, 3) points (n,), nan where nothing is below."""
        return _heights_below(self, points)


_HEIGHTS_BLOCK = 1 << 20  # (points x faces) entries per block of heights_below


def _heights_below(scene: Scene, points: FloatArray) -> FloatArray:
    """:meth:`Scene.height_below` of each of (n, 3) points at once, nan where nothing is
    below: the faces whose boxes the points' span meets are picked once (per block of
    points, bounding memory), and each point is then tested against those (the same
    arithmetic, point by point, as one call each)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.full(len(pts), np.nan)
    lo, hi, tri = _vertical_ray_data(scene)
    step = max(1, _HEIGHTS_BLOCK // max(1, len(tri)))
    for begin in range(0, len(pts), step):
        out[begin : begin + step] = _block_heights_below(lo, hi, tri, pts[begin : begin + step])
    return out


def _block_heights_below(
    lo: FloatArray, hi: FloatArray, tri: FloatArray, pts: FloatArray
) -> FloatArray:
    """:func:`_heights_below` of the points ``pts`` (n, 3), given the faces' boxes (low and
    high corners (m, 3)) and triangles (m, 3, 3)."""
    out = np.full(len(pts), np.nan)
    hit, heights = _crossings(lo, hi, tri, pts)
    hit &= heights <= pts[:, 2:3] + 1e-9
    found = hit.any(axis=1)
    if found.any():
        out[found] = np.where(hit, heights, -np.inf)[found].max(axis=1)
    return out


def _vertical_crossings(scene: Scene, point: FloatArray) -> FloatArray:
    """Heights (k,) where the vertical line through ``point`` (3,) crosses a face of
    ``scene`` (vertical faces are grazed, not crossed)."""
    pts = np.asarray(point, dtype=np.float64).reshape(1, 3)
    hit, heights = _crossings(*_vertical_ray_data(scene), pts)
    return np.asarray(heights[0][hit[0]], dtype=np.float64)


def _crossings(
    lo: FloatArray, hi: FloatArray, tri: FloatArray, pts: FloatArray
) -> tuple[NDArray[np.bool_], FloatArray]:
    """Whether the vertical line through each of the points ``pts`` (n, 3) crosses each face
    (n, k) whose box the points' span meets (of the faces' boxes, low and high corners
    (m, 3), and triangles (m, 3, 3); vertical faces are grazed, not crossed), and at which
    height (n, k) m."""
    span = (
        (lo[:, 0] <= pts[:, 0].max())
        & (pts[:, 0].min() <= hi[:, 0])
        & (lo[:, 1] <= pts[:, 1].max())
        & (pts[:, 1].min() <= hi[:, 1])
    )
    lo, hi, t = lo[span], hi[span], tri[span]
    px, py = pts[:, 0:1], pts[:, 1:2]  # (n, 1) against (k,) faces
    near = (lo[:, 0] <= px) & (px <= hi[:, 0]) & (lo[:, 1] <= py) & (py <= hi[:, 1])
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    v0, v1 = b[:, :2] - a[:, :2], c[:, :2] - a[:, :2]
    v2x, v2y = px - a[:, 0], py - a[:, 1]  # (n, k)
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    flat = np.abs(den) > 1e-12
    den = np.where(flat, den, 1.0)
    wb = (v2x * v1[:, 1] - v1[:, 0] * v2y) / den
    wc = (v0[:, 0] * v2y - v2x * v0[:, 1]) / den
    wa = 1.0 - wb - wc
    hit = near & flat & (wa >= -1e-12) & (wb >= -1e-12) & (wc >= -1e-12)
    heights = wa * a[:, 2] + wb * b[:, 2] + wc * c[:, 2]
    return hit, heights


_RAY_DATA: dict[int, tuple[Scene, FloatArray, FloatArray, FloatArray]] = {}


def _vertical_ray_data(scene: Scene) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per face of ``scene``: bounding-box corners (m, 3) low and high, and the triangles
    (m, 3, 3); memoised per scene."""
    hit = _RAY_DATA.get(id(scene))
    if hit is None or hit[0] is not scene:
        tri = np.asarray(scene.vertices[scene.faces], dtype=np.float64)
        hit = (scene, tri.min(axis=1), tri.max(axis=1), tri)
        if len(_RAY_DATA) > 64:
            _RAY_DATA.clear()
        _RAY_DATA[id(scene)] = hit
    return hit[1], hit[2], hit[3]


def build_scene(
    mesh: trimesh.Trimesh,
    *,
    scene_id: str | None = None,
    name: str = "",
    params: AffordanceParams | None = None,
    cache_dir: Path | None = None,
) -> Scene:
    """Extract the surfaces of ``mesh`` and build (or load from ``cache_dir``) its BVH.

    scene_id defaults to the content hash of the mesh arrays. Raises SceneError on an empty,
    non-finite or malformed mesh. The mesh is not modified.
    """
    params = AffordanceParams() if params is None else params
    if not isinstance(mesh, trimesh.Trimesh):
        raise SceneError("build_scene needs a trimesh.Trimesh", "mesh")
    vertices, faces = validate_arrays(mesh.vertices, mesh.faces)
    vertices = vertices.copy()
    faces = faces.copy()
    vertices.flags.writeable = False
    faces.flags.writeable = False
    digest = content_hash(vertices, faces)
    surfaces, face_surface = extract_surfaces(vertices, faces, params)
    face_surface.flags.writeable = False
    bvh, from_cache = load_or_build_bvh(vertices, faces, digest, cache_dir)
    return Scene(
        id=digest if scene_id is None else scene_id,
        name=name,
        mesh=mesh,
        vertices=vertices,
        faces=faces,
        surfaces=surfaces,
        face_surface=face_surface,
        collision=CollisionWorld(bvh, from_cache=from_cache),
        params=params,
        content_hash=digest,
    )
