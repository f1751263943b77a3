"""Reachability condition of the reduced model (anchor section 1): trunk W0 free, ROMs Wk touching.

A root pose (4, 4, world frame) is valid when the trunk shapes W0 collide with nothing (scene and
extra obstacles), the root lies within the position bounds, and the workspace Wk (root frame,
from the offline data) of every required limb intersects a scene surface of an allowed kind.
Workspaces are tested against a BVH of the allowed surface triangles only, never raw obstacles.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Collection, Mapping, Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character
from planner.offline import OfflineData
from planner.scene import CollisionWorld, Scene, SurfaceKind
from planner.scene.collision import build_bvh
from planner.shapes import Box, ConvexPolytope, Shape

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

GROUND_TOLERANCE = 0.01
"""A limb touches the ground in ``q_ref`` when its lowest contact point is this close (m)."""


def ground_limbs(character: Character) -> tuple[str, ...]:
    """Limbs whose contact touches the ground (z = 0) in the reference configuration."""
    model = character.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, character.q_ref)
    out = []
    for limb in character.limbs:
        placement = data.oMf[limb.frame_id]
        points = limb.contact_points() @ np.array(placement.rotation).T + placement.translation
        if float(points[:, 2].min()) <= GROUND_TOLERANCE:
            out.append(limb.name)
    return tuple(out)


def reference_offsets(character: Character) -> dict[str, FloatArray]:
    """Per limb, the (3,) contact centre in the root frame in ``q_ref`` (m)."""
    model = character.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, character.q_ref)
    root = data.oMi[1]
    out = {}
    for limb in character.limbs:
        placement = root.actInv(data.oMf[limb.frame_id])
        centre = np.array(placement.rotation) @ limb.contact_points().mean(axis=0)
        out[limb.name] = np.asarray(centre + placement.translation, dtype=np.float64)
    return out


_SUB_WORLDS: OrderedDict[tuple[int, frozenset[SurfaceKind]], tuple[Scene, CollisionWorld | None]]
_SUB_WORLDS = OrderedDict()
_SUB_WORLDS_KEPT = 8  # (scene, kinds) sub-worlds remembered: a checker is built per standing


def _sub_world(scene: Scene, kinds: frozenset[SurfaceKind]) -> CollisionWorld | None:
    """The collision world of ``scene``'s surfaces of ``kinds`` (None without any),
    remembered for the last few scenes (immutable: only queried)."""
    key = (id(scene), kinds)
    known = _SUB_WORLDS.get(key)
    if known is not None and known[0] is scene:
        _SUB_WORLDS.move_to_end(key)
        return known[1]
    world = _build_sub_world(scene, kinds)
    _SUB_WORLDS[key] = (scene, world)
    if len(_SUB_WORLDS) > _SUB_WORLDS_KEPT:
        _SUB_WORLDS.popitem(last=False)
    return world


def _build_sub_world(scene: Scene, kinds: frozenset[SurfaceKind]) -> CollisionWorld | None:
    faces = [s.triangles for s in scene.surfaces if s.kind in kinds]
    if not faces:
        return None
    face_ids = np.unique(np.concatenate(faces))
    tris = np.asarray(scene.faces[face_ids], dtype=np.int64)
    used, inverse = np.unique(tris.ravel(), return_inverse=True)
    vertices = np.ascontiguousarray(scene.vertices[used], dtype=np.float64)
    return CollisionWorld(build_bvh(vertices, inverse.reshape(-1, 3).astype(np.int64)))


def _fibonacci_sphere(k: int) -> FloatArray:
    i = np.arange(k) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / k)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )


_SIMPLIFIED: OrderedDict[tuple[int, int], tuple[ConvexPolytope, ConvexPolytope]] = OrderedDict()
_SIMPLIFIED_BY_CONTENT: OrderedDict[tuple[bytes, int], ConvexPolytope] = OrderedDict()
_SIMPLIFIED_KEPT = 64  # workspaces whose simplification is remembered (a few characters' limbs)


def simplified_workspace(workspace: ConvexPolytope, directions: int) -> ConvexPolytope:
    """Inner approximation of Wk: the hull of its support points along ``directions`` unit
    directions spread over the sphere (a subset of its vertices, so it lies inside Wk).

    Remembered per workspace object: a checker is built for every standing state, and a
    workspace of points on a sphere (a sit bone turning about the hip) keeps all its 1e5
    samples as vertices. Also remembered by content (its arrays), for the same
    workspace loaded again (offline data read anew for another plan)."""
    key = (id(workspace), directions)
    known = _SIMPLIFIED.get(key)
    if known is not None and known[0] is workspace:
        _SIMPLIFIED.move_to_end(key)
        return known[1]
    content = (_content_key(workspace), directions)
    simplified = _SIMPLIFIED_BY_CONTENT.get(content)
    if simplified is None:
        simplified = _simplify(workspace, directions)
        _SIMPLIFIED_BY_CONTENT[content] = simplified
        if len(_SIMPLIFIED_BY_CONTENT) > _SIMPLIFIED_KEPT:
            _SIMPLIFIED_BY_CONTENT.popitem(last=False)
    else:
        _SIMPLIFIED_BY_CONTENT.move_to_end(content)
    _SIMPLIFIED[key] = (workspace, simplified)
    if len(_SIMPLIFIED) > _SIMPLIFIED_KEPT:
        _SIMPLIFIED.popitem(last=False)
    return simplified


def _content_key(workspace: ConvexPolytope) -> bytes:
    """A digest of ``workspace``'s arrays (vertices, half-spaces, offset): equal digests, an
    equal simplification (:func:`_simplify` may answer the workspace itself)."""
    digest = hashlib.blake2b(digest_size=20)
    for array in (workspace.vertices, workspace.A, workspace.b, workspace.offset):
        a = np.ascontiguousarray(array, dtype=np.float64)
        digest.update(str(a.shape).encode())
        digest.update(a.tobytes())
    return digest.digest()


SUPPORT_CHUNK = 4096
"""Vertices whose products with the directions are taken at a time by :func:`support_indices`
(a (chunk, directions) block stays in cache; the whole product of 1e5 vertices is 77 MB)."""


def support_indices(vertices: FloatArray, directions: FloatArray) -> IntArray:
    """(k,) per direction of ``directions`` (k, 3), the index of the first of ``vertices``
    (n, 3) with the largest product: ``np.argmax(vertices @ directions.T, axis=0)``, the same
    products compared, taken ``SUPPORT_CHUNK`` vertices at a time (an earlier chunk keeps a
    tie, as argmax keeps the first)."""
    transposed = directions.T
    if len(vertices) <= SUPPORT_CHUNK:
        return np.asarray(np.argmax(vertices @ transposed, axis=0), dtype=np.int64)
    best = np.full(len(directions), -np.inf)
    index = np.zeros(len(directions), dtype=np.int64)
    for start in range(0, len(vertices), SUPPORT_CHUNK):
        products = vertices[start : start + SUPPORT_CHUNK] @ transposed
        top = products.max(axis=0)
        rows, cols = np.nonzero(products == top)  # row-major: each column's first row first
        _, first = np.unique(cols, return_index=True)
        if len(first) != len(top):  # a column without its maximum: nan products
            return np.asarray(np.argmax(vertices @ transposed, axis=0), dtype=np.int64)
        better = top > best
        best[better] = top[better]
        index[better] = rows[first][better] + start
    return index


def _simplify(workspace: ConvexPolytope, directions: int) -> ConvexPolytope:
    if directions <= 0 or directions >= len(workspace.vertices):
        return workspace
    support = support_indices(workspace.vertices, _fibonacci_sphere(directions))
    chosen = workspace.vertices[np.unique(support)]
    if len(chosen) < 4:
        return workspace
    return ConvexPolytope.from_points(chosen, offset=workspace.offset)


def _shape_radius(shape: Shape) -> float:
    if isinstance(shape, Box):
        points = shape.vertices()
    elif isinstance(shape, ConvexPolytope):
        points = shape.vertices @ shape.offset[:3, :3].T + shape.offset[:3, 3]
    else:
        return float(np.linalg.norm(shape.offset[:3, 3]) + shape.half_length + shape.radius)
    return float(np.linalg.norm(points, axis=1).max())


class ReachabilityChecker:
    """Batched reachability condition for one character in one scene (immutable once built).

    required_limbs : limbs whose Wk must touch a surface (default: the ground limbs of q_ref).
    allowed_kinds : per limb, the surface kinds its Wk may touch (default: ground limbs
        Support, other limbs Support and Lean). obstacles : extra (shape, (4, 4) pose) pairs
        the trunk must avoid. bounds : (2, 3) box the root position must lie in (default: the
        scene bounds grown by 1 m sideways and by the character height upwards).
    radius : m, largest distance from the root to a trunk point (used to bound how far a
        rotation moves the trunk). offsets : per limb, the reference contact centre in the
        root frame (3,).
    """

    __slots__ = (
        "__weakref__",
        "_limb_worlds",
        "_trunk_world",
        "allowed_kinds",
        "bounds",
        "character",
        "limb_names",
        "offsets",
        "radius",
        "required_limbs",
        "scene",
        "workspaces",
    )

    def __init__(
        self,
        scene: Scene,
        character: Character,
        data: OfflineData,
        *,
        required_limbs: Sequence[str] | None = None,
        allowed_kinds: Mapping[str, Collection[SurfaceKind]] | None = None,
        obstacles: Sequence[tuple[Shape, FloatArray]] = (),
        bounds: FloatArray | None = None,
        workspace_directions: int = 96,
    ) -> None:
        names = tuple(limb.name for limb in character.limbs)
        grounded = ground_limbs(character)
        required = grounded if required_limbs is None else tuple(required_limbs)
        for name in required:
            if name not in names:
                raise ValueError(f"character {character.id!r} has no limb {name!r}")
        kinds: dict[str, frozenset[SurfaceKind]] = {
            name: frozenset({SurfaceKind.SUPPORT})
            if name in grounded
            else frozenset({SurfaceKind.SUPPORT, SurfaceKind.LEAN})
            for name in names
        }
        for name, given in (allowed_kinds or {}).items():
            if name not in names:
                raise ValueError(f"character {character.id!r} has no limb {name!r}")
            kinds[name] = frozenset(given)
        self.scene = scene
        self.character = character
        self.limb_names = names
        self.required_limbs = required
        self.allowed_kinds: Mapping[str, frozenset[SurfaceKind]] = kinds
        self.workspaces = tuple(
            simplified_workspace(data.limb(name).workspace, workspace_directions) for name in names
        )
        worlds: dict[frozenset[SurfaceKind], CollisionWorld | None] = {}
        for kind_set in set(kinds.values()):
            worlds[kind_set] = _sub_world(scene, kind_set)
        self._limb_worlds = tuple(worlds[kinds[name]] for name in names)
        self._trunk_world = (
            scene.collision.with_obstacles(obstacles) if obstacles else (scene.collision)
        )
        self.offsets = reference_offsets(character)
        self.radius = max(_shape_radius(shape) for shape in character.trunk)
        if bounds is None:
            lo, hi = scene.bounds
            height = float(character.q_ref[2]) + 0.5
            grow = np.array([1.0, 1.0, 0.5]), np.array([1.0, 1.0, height])
            bounds = np.array([lo - grow[0], hi + grow[1]])
        self.bounds = np.asarray(bounds, dtype=np.float64).reshape(2, 3)

    def in_bounds(self, poses: FloatArray) -> BoolArray:
        """(n,) mask: the root positions of the (n, 4, 4) poses lie within ``bounds``."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)[:, :3, 3]
        return np.asarray(np.all((p >= self.bounds[0]) & (p <= self.bounds[1]), axis=1))

    def trunk_free(self, poses: FloatArray) -> BoolArray:
        """(n,) mask: the trunk W0 at the (n, 4, 4) root poses touches no scene part/obstacle."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        free = np.ones(len(p), dtype=bool)
        for shape in self.character.trunk:
            idx = np.flatnonzero(free)
            if len(idx) == 0:
                break
            free[idx] = ~self._trunk_world.collides_many(shape, p[idx])
        return free

    def limb_touching(self, limb: str, poses: FloatArray) -> BoolArray:
        """(n,) mask: limb's Wk at the (n, 4, 4) root poses meets an allowed surface."""
        k = self.limb_names.index(limb)
        world = self._limb_worlds[k]
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        if world is None:
            return np.zeros(len(p), dtype=bool)
        return world.collides_many(self.workspaces[k], p)

    def limbs_touching(self, poses: FloatArray) -> BoolArray:
        """(n, n_limbs) mask, limbs in ``character.limbs`` order (see ``limb_touching``)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        out = np.zeros((len(p), len(self.limb_names)), dtype=bool)
        for k, name in enumerate(self.limb_names):
            out[:, k] = self.limb_touching(name, p)
        return out

    def valid(self, poses: FloatArray) -> BoolArray:
        """(n,) mask of the (n, 4, 4) root poses meeting the reachability condition."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        ok = self.in_bounds(p)
        idx = np.flatnonzero(ok)
        if len(idx):  # trunk tests are the cheapest: they go first
            ok[idx] = self.trunk_free(p[idx])
        for name in self.required_limbs:
            idx = np.flatnonzero(ok)
            if len(idx) == 0:
                break
            ok[idx] = self.limb_touching(name, p[idx])
        return ok

    def is_valid(self, pose: FloatArray) -> bool:
        """Whether one (4, 4) root pose meets the reachability condition."""
        return bool(self.valid(np.asarray(pose, dtype=np.float64)[None])[0])
