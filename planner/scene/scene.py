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
