"""Affordance surfaces: region growing over mesh triangles into Support and Lean surfaces.

A triangle is Support when its unit normal n satisfies ||z - n||^2 < support_margin (41
degrees of vertical by default; the reference's 0.5 is 41.4) and Lean when |n . z| <
lean_margin (near vertical); Support wins.
Two triangles of the same kind are neighbours when they share a vertex and their normals differ
by ||n_i - n_j||^2 < the kind's neighbour margin; regions are the connected components of that
graph (hpp-affordance's flood fill, but linear in the number of vertex-face incidences), kept
when their area exceeds the kind's minimum area.

Surface polygons are the boundary loops of a region's triangles, projected along the surface
normal and lifted back onto the mesh: outer boundaries counter-clockwise about the normal,
holes clockwise (holes are kept, so a floor with a pit has a hole where the pit is).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planner.scene import geometry2d as g2
from planner.scene.errors import SceneError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_UP = np.array([0.0, 0.0, 1.0])

SUPPORT_MARGIN_41_DEG = 2.0 * (1.0 - float(np.cos(np.deg2rad(41.0))))
"""||z - n||^2 bound of exactly 41 degrees (0.4906); the reference's 0.5 is 41.4 degrees."""
_CHUNK = 4096


class SurfaceKind(enum.Enum):
    """What a surface affords: standing on it (SUPPORT) or pushing against it (LEAN)."""

    SUPPORT = "support"
    LEAN = "lean"


@dataclass(frozen=True, slots=True)
class AffordanceParams:
    """Thresholds of the region growing (defaults: the reference scenarios' Support values,
    with the slope bound tightened from 41.4 to exactly 41 degrees; Lean: within ~6 degrees of
    vertical, 10 degrees between neighbours, at least 0.01 m^2 (a hand)).

    *_margin : classification threshold (Support: ||z - n||^2 < m; Lean: |n . z| < m).
    *_neighbour_margin : neighbours join when ||n_i - n_j||^2 < this.
    *_min_area : regions of at most this area (m^2) are dropped.
    max_vertex_degree : vertices shared by more faces than this join them only through shared
        edges (bounds the pair count on pathological fans).
    """

    support_margin: float = SUPPORT_MARGIN_41_DEG
    support_neighbour_margin: float = 0.03
    support_min_area: float = 5e-5
    lean_margin: float = 0.1
    lean_neighbour_margin: float = 0.03
    lean_min_area: float = 0.01
    max_vertex_degree: int = 64

    def __post_init__(self) -> None:
        checks = {
            "support_margin": 0.0 < self.support_margin <= 2.0,
            "support_neighbour_margin": 0.0 <= self.support_neighbour_margin <= 4.0,
            "support_min_area": self.support_min_area >= 0.0,
            "lean_margin": 0.0 <= self.lean_margin <= 1.0,
            "lean_neighbour_margin": 0.0 <= self.lean_neighbour_margin <= 4.0,
            "lean_min_area": self.lean_min_area >= 0.0,
            "max_vertex_degree": self.max_vertex_degree >= 2,
        }
        for name, ok in checks.items():
            if not ok:
                raise SceneError(f"{name} out of range: {getattr(self, name)!r}", name)


def _readonly(array: object) -> FloatArray:
    out = np.array(array, dtype=np.float64)
    out.flags.writeable = False
    return out


def _readonly_int(array: object) -> IntArray:
    out = np.array(array, dtype=np.int64)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True, eq=False)
class Surface:
    """One affordance surface of a scene, world frame, metres.

    id : index in ``Scene.surfaces``. kind : SUPPORT or LEAN.
    polygons : (k, 3) loops on the mesh; outer boundaries counter-clockwise about ``normal``,
        holes clockwise. normal : (3,) unit, area-weighted mean of the triangle normals.
    area : m^2, sum of the triangle areas. triangles : (t,) face ids in the scene mesh.
    centroid : (3,) area centroid of the triangles. basis : (3, 3) rows u, v, normal (plane
        coordinates are (x - centroid) . u, . v). flatness : largest distance (m) of a
        triangle vertex from the plane through ``centroid``. triangle_vertices : (t, 3, 3).
        polygons_uv : the polygons in plane coordinates, (k, 2) each.
    """

    id: int
    kind: SurfaceKind
    polygons: tuple[FloatArray, ...]
    normal: FloatArray
    area: float
    triangles: IntArray
    centroid: FloatArray
    basis: FloatArray
    flatness: float
    triangle_vertices: FloatArray = field(repr=False)
    polygons_uv: tuple[FloatArray, ...] = field(repr=False)

    def to_plane(self, points: FloatArray) -> FloatArray:
        """(p, 2) plane coordinates of (p, 3) world points projected along the normal."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.asarray((pts - self.centroid) @ self.basis[:2].T, dtype=np.float64)

    def from_plane(self, coords: FloatArray) -> FloatArray:
        """(p, 3) world points on the surface plane for (p, 2) plane coordinates."""
        c = np.asarray(coords, dtype=np.float64).reshape(-1, 2)
        return np.asarray(self.centroid + c @ self.basis[:2], dtype=np.float64)

    def polygons_2d(self) -> list[FloatArray]:
        """The polygons in plane coordinates, (k, 2) each."""
        return list(self.polygons_uv)

    def height(self, points: FloatArray) -> FloatArray:
        """(p,) signed distance (m) of (p, 3) points above the surface plane."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.asarray((pts - self.centroid) @ self.normal, dtype=np.float64)

    def contains_projection(self, points: FloatArray, margin: float = 0.0) -> BoolArray:
        """(p,) mask: the (p, 3) points projected along the normal fall inside the surface.

        margin : metres; if positive, points closer than this to the boundary are outside.
        """
        coords = self.to_plane(points)
        inside = _winding_numbers(self, coords) != 0
        if margin > 0.0 and np.any(inside):
            distance, _, _ = self._boundary_distance(coords[inside])
            inside[np.flatnonzero(inside)[distance < margin]] = False
        return np.asarray(inside, dtype=np.bool_)

    def closest_point(self, points: FloatArray) -> FloatArray:
        """(p, 3) points of the surface nearest to (p, 3) points, in the plane-projection sense.

        A point whose projection falls inside is dropped along the normal onto the triangle
        below it; other points go to the nearest boundary point.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        coords = self.to_plane(pts)
        inside = _winding_numbers(self, coords) != 0
        out = np.zeros_like(pts)
        if np.any(inside):
            out[inside] = self._lift(coords[inside])
        outside = ~inside
        if np.any(outside):
            _, segment, t = self._boundary_distance(coords[outside])
            starts, ends = self._segments_3d()
            out[outside] = starts[segment] + t[:, None] * (ends[segment] - starts[segment])
        return out

    def nearest_boundary(self, coords: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Distances (p,) from (p, 2) plane coordinates to the boundary (outer loops and
        holes), and the nearest boundary points (p, 2) in plane coordinates."""
        c = np.asarray(coords, dtype=np.float64).reshape(-1, 2)
        distance, segment, t = self._boundary_distance(c)
        _, _, starts_uv, ends_uv = _boundary_segments(self)
        a, b = starts_uv[segment], ends_uv[segment]
        return distance, a + t[:, None] * (b - a)

    def _segments_3d(self) -> tuple[FloatArray, FloatArray]:
        starts, ends, _, _ = _boundary_segments(self)
        return starts, ends

    def _boundary_distance(
        self, coords: FloatArray
    ) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
        _, _, starts_uv, ends_uv = _boundary_segments(self)
        return g2.closest_on_segments(coords, starts_uv, ends_uv)

    def _lift(self, coords: FloatArray) -> FloatArray:
        """Points on the mesh above/below (q, 2) plane coordinates lying inside the surface."""
        on_plane = self.from_plane(coords)
        if self.flatness <= 1e-9:
            return on_plane
        tri = self.triangle_vertices
        tri2 = np.stack([self.to_plane(tri[:, k]) for k in range(3)], axis=1)  # (t, 3, 2)
        result = on_plane.copy()
        for begin in range(0, len(coords), max(1, _CHUNK * 16 // max(1, len(tri)))):
            block = coords[begin : begin + max(1, _CHUNK * 16 // max(1, len(tri)))]
            a, b, c = tri2[None, :, 0], tri2[None, :, 1], tri2[None, :, 2]
            p = block[:, None, :]
            v0, v1, v2 = b - a, c - a, p - a
            den = v0[..., 0] * v1[..., 1] - v1[..., 0] * v0[..., 1]
            den = np.where(np.abs(den) > 1e-300, den, 1e-300)
            wb = (v2[..., 0] * v1[..., 1] - v1[..., 0] * v2[..., 1]) / den
            wc = (v0[..., 0] * v2[..., 1] - v2[..., 0] * v0[..., 1]) / den
            wa = 1.0 - wb - wc
            score = np.minimum(np.minimum(wa, wb), wc)  # >= 0 inside
            best = np.argmax(score, axis=1)
            rows = np.arange(len(block))
            w = np.stack([wa[rows, best], wb[rows, best], wc[rows, best]], axis=1)
            result[begin : begin + len(block)] = np.einsum("qk,qkj->qj", w, tri[best])
        return result


_SEGMENTS: dict[int, tuple[Surface, tuple[FloatArray, FloatArray, FloatArray, FloatArray]]] = {}


def _boundary_segments(
    surface: Surface,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The boundary segments of ``surface``'s polygons: starts and ends (s, 3) in the world
    and the same (s, 2) in plane coordinates; computed once per surface (read-only), as
    contact placement asks for them again and again."""
    hit = _SEGMENTS.get(id(surface))
    if hit is not None and hit[0] is surface:
        return hit[1]
    starts = np.concatenate(surface.polygons)
    ends = np.concatenate([np.roll(p, -1, axis=0) for p in surface.polygons])
    out = (starts, ends, surface.to_plane(starts), surface.to_plane(ends))
    for array in out:
        array.flags.writeable = False
    if len(_SEGMENTS) > 4096:
        _SEGMENTS.clear()
    _SEGMENTS[id(surface)] = (surface, out)
    return out


_LoopEdges = tuple[FloatArray, FloatArray, tuple[g2.Edge, ...]]
_LOOP_EDGES: dict[int, tuple[Surface, _LoopEdges | None]] = {}
_SCALAR_EDGES = 64  # up to this many edges, one point's winding number in scalar arithmetic


def _winding_numbers(surface: Surface, coords: FloatArray) -> NDArray[np.int64]:
    """:func:`geometry2d.winding_numbers` of (p, 2) plane coordinates about ``surface``'s
    polygons, their edges made once per surface (read-only)."""
    hit = _LOOP_EDGES.get(id(surface))
    if hit is None or hit[0] is not surface:
        loops = surface.polygons_2d()
        edges: _LoopEdges | None = None
        if loops:
            a, b = g2.loop_edges(loops)
            a.flags.writeable = b.flags.writeable = False
            edges = (a, b, g2.edge_tuples(a, b))
        if len(_LOOP_EDGES) > 4096:
            _LOOP_EDGES.clear()
        hit = (surface, edges)
        _LOOP_EDGES[id(surface)] = hit
    points = np.asarray(coords, dtype=np.float64).reshape(-1, 2)
    if hit[1] is None:
        return np.zeros(len(points), dtype=np.int64)
    a, b, scalar = hit[1]
    if len(points) == 1 and len(scalar) <= _SCALAR_EDGES:  # most queries: one contact point
        x, y = points[0].tolist()
        return np.array([g2.point_winding_number(x, y, scalar)], dtype=np.int64)
    return g2.edge_winding_numbers(points, a, b)


def _triangle_geometry(
    vertices: FloatArray, faces: IntArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Unit normals (m, 3), areas (m,) and a validity mask (non-degenerate) per face."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    scale = np.max(np.abs(vertices)) if len(vertices) else 1.0
    valid = double_area > 1e-14 * max(scale, 1.0) ** 2
    normals = np.zeros_like(cross)
    normals[valid] = cross[valid] / double_area[valid, None]
    return normals, 0.5 * double_area, valid


def classify_faces(normals: FloatArray, valid: BoolArray, params: AffordanceParams) -> IntArray:
    """(m,) kind code per face: 0 Support, 1 Lean, -1 neither (or degenerate)."""
    support = valid & (np.sum((normals - _UP) ** 2, axis=1) < params.support_margin)
    lean = valid & ~support & (np.abs(normals[:, 2]) < params.lean_margin)
    kind: IntArray = np.full(len(normals), -1, dtype=np.int64)
    kind[support] = 0
    kind[lean] = 1
    return kind


def _sharing_pairs(keys: IntArray, owners: IntArray, max_group: int) -> tuple[IntArray, IntArray]:
    """All owner pairs that share a key, for key groups of at most ``max_group`` members."""
    order = np.lexsort((owners, keys))
    k, o = keys[order], owners[order]
    _, sizes = np.unique(k, return_counts=True)
    small = np.repeat(sizes <= max_group, sizes)
    firsts: list[IntArray] = []
    seconds: list[IntArray] = []
    largest = int(sizes[sizes <= max_group].max()) if np.any(sizes <= max_group) else 1
    for step in range(1, largest):
        same = (k[:-step] == k[step:]) & small[:-step]
        firsts.append(o[:-step][same])
        seconds.append(o[step:][same])
    if not firsts:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(firsts), np.concatenate(seconds)


def face_pairs(
    faces: IntArray, candidates: IntArray, max_vertex_degree: int
) -> tuple[IntArray, IntArray]:
    """Pairs of candidate faces sharing a vertex (vertices up to the degree bound) or an edge."""
    sub = faces[candidates]
    owners = np.repeat(candidates, 3)
    first_v, second_v = _sharing_pairs(sub.ravel(), owners, max_vertex_degree)
    edges = np.sort(np.stack([sub, sub[:, [1, 2, 0]]], axis=2), axis=2).reshape(-1, 2)
    size = int(faces.max()) + 1
    edge_keys = edges[:, 0] * size + edges[:, 1]
    first_e, second_e = _sharing_pairs(edge_keys, owners, 16)
    return np.concatenate([first_v, first_e]), np.concatenate([second_v, second_e])


def extract_surfaces(
    vertices: FloatArray, faces: IntArray, params: AffordanceParams
) -> tuple[tuple[Surface, ...], IntArray]:
    """Affordance surfaces of a mesh and the (m,) surface id per face (-1: none).

    vertices : (n, 3) float64, world frame, metres; faces : (m, 3) int64.
    Surfaces are ordered Support first, then Lean, each by their smallest face id.
    """
    normals, areas, valid = _triangle_geometry(vertices, faces)
    kind = classify_faces(normals, valid, params)
    face_surface = np.full(len(faces), -1, dtype=np.int64)
    candidates = np.flatnonzero(kind >= 0).astype(np.int64)
    if len(candidates) == 0:
        return (), face_surface
    first, second = face_pairs(faces, candidates, params.max_vertex_degree)
    neighbour = np.array([params.support_neighbour_margin, params.lean_neighbour_margin])
    same = kind[first] == kind[second]
    first, second = first[same], second[same]
    close = np.sum((normals[first] - normals[second]) ** 2, axis=1) < neighbour[kind[first]]
    first, second = first[close], second[close]
    m = len(faces)
    graph = coo_matrix((np.ones(len(first), dtype=np.int8), (first, second)), shape=(m, m))
    _, labels = connected_components(graph, directed=False)
    cand_labels = labels[candidates]
    region_area = np.bincount(cand_labels, weights=areas[candidates], minlength=labels.max() + 1)
    min_area = np.array([params.support_min_area, params.lean_min_area])
    # Representative (smallest face id) of each region, for a deterministic order.
    rep = np.full(labels.max() + 1, m, dtype=np.int64)
    np.minimum.at(rep, cand_labels, candidates)
    uniq = np.unique(cand_labels)
    uniq = uniq[region_area[uniq] > min_area[kind[rep[uniq]]]]
    kept = uniq[np.lexsort((rep[uniq], kind[rep[uniq]]))]
    if len(kept) == 0:
        return (), face_surface
    # Per-region aggregates, vectorised: area, mean normal, centroid, plane frame, flatness.
    index_of = np.full(labels.max() + 1, -1, dtype=np.int64)
    index_of[kept] = np.arange(len(kept))
    region_of = index_of[cand_labels]
    in_kept = region_of >= 0
    members_all, region_of = candidates[in_kept], region_of[in_kept]
    count = len(kept)
    weight = areas[members_all]
    tri = vertices[faces[members_all]]
    area_r = np.bincount(region_of, weights=weight, minlength=count)
    normal_r = np.asarray(
        np.stack(
            [
                np.bincount(region_of, weights=normals[members_all, k] * weight, minlength=count)
                for k in range(3)
            ],
            axis=1,
        ),
        dtype=np.float64,
    )
    centre_r = np.stack(
        [
            np.bincount(region_of, weights=tri[:, :, k].mean(axis=1) * weight, minlength=count)
            for k in range(3)
        ],
        axis=1,
    )
    length = np.linalg.norm(normal_r, axis=1)
    usable = (length > 0.0) & (area_r > 0.0)
    normal_r[usable] /= length[usable, None]
    centre_r[usable] /= area_r[usable, None]
    basis_r = _plane_bases(normal_r)
    offsets = np.abs(
        np.einsum("fkj,fj->fk", tri - centre_r[region_of][:, None, :], normal_r[region_of])
    ).max(axis=1)
    flat_r = np.zeros(count)
    np.maximum.at(flat_r, region_of, offsets)
    order = np.argsort(region_of, kind="stable")
    bounds = np.searchsorted(region_of[order], np.arange(count + 1)).tolist()
    surfaces: list[Surface] = []
    for r in range(count):
        if not usable[r]:
            continue
        members = np.sort(members_all[order[bounds[r] : bounds[r + 1]]])
        surface = _make_surface(
            len(surfaces),
            int(kind[rep[kept[r]]]),
            vertices,
            faces,
            members,
            float(area_r[r]),
            normal_r[r],
            centre_r[r],
            basis_r[r],
            float(flat_r[r]),
        )
        face_surface[members] = surface.id
        surfaces.append(surface)
    return tuple(surfaces), face_surface


def _plane_bases(normals: FloatArray) -> FloatArray:
    """(r, 3, 3) frames (rows u, v, n, u x v = n) for (r, 3) unit normals (as plane_basis)."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(helper, normals)
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    v = np.cross(normals, u)
    return np.asarray(np.stack([u, v, normals], axis=1), dtype=np.float64)


def _make_surface(
    surface_id: int,
    code: int,
    vertices: FloatArray,
    faces: IntArray,
    members: IntArray,
    area: float,
    normal: FloatArray,
    centroid: FloatArray,
    basis: FloatArray,
    flatness: float,
) -> Surface:
    region_faces = faces[members]
    tri = vertices[region_faces]
    used, local = np.unique(region_faces, return_inverse=True)
    local = local.reshape(-1, 3)
    points = vertices[used]
    coords = (points - centroid) @ basis[:2].T
    polygons: list[FloatArray] = []
    polygons_uv: list[FloatArray] = []
    loop_areas: list[float] = []
    for loop in g2.boundary_loops(local, coords):
        keep = g2.simplify_loop(coords[loop])
        loop_kept = loop[keep]
        loop_area = g2.signed_area(coords[loop_kept])
        if abs(loop_area) <= 1e-12 * max(area, 1e-12):
            continue
        polygons.append(_readonly(points[loop_kept]))
        polygons_uv.append(_readonly(coords[loop_kept]))
        loop_areas.append(loop_area)
    # Outer boundaries (largest first) before holes, for readability; loops keep their order.
    order = np.argsort([-area for area in loop_areas], kind="stable")
    polygons = [polygons[i] for i in order]
    polygons_uv = [polygons_uv[i] for i in order]
    return Surface(
        id=surface_id,
        kind=SurfaceKind.SUPPORT if code == 0 else SurfaceKind.LEAN,
        polygons=tuple(polygons),
        normal=_readonly(normal),
        area=area,
        triangles=_readonly_int(members),
        centroid=_readonly(centroid),
        basis=_readonly(basis),
        flatness=flatness,
        triangle_vertices=_readonly(tri),
        polygons_uv=tuple(polygons_uv),
    )
