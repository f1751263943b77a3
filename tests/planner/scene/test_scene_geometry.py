"""Contact regions and planar polygon kernels (hypothesis property tests)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from planner.poses import pose_matrix, yaw_matrix
from planner.scene import ContactRegion, SurfaceKind, build_scene, contact_region
from planner.scene import builtin as b
from planner.scene import geometry2d as g2
from planner.scene import scene as scene_module
from planner.shapes import Box, ConvexPolytope

coordinate = st.floats(-5.0, 5.0, allow_nan=False, allow_infinity=False)
point_sets = st.lists(st.tuples(coordinate, coordinate), min_size=3, max_size=12)


def _convex_polygon(points: list[tuple[float, float]]) -> np.ndarray | None:
    p = np.asarray(points, dtype=np.float64)
    try:
        hull = ConvexHull(p)
    except Exception:
        return None
    if hull.volume < 1e-3:
        return None
    return p[hull.vertices]  # counter-clockwise in 2D


@given(point_sets)
def test_signed_area_and_centroid_match_qhull(points) -> None:
    polygon = _convex_polygon(points)
    if polygon is None:
        return
    hull = ConvexHull(polygon)
    assert g2.signed_area(polygon) == pytest.approx(hull.volume, rel=1e-9)
    assert g2.signed_area(polygon[::-1]) == pytest.approx(-hull.volume, rel=1e-9)
    # Centroid of a fan triangulation.
    tri = np.stack([np.repeat(polygon[:1], len(polygon) - 2, 0), polygon[1:-1], polygon[2:]], 1)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    areas = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    expected = (tri.mean(axis=1) * areas[:, None]).sum(0) / areas.sum()
    assert np.allclose(g2.polygon_centroid(polygon), expected, atol=1e-9)


@given(point_sets, st.floats(-np.pi, np.pi), st.floats(-3.0, 3.0))
def test_clipping_splits_area(points, angle, offset) -> None:
    polygon = _convex_polygon(points)
    if polygon is None:
        return
    a = np.array([[np.cos(angle), np.sin(angle)]])
    inside = g2.clip_halfplanes(polygon, a, np.array([offset]))
    outside = g2.clip_halfplanes(polygon, -a, np.array([-offset]))
    total = g2.signed_area(inside) + g2.signed_area(outside)
    assert total == pytest.approx(g2.signed_area(polygon), rel=1e-9, abs=1e-9)
    if len(inside):
        assert np.all(inside @ a[0] <= offset + 1e-9)


@given(point_sets, st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=30))
def test_winding_agrees_with_convex_halfspaces(points, queries) -> None:
    polygon = _convex_polygon(points)
    if polygon is None:
        return
    q = np.asarray(queries, dtype=np.float64)
    equations = ConvexHull(polygon).equations
    signed = q @ equations[:, :2].T + equations[:, 2]
    clear = np.all(signed < -1e-9, axis=1) | np.any(signed > 1e-9, axis=1)
    expected = np.all(signed < 0, axis=1)
    got = g2.winding_numbers(q, [polygon]) != 0
    assert np.array_equal(got[clear], expected[clear])
    reverse = g2.winding_numbers(q, [polygon[::-1]])
    assert np.array_equal(reverse[clear], -expected[clear].astype(np.int64))


@given(
    st.lists(point_sets, min_size=1, max_size=3),
    st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=20),
)
def test_one_points_winding_number_in_scalar_arithmetic_is_the_arrays(loops, queries) -> None:
    """point_winding_number of a point equals edge_winding_numbers' for it, about any loops
    (not convex, crossing, holes), at any point, a vertex or an edge's midpoint included."""
    polygons = [np.asarray(loop, dtype=np.float64) for loop in loops]
    a, b = g2.loop_edges(polygons)
    edges = g2.edge_tuples(a, b)
    points = np.vstack([np.asarray(queries, dtype=np.float64), a, 0.5 * (a + b)])
    expected = g2.edge_winding_numbers(points, a, b)
    for (x, y), want in zip(points.tolist(), expected.tolist(), strict=True):
        assert g2.point_winding_number(x, y, edges) == want


@given(
    st.lists(st.tuples(coordinate, coordinate, coordinate, coordinate), min_size=1, max_size=40),
    st.tuples(coordinate, coordinate),
)
def test_one_points_nearest_segment_in_scalar_arithmetic_is_the_arrays(segments, query) -> None:
    """closest_on_segments of one 2D point (its scalar path) answers, bit for bit, what the
    array path answers for it among other points: distance, segment and parameter, at any
    point, a segment's end or middle included, degenerate segments too."""
    ends4 = np.asarray(segments, dtype=np.float64)
    starts, ends = ends4[:, :2], ends4[:, 2:]
    ends[0] = starts[0]  # one segment of zero length
    for point in (np.asarray(query, dtype=np.float64), starts[-1], 0.5 * (starts[-1] + ends[-1])):
        one = g2.closest_on_segments(point[None], starts, ends)
        many = g2.closest_on_segments(np.vstack([point, point + 1.0]), starts, ends)
        for got, want in zip(one, many, strict=True):
            assert got.tolist() == want[:1].tolist()


def _oracle_area(polygon: np.ndarray, a2: np.ndarray, b2: np.ndarray) -> float:
    """Area of (convex polygon) & {a2 x <= b2} by scipy's half-space intersection."""
    eq = ConvexHull(polygon).equations  # n.x + d <= 0
    halfspaces = np.vstack([eq, np.column_stack([a2, -b2])])
    norms = np.linalg.norm(halfspaces[:, :2], axis=1)
    result = linprog(
        c=[0, 0, -1],
        A_ub=np.column_stack([halfspaces[:, :2], norms]),
        b_ub=-halfspaces[:, 2],
        bounds=[(None, None), (None, None), (0, 1)],
    )
    if result.status != 0 or result.x[2] < 1e-7:
        return 0.0
    vertices = HalfspaceIntersection(halfspaces, result.x[:2]).intersections
    return float(ConvexHull(vertices).volume)


@given(
    point_sets,
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-np.pi, np.pi),
    st.floats(0.1, 1.5),
    st.floats(0.1, 1.5),
    st.floats(-0.3, 0.3),
)
def test_contact_region_area_matches_halfspace_oracle(points, x, y, yaw, hx, hy, height) -> None:
    polygon = _convex_polygon(points)
    if polygon is None:
        return
    # A one-surface scene: the polygon fan-triangulated at z = 0.5.
    vertices = np.column_stack([polygon, np.full(len(polygon), 0.5)])
    faces = np.array([[0, i, i + 1] for i in range(1, len(polygon) - 1)])
    scene = build_scene(trimesh.Trimesh(vertices, faces, process=False))
    (surface,) = scene.surfaces
    box = Box(half_extents=[hx, hy, 0.4])
    pose = pose_matrix(np.array([x, y, 0.5 + height]), yaw_matrix(np.array(yaw)))
    region = scene.collision.contact_region(box, pose, surface)
    expected = _oracle_area(polygon, *_box_section(box, pose))
    if region is None:
        assert expected == pytest.approx(0.0, abs=1e-6)
        return
    assert region.area == pytest.approx(expected, rel=1e-6, abs=1e-9)
    assert np.allclose(region.polygon[:, 2], 0.5)
    assert g2.signed_area(region.polygon[:, :2]) == pytest.approx(region.area, rel=1e-9)
    assert surface.contains_projection(region.centroid[None])[0] or region.area < 1e-6


def _box_section(box: Box, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-planes of the box's section by z = 0.5 (the box is upright: z-faces are parallel)."""
    rotation, centre = pose[:3, :3], pose[:3, 3]
    if abs(centre[2] - 0.5) > box.half_extents[2]:
        return np.array([[0.0, 0.0]]), np.array([-1.0])
    axes = rotation[:2, :2].T  # rows: box x and y axes in the plane
    a2 = np.vstack([axes, -axes])
    b2 = np.concatenate(
        [box.half_extents[:2] + axes @ centre[:2], box.half_extents[:2] - axes @ centre[:2]]
    )
    return a2, b2


def test_box_across_a_tread_gives_the_overlap_rectangle(builtin_scenes) -> None:
    scene = builtin_scenes["stairs"]
    step = 2
    height = step * b.STAIRS_RISE
    tread = next(
        s
        for s in scene.surfaces_of(SurfaceKind.SUPPORT)
        if abs(s.centroid[2] - height) < 1e-9 and abs(s.centroid[1]) < 1e-9
    )
    x_front = b.STAIRS_START_X + (step - 1) * b.STAIRS_TREAD
    box = Box(half_extents=[0.2, 0.2, 0.1])
    pose = pose_matrix(np.array([x_front + 0.1, 0.45, height + 0.02]))
    region = scene.collision.contact_region(box, pose, tread)
    assert isinstance(region, ContactRegion)
    polygon, centroid = region
    expected = {
        (round(x_front, 9), 0.25),
        (round(x_front + 0.3, 9), 0.25),
        (round(x_front + 0.3, 9), 0.5),
        (round(x_front, 9), 0.5),
    }
    assert {(round(px, 9), round(py, 9)) for px, py, _ in polygon} == expected
    assert np.allclose(polygon[:, 2], height)
    assert g2.signed_area(polygon[:, :2]) == pytest.approx(0.3 * 0.25)  # counter-clockwise
    assert np.allclose(centroid, [x_front + 0.15, 0.375, height])
    assert region.area == pytest.approx(0.075)
    # Too high above the tread, or beside the stairs: no region.
    pose[2, 3] = height + 0.2
    assert scene.collision.contact_region(box, pose, tread) is None
    assert contact_region(box, pose_matrix(np.array([x_front, 1.2, height])), tread) is None


def test_contact_region_of_a_rotated_polytope_on_the_ground(builtin_scenes) -> None:
    scene = builtin_scenes["flat"]
    (ground,) = scene.surfaces
    octahedron = ConvexPolytope.from_points(
        np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    )
    region = scene.collision.contact_region(
        octahedron, pose_matrix(np.array([1.0, 2.0, 0.5])), ground
    )
    assert region is not None
    # Section of |x| + |y| + |z| <= 1 at z = -0.5 (local): a diamond of half-diagonal 0.5.
    assert region.area == pytest.approx(0.5)
    assert np.allclose(region.centroid, [1.0, 2.0, 0.0])
    with pytest.raises(TypeError):
        contact_region(object(), np.eye(4), ground)  # type: ignore[arg-type]


def _translation(x: float, y: float, z: float) -> np.ndarray:
    return pose_matrix(np.array([x, y, z]))


_BOX_SCENE = build_scene(
    trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=(4.0, 4.0, 0.02), transform=_translation(0, 0, -0.01)),
            trimesh.creation.box(extents=(1.0, 0.6, 0.4), transform=_translation(0.3, -0.2, 0.2)),
        ]
    )
)


@settings(max_examples=80, deadline=None)
@given(
    x=st.floats(-1.0, 1.5),
    y=st.floats(-1.0, 1.0),
    z=st.floats(0.001, 0.8),
)
def test_inside_solid_matches_the_box(x: float, y: float, z: float) -> None:
    """Inside the block (x 0.3 +- 0.5, y -0.2 +- 0.3, z 0 to 0.4) is inside a solid; the
    ground slab's top and everything beside or above the block is not."""
    margin = 1e-3
    inside = abs(x - 0.3) < 0.5 - margin and abs(y + 0.2) < 0.3 - margin and z < 0.4 - margin
    outside = abs(x - 0.3) > 0.5 + margin or abs(y + 0.2) > 0.3 + margin or z > 0.4 + margin
    got = _BOX_SCENE.inside_solid(np.array([x, y, z]))
    if inside:
        assert got
    elif outside:
        assert not got


@settings(max_examples=80, deadline=None)
@given(
    x=st.floats(-1.9, 1.9),
    y=st.floats(-1.9, 1.9),
    z=st.floats(0.41, 2.0),
)
def test_height_below_is_the_top_underneath(x: float, y: float, z: float) -> None:
    """Above the block (top 0.4) the ground under a point is the block's top; beside it,
    the slab's top (0); beyond the slab, nothing."""
    margin = 1e-3
    on_block = abs(x - 0.3) < 0.5 - margin and abs(y + 0.2) < 0.3 - margin
    beside = abs(x - 0.3) > 0.5 + margin or abs(y + 0.2) > 0.3 + margin
    got = _BOX_SCENE.height_below(np.array([x, y, z]))
    if on_block:
        assert got == pytest.approx(0.4, abs=1e-9)
    elif beside:
        assert got == pytest.approx(0.0, abs=1e-9)
    assert _BOX_SCENE.height_below(np.array([x + 10.0, y, z])) is None
    assert _BOX_SCENE.height_below(np.array([x, y, -0.5])) is None  # under the slab


@settings(max_examples=30, deadline=None)
@given(
    name=st.sampled_from(["stairs", "rubble", "climbing_wall", "flat"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_heights_below_at_once_are_those_of_each_point(
    builtin_scenes, name: str, seed: int
) -> None:
    """heights_below answers for many points exactly what height_below does point by point
    (nan where it says None): over the scene, beside it, under it and above it, whether the
    points go in one block or in blocks of three."""
    scene = builtin_scenes[name]
    rng = np.random.default_rng(seed)
    low, high = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
    points = rng.uniform(low - 0.3, high + 0.5, (40, 3))
    at_once = scene.heights_below(points)
    for point, got in zip(points, at_once, strict=True):
        one = scene.height_below(point)
        assert (one is None and np.isnan(got)) or one == got
    with pytest.MonkeyPatch.context() as patch:  # in blocks of a point or a few
        patch.setattr(scene_module, "_HEIGHTS_BLOCK", 3 * len(scene.faces))
        np.testing.assert_array_equal(scene.heights_below(points), at_once)
    assert scene.heights_below(np.zeros((0, 3))).shape == (0,)
