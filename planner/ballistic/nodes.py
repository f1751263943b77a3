"""Reduced model of a character in a scene: trunk collision, contact estimate, node sampling.

The reduced model (jump paper, section 3) is the trunk W0 (the character's trunk shapes) plus
one reachable workspace Wk per limb (``OfflineData``), both rigidly attached to the root. A root
pose is a valid roadmap node when W0 is collision-free and at least ``min_limbs`` workspaces
meet a contact surface (Support, optionally Lean).

Contact estimate (no whole-body search): for each limb whose Wk meets surfaces, the contact is
the area centroid of Wk ∩ S for the largest surface S (by area) that Wk meets, with the
normal of S and the limb's (or the configured) mu. Wk is replaced by an inner approximation
(the hull of its support points in ``_DIRECTIONS`` directions, ~50 vertices): the exact hulls
have thousands of faces and the estimate only needs the centre of the section. The centroidal
cone follows ``cones.centroidal_cones``; force-closure configurations (normals summing to zero)
are rejected as nodes, as the jump paper does.

Arrays kept per node in ``RoadmapNodes.contacts`` (L = number of limbs, character order):
``active`` (N, L) bool, ``points`` (N, L, 3) m, ``normals`` (N, L, 3), ``mus`` (N, L),
``surfaces`` (N, L) int64 surface ids (-1 when inactive).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.ballistic.cones import centroidal_cones
from planner.ballistic.roadmap import RoadmapNodes
from planner.character import Character
from planner.kinematics import frame_placement
from planner.offline import OfflineData
from planner.poses import matrix_to_quaternion, quaternion_to_matrix, rotation_between
from planner.scene import Scene, Surface, SurfaceKind
from planner.scene import geometry2d as g2
from planner.shapes import Box, Capsule, ConvexPolytope

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

_DIRECTIONS = 64
"""Support directions of the reduced workspace hulls."""


def _fibonacci_sphere(k: int) -> FloatArray:
    i = np.arange(k) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / k)
    theta = np.pi * (1.0 + 5.0**0.5) * i
    return np.asarray(
        np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]),
        dtype=np.float64,
    )


def reduced_hull(polytope: ConvexPolytope, directions: int = _DIRECTIONS) -> ConvexPolytope:
    """Inner approximation of a convex polytope: the hull of its support points along
    ``directions`` quasi-uniform directions (same frame as ``polytope``)."""
    dirs = _fibonacci_sphere(directions)
    verts = polytope.vertices
    picked = np.unique(np.argmax(verts @ dirs.T, axis=0))
    return ConvexPolytope.from_points(verts[picked], offset=polytope.offset)


def poses_from_quaternions(positions: FloatArray, quats: FloatArray) -> FloatArray:
    """(n, 4, 4) poses from (n, 3) positions and (n, 4) quaternions [x, y, z, w]."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(pos), 4, 4))
    out[:, :3, :3] = quaternion_to_matrix(np.asarray(quats, dtype=np.float64).reshape(-1, 4))
    out[:, :3, 3] = pos
    out[:, 3, 3] = 1.0
    return out


# --------------------------------------------------------------------------------------------
# Trunk collision


@dataclass(frozen=True, slots=True, eq=False)
class TrunkCollider:
    """``collides_many(poses (n, 4, 4)) -> (n,) bool`` for the character's trunk W0 against the
    scene, every shape inflated by ``margin`` (m).

    With ``margin`` = max_gap / 2 the bounded-gap arc check of ``arc`` is conservative for the
    root's path (consecutive samples are at most max_gap apart in a straight line).
    """

    scene: Scene
    shapes: tuple[Box | Capsule, ...]
    margin: float

    @staticmethod
    def of(scene: Scene, character: Character, margin: float) -> TrunkCollider:
        """The trunk of ``character`` inflated by ``margin`` (m) in ``scene``."""
        grown: list[Box | Capsule] = []
        for shape in character.trunk:
            if isinstance(shape, Box):
                grown.append(Box(shape.half_extents + margin, shape.offset))
            else:
                grown.append(Capsule(shape.radius + margin, shape.half_length, shape.offset))
        return TrunkCollider(scene, tuple(grown), float(margin))

    @property
    def reach(self) -> float:
        """Largest distance (m) of a point of the (inflated) trunk from the root."""
        out = 0.0
        for shape in self.shapes:
            centre = float(np.linalg.norm(shape.offset[:3, 3]))
            if isinstance(shape, Box):
                out = max(out, centre + float(np.linalg.norm(shape.half_extents)))
            else:
                out = max(out, centre + shape.radius + shape.half_length)
        return out

    def _hits(self, poses: FloatArray) -> BoolArray:
        hit = np.zeros(len(poses), dtype=bool)
        for shape in self.shapes:
            todo = np.flatnonzero(~hit)
            if len(todo) == 0:
                break
            hit[todo] = self.scene.collision.collides_many(shape, poses[todo])
        return hit

    def clearance(self, poses: FloatArray) -> FloatArray:
        """(n,) distance (m) from the inflated trunk to the scene (<= 0: touching)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        out = np.full(len(p), np.inf)
        for shape in self.shapes:
            out = np.minimum(out, self.scene.collision.distance_many(shape, p))
        return out

    def __call__(self, poses: FloatArray) -> BoolArray:
        """(n,) True where the inflated trunk at the root pose (n, 4, 4) touches the scene."""
        return self._hits(np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4))


# --------------------------------------------------------------------------------------------
# Contact estimate


@dataclass(frozen=True, slots=True)
class NodeContacts:
    """Contact estimate of n root poses, L limbs in character order.

    active (n, L) bool; points (n, L, 3) m (world); normals (n, L, 3) unit; mus (n, L);
    surfaces (n, L) int64 surface ids (-1 inactive); areas (n, L) m^2 of Wk ∩ surface.
    """

    active: BoolArray
    points: FloatArray
    normals: FloatArray
    mus: FloatArray
    surfaces: IntArray
    areas: FloatArray

    def as_arrays(self) -> dict[str, NDArray[np.generic]]:
        """The ``RoadmapNodes.contacts`` mapping."""
        return {
            "active": self.active,
            "points": self.points,
            "normals": self.normals,
            "mus": self.mus,
            "surfaces": self.surfaces,
        }


def hull_edges(polytope: ConvexPolytope) -> IntArray:
    """(E, 2) vertex index pairs of the edges of a convex polytope's hull triangulation."""
    from scipy.spatial import ConvexHull

    tri = ConvexHull(polytope.vertices).simplices
    pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    pairs = np.sort(pairs, axis=1)
    return np.asarray(np.unique(pairs, axis=0), dtype=np.int64)


_HULLS: dict[tuple[str, str], tuple[ConvexPolytope, IntArray]] = {}


def _reduced(data: OfflineData, limb: str) -> tuple[ConvexPolytope, IntArray]:
    """Reduced hull of a limb's workspace and its edges, cached by the data's cache key."""
    key = (data.cache_key, limb)
    found = _HULLS.get(key)
    if found is None:
        hull = reduced_hull(data.limb(limb).workspace)
        found = (hull, hull_edges(hull))
        if len(_HULLS) > 256:
            _HULLS.clear()
        _HULLS[key] = found
    return found


def _convex(loop: FloatArray) -> bool:
    edge = np.roll(loop, -1, axis=0) - loop
    turn = (
        edge[:, 0] * np.roll(edge, -1, axis=0)[:, 1] - edge[:, 1] * np.roll(edge, -1, axis=0)[:, 0]
    )
    return bool(np.all(turn >= -1e-12))


def _convex_planes(surface: Surface) -> list[tuple[float, float, float]] | None:
    """Half-planes of a surface made of one convex loop, None otherwise."""
    if len(surface.polygons_uv) != 1 or not _convex(surface.polygons_uv[0]):
        return None
    a, b = _halfplanes(surface.polygons_uv[0])
    return [(float(x), float(y), float(z)) for (x, y), z in zip(a, b, strict=True)]


def _halfplanes(polygon: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Half-planes a x <= b (outward a) of a counter-clockwise convex polygon (k, 2)."""
    edge = np.roll(polygon, -1, axis=0) - polygon
    a = np.column_stack([edge[:, 1], -edge[:, 0]])
    return a, np.einsum("ij,ij->i", a, polygon)


def _clip_convex(
    polygon: list[list[float]], planes: list[tuple[float, float, float]]
) -> list[list[float]]:
    """Sutherland-Hodgman clip of a small polygon by half-planes (ax, ay, b): a . x <= b, in
    plain Python (faster than numpy at these sizes)."""
    out = polygon
    for ax, ay, b in planes:
        if not out:
            break
        side = [ax * x + ay * y - b for x, y in out]
        if max(side) <= 0.0:
            continue
        if min(side) > 0.0:
            return []
        nxt: list[list[float]] = []
        count = len(out)
        for i in range(count):
            j = (i + 1) % count
            si, sj = side[i], side[j]
            if si <= 0.0:
                nxt.append(out[i])
            if (si <= 0.0) != (sj <= 0.0):
                t = si / (si - sj)
                xi, yi = out[i]
                xj, yj = out[j]
                nxt.append([xi + t * (xj - xi), yi + t * (yj - yi)])
        out = nxt
    return out


def _area_centroid(polygon: list[list[float]]) -> tuple[float, float, float]:
    """Signed area and centroid (x, y) of a simple polygon given as [x, y] pairs."""
    area = cx = cy = 0.0
    x0, y0 = polygon[0]
    count = len(polygon)
    for i in range(1, count - 1):
        x1, y1 = polygon[i]
        x2, y2 = polygon[i + 1]
        cross = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        area += cross
        cx += cross * (x0 + x1 + x2)
        cy += cross * (y0 + y1 + y2)
    if abs(area) < 1e-300:
        return 0.0, x0, y0
    return 0.5 * area, cx / (3.0 * area), cy / (3.0 * area)


def _section(
    world: FloatArray,
    edges: IntArray,
    surface: Surface,
    convex: list[tuple[float, float, float]] | None,
) -> tuple[float, FloatArray] | None:
    """Area (m^2) and centroid (3,) of hull(world) ∩ surface, or None if empty.

    world : (V, 3) the hull's vertices in the world frame; edges : (E, 2) its edges. The plane
    section of the hull is the convex polygon of the edge/plane crossings; it is clipped by the
    surface polygon (``convex``: its half-planes, for a convex surface) or clips each surface
    loop (otherwise)."""
    dist = (world - surface.centroid) @ surface.normal
    da, db = dist[edges[:, 0]], dist[edges[:, 1]]
    cross = (da < 0.0) != (db < 0.0)
    if np.count_nonzero(cross) < 3:
        return None
    e = edges[cross]
    t = (da[cross] / (da[cross] - db[cross]))[:, None]
    pts = world[e[:, 0]] + t * (world[e[:, 1]] - world[e[:, 0]])
    uv = (pts - surface.centroid) @ surface.basis[:2].T
    centre = uv.mean(axis=0)
    order = np.argsort(np.arctan2(uv[:, 1] - centre[1], uv[:, 0] - centre[0]))
    section = uv[order]
    if convex is not None:
        kept = _clip_convex(section.tolist(), convex)
        if len(kept) < 3:
            return None
        area, cx, cy = _area_centroid(kept)
        if area <= 1e-10:
            return None
        return area, np.asarray(surface.from_plane(np.array([cx, cy]))[0], dtype=np.float64)
    a2, b2 = _halfplanes(section)
    total = 0.0
    moment = np.zeros(2)
    for loop in surface.polygons_uv:
        clipped = g2.clip_halfplanes(loop, a2, b2)
        if len(clipped) < 3:
            continue
        piece, mom = g2.area_moments(clipped)
        total += piece
        moment += mom
    if total <= 1e-10:
        return None
    return total, np.asarray(surface.from_plane(moment / total)[0], dtype=np.float64)


@dataclass(frozen=True, slots=True, eq=False)
class ReducedModel:
    """A character's reduced model in a scene (see the module docstring).

    workspaces : per limb, the reduced Wk (root frame). surfaces : the contact surfaces.
    reference_points : (L, 3) each limb's contact centre at ``q_ref`` in the root frame.
    stance : indices of the limbs whose reference contact is within 5 cm of the lowest one
    (the feet; used to place sampled roots). mus : (L,) friction per limb.
    """

    scene: Scene
    character: Character
    workspaces: tuple[ConvexPolytope, ...]
    edges: tuple[IntArray, ...]
    surfaces: tuple[Surface, ...]
    convex: tuple[list[tuple[float, float, float]] | None, ...]
    reference_points: FloatArray
    stance: IntArray
    mus: FloatArray
    collider: TrunkCollider
    _plane: FloatArray = field(repr=False)  # (S, 4): normal, offset of each surface plane
    _boxes: FloatArray = field(repr=False)  # (S, 2, 2): uv bounds of each surface
    _area_rank: IntArray = field(repr=False)  # (S,): rank of each surface by decreasing area

    @staticmethod
    def build(
        scene: Scene,
        character: Character,
        data: OfflineData,
        *,
        lean: bool = False,
        mu: float | None = None,
        margin: float = 0.025,
    ) -> ReducedModel:
        """Reduced model; ``lean`` adds Lean surfaces as contact surfaces, ``mu`` overrides the
        limbs' friction, ``margin`` (m) inflates the trunk (see ``TrunkCollider``)."""
        kinds = {SurfaceKind.SUPPORT, SurfaceKind.LEAN} if lean else {SurfaceKind.SUPPORT}
        surfaces = tuple(s for s in scene.surfaces if s.kind in kinds)
        hulls = [_reduced(data, limb.name) for limb in character.default_limbs]
        workspaces = tuple(hull for hull, _ in hulls)
        ref = np.zeros((len(character.default_limbs), 3))
        root_rot = quaternion_to_matrix(character.q_ref[3:7])
        root_pos = character.q_ref[:3]
        for k, limb in enumerate(character.default_limbs):
            eff = frame_placement(character.model, character.q_ref, limb.effector_frame)
            point = eff[:3, :3] @ limb.offset + eff[:3, 3]
            ref[k] = root_rot.T @ (point - root_pos)
        stance = np.flatnonzero(ref[:, 2] <= ref[:, 2].min() + 0.05).astype(np.int64)
        mus = np.array(
            [limb.mu if mu is None else mu for limb in character.default_limbs], np.float64
        )
        plane = np.array([[*s.normal, -float(s.normal @ s.centroid)] for s in surfaces])
        boxes = np.array(
            [
                [np.concatenate(s.polygons_uv).min(axis=0), np.concatenate(s.polygons_uv).max(0)]
                for s in surfaces
            ]
        ).reshape(-1, 2, 2)
        return ReducedModel(
            scene,
            character,
            workspaces,
            tuple(edges for _, edges in hulls),
            surfaces,
            tuple(_convex_planes(sf) for sf in surfaces),
            ref,
            stance,
            mus,
            TrunkCollider.of(scene, character, margin),
            plane.reshape(-1, 4),
            boxes,
            np.argsort(np.argsort([-sf.area for sf in surfaces], kind="stable")).astype(np.int64),
        )

    @property
    def n_limbs(self) -> int:
        return len(self.workspaces)

    def contacts(self, poses: FloatArray) -> NodeContacts:
        """Contact estimate at root poses (n, 4, 4) (see the module docstring)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        n, n_limbs, n_surf = len(p), self.n_limbs, len(self.surfaces)
        active = np.zeros((n, n_limbs), dtype=bool)
        points = np.zeros((n, n_limbs, 3))
        normals = np.zeros((n, n_limbs, 3))
        surf_ids = np.full((n, n_limbs), -1, dtype=np.int64)
        areas = np.zeros((n, n_limbs))
        if n == 0 or n_surf == 0:
            return NodeContacts(active, points, normals, self._mus(n), surf_ids, areas)
        rot, trans = p[:, :3, :3], p[:, :3, 3]
        for k, ws in enumerate(self.workspaces):
            world = np.einsum("nij,vj->nvi", rot, ws.vertices) + trans[:, None, :]  # (n, V, 3)
            dist = np.einsum("nvi,si->nsv", world, self._plane[:, :3]) + self._plane[None, :, 3:4]
            straddle = (dist.min(axis=2) <= 0.0) & (dist.max(axis=2) >= 0.0)  # (n, S)
            for s_idx, surface in enumerate(self.surfaces):
                rows = np.flatnonzero(straddle[:, s_idx])
                if len(rows) == 0:
                    continue
                uv = np.einsum("nvi,ji->nvj", world[rows] - surface.centroid, surface.basis[:2])
                box = self._boxes[s_idx]
                overlap = np.all(uv.min(axis=1) <= box[1], axis=1) & np.all(
                    uv.max(axis=1) >= box[0], axis=1
                )
                straddle[rows[~overlap], s_idx] = False
            # The largest surface with a non-empty section wins: visit surfaces by decreasing
            # area (ties: lower index) and stop at the first section found.
            rows_i, surf_i = np.nonzero(straddle)
            visit = np.lexsort((self._area_rank[surf_i], rows_i))
            for i, s_idx in zip(rows_i[visit], surf_i[visit], strict=True):
                if active[i, k]:
                    continue
                found = _section(world[i], self.edges[k], self.surfaces[s_idx], self.convex[s_idx])
                if found is not None:
                    areas[i, k] = found[0]
                    points[i, k] = found[1]
                    normals[i, k] = self.surfaces[s_idx].normal
                    surf_ids[i, k] = self.surfaces[s_idx].id
                    active[i, k] = True
        return NodeContacts(active, points, normals, self._mus(n), surf_ids, areas)

    def _mus(self, n: int) -> FloatArray:
        return np.asarray(np.tile(self.mus, (n, 1)), dtype=np.float64)

    def nodes(self, poses: FloatArray, min_limbs: int) -> tuple[RoadmapNodes, BoolArray]:
        """Nodes for the root poses (n, 4, 4) that are valid: trunk free, at least
        ``min_limbs`` contacts, no force closure. Returns (the valid nodes, (n,) validity)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        valid = ~self.collider(p)
        rows = np.flatnonzero(valid)
        est = self.contacts(p[rows])
        axes, mu_c, closure = centroidal_cones(est.normals, est.mus, est.active)
        ok = (est.active.sum(axis=1) >= min_limbs) & ~closure
        valid[rows[~ok]] = False
        keep = np.flatnonzero(ok)
        quats = (
            np.array([matrix_to_quaternion(m[:3, :3]) for m in p[rows[keep]]])
            if len(keep)
            else np.zeros((0, 4))
        )
        arrays = {k: v[keep] for k, v in est.as_arrays().items()}
        nodes = RoadmapNodes(
            positions=p[rows[keep], :3, 3].reshape(-1, 3),
            orientations=quats.reshape(-1, 4),
            cone_axes=axes[keep].reshape(-1, 3),
            mus=mu_c[keep],
            contacts=arrays,
        )
        return nodes, valid

    def place(
        self, points: FloatArray, normals: FloatArray, yaw: FloatArray, limb: IntArray
    ) -> FloatArray:
        """Root poses (n, 4, 4) with the up axis along ``normals`` (n, 3) (world z when the
        normal is steeper than 45 degrees), turned by ``yaw`` (n,) rad about it, placed so that
        the reference contact of limb ``limb`` (n,) lands on ``points`` (n, 3)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        out = np.zeros((len(pts), 4, 4))
        out[:, 3, 3] = 1.0
        c, s = np.cos(yaw), np.sin(yaw)
        for i in range(len(pts)):
            turn = np.array([[c[i], -s[i], 0.0], [s[i], c[i], 0.0], [0.0, 0.0, 1.0]])
            if np.sqrt(0.5) < nrm[i, 2] < 1.0 - 1e-12:
                rot = rotation_between(np.array([0.0, 0.0, 1.0]), nrm[i]) @ turn
            else:
                rot = turn
            out[i, :3, :3] = rot
            out[i, :3, 3] = pts[i] - rot @ self.reference_points[limb[i]]
        return out


# --------------------------------------------------------------------------------------------
# Sampling


@dataclass(frozen=True, slots=True, eq=False)
class SceneSampler:
    """``roadmap.NodeSampler`` on a real scene.

    Surface points are drawn per surface with weight 0.5 area / total + 0.5 / count (half
    area-weighted, half uniform over surfaces, as the authors' shooter does, so small platforms
    are not starved by a large ground), then uniformly on the surface's triangles (area-
    weighted). Yaw ~ U[-pi, pi]. The root is placed so that a random stance limb's reference
    contact lands on the point; a colliding trunk is pushed out along the normal (``lifts``).
    ``oversample`` candidates are drawn per wanted node and the first valid ones kept.
    """

    model: ReducedModel
    min_limbs: int
    oversample: int = 6
    lifts: tuple[float, ...] = (0.03, 0.08, 0.15)

    def sample(self, n: int, *, rng: np.random.Generator) -> RoadmapNodes:
        """Up to n valid nodes; deterministic given rng."""
        model = self.model
        m = max(1, n * self.oversample)
        surfaces = [s for s in model.surfaces if s.kind is SurfaceKind.SUPPORT] or list(
            model.surfaces
        )
        area = np.array([s.area for s in surfaces])
        weight = 0.5 * area / area.sum() + 0.5 / len(surfaces)
        which = rng.choice(len(surfaces), size=m, p=weight / weight.sum())
        points = np.zeros((m, 3))
        normals = np.zeros((m, 3))
        for s_idx in np.unique(which):
            rows = np.flatnonzero(which == s_idx)
            points[rows] = _triangle_points(surfaces[s_idx].triangle_vertices, len(rows), rng)
            normals[rows] = surfaces[s_idx].normal
        yaw = rng.uniform(-np.pi, np.pi, size=m)
        limb = model.stance[rng.integers(0, len(model.stance), size=m)]
        poses = model.place(points, normals, yaw, limb)
        hit = model.collider(poses)
        for lift in self.lifts:
            rows = np.flatnonzero(hit)
            if len(rows) == 0:
                break
            moved = poses[rows].copy()
            moved[:, :3, 3] += lift * normals[rows]
            free = ~model.collider(moved)
            poses[rows[free]] = moved[free]
            hit[rows[free]] = False
        candidates = poses[~hit]
        found: list[RoadmapNodes] = []
        have = 0
        start, batch = 0, max(n, 16)
        while start < len(candidates) and have < n:
            got, _ = model.nodes(candidates[start : start + batch], self.min_limbs)
            found.append(got)
            have += len(got)
            start += batch
            # size the next batch from the acceptance seen so far (+10 %), not a full batch
            rate = max(have / start, 0.05)
            batch = max(8, int(np.ceil(1.1 * (n - have) / rate)))
        if not found:
            return model.nodes(np.zeros((0, 4, 4)), self.min_limbs)[0]
        out = found[0]
        for part in found[1:]:
            out = out.concat(part)
        return out.take(slice(0, n)) if len(out) > n else out


def _triangle_points(triangles: FloatArray, n: int, rng: np.random.Generator) -> FloatArray:
    """n uniform points on (t, 3, 3) triangles, area-weighted."""
    tri = np.asarray(triangles, dtype=np.float64)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    pick = rng.choice(len(tri), size=n, p=area / area.sum())
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    a, b, c = tri[pick, 0], tri[pick, 1], tri[pick, 2]
    return np.asarray(
        (1 - r1)[:, None] * a + (r1 * (1 - r2))[:, None] * b + (r1 * r2)[:, None] * c,
        dtype=np.float64,
    )


__all__ = [
    "NodeContacts",
    "ReducedModel",
    "SceneSampler",
    "TrunkCollider",
    "poses_from_quaternions",
    "reduced_hull",
]
