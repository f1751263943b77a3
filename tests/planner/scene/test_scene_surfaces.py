"""Affordance surfaces: thresholds, areas, per-tread surfaces, polygons and determinism."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from planner.scene import (
    AffordanceParams,
    Scene,
    SceneError,
    SurfaceKind,
    build_scene,
    builtin_scene_ids,
    load_builtin_scene,
)
from planner.scene import builtin as b
from planner.scene.affordance import _triangle_geometry

COS_41 = np.cos(np.deg2rad(41.0))


def _all_scenes(builtin_scenes: dict[str, Scene], hpp_scenes: dict[str, Scene]) -> list[Scene]:
    return [*builtin_scenes.values(), *hpp_scenes.values()]


def test_builtin_ids() -> None:
    assert builtin_scene_ids() == (
        "flat",
        "stairs",
        "chair",
        "climbing_wall",
        "twister",
        "rubble",
        "gaps",
        "pen",
    )
    with pytest.raises(SceneError, match="unknown built-in scene"):
        load_builtin_scene("moon")


def test_support_normals_within_41_degrees(builtin_scenes, hpp_scenes) -> None:
    for scene in _all_scenes(builtin_scenes, hpp_scenes):
        _, _, valid = _triangle_geometry(scene.vertices, scene.faces)
        face_normals = scene.mesh.face_normals
        for surface in scene.surfaces:
            if surface.kind is SurfaceKind.SUPPORT:
                assert surface.normal[2] >= COS_41, (scene.id, surface.id)
                tri_normals = face_normals[surface.triangles]
                assert np.all(tri_normals[:, 2] >= COS_41 - 1e-9), (scene.id, surface.id)
            else:
                assert abs(surface.normal[2]) < 0.1 + 1e-9
        assert np.all(valid[scene.face_surface >= 0])


def test_areas_add_up_to_qualifying_triangles(builtin_scenes, hpp_scenes) -> None:
    for scene in _all_scenes(builtin_scenes, hpp_scenes):
        _, areas, _ = _triangle_geometry(scene.vertices, scene.faces)
        qualifying = scene.face_surface >= 0
        total = sum(surface.area for surface in scene.surfaces)
        assert total == pytest.approx(float(np.sum(areas[qualifying])), rel=1e-12)
        # Each face belongs to at most one surface, and the surface lists agree with the map.
        ids = np.concatenate([s.triangles for s in scene.surfaces]) if scene.surfaces else []
        assert len(ids) == len(set(ids)) == int(np.count_nonzero(qualifying))
        for surface in scene.surfaces:
            assert np.all(scene.face_surface[surface.triangles] == surface.id)
            assert surface.area > (
                scene.params.support_min_area
                if surface.kind is SurfaceKind.SUPPORT
                else scene.params.lean_min_area
            )


def test_polygon_area_matches_planar_surface_area(builtin_scenes, hpp_scenes) -> None:
    from planner.scene.geometry2d import signed_area

    for scene in _all_scenes(builtin_scenes, hpp_scenes):
        for surface in scene.surfaces:
            if surface.flatness > 1e-9:
                continue
            polygon_area = sum(signed_area(p) for p in surface.polygons_2d())
            assert polygon_area == pytest.approx(surface.area, rel=1e-6, abs=1e-9)


def test_triangle_centroids_project_inside_their_surface(builtin_scenes, hpp_scenes) -> None:
    for scene in _all_scenes(builtin_scenes, hpp_scenes):
        for surface in scene.surfaces:
            if surface.flatness > 1e-6:
                continue
            centroids = surface.triangle_vertices.mean(axis=1)
            assert np.all(surface.contains_projection(centroids)), (scene.id, surface.id)
            far = surface.centroid + 1e3 * surface.basis[0]
            assert not surface.contains_projection(far[None])[0]


def test_stairs_one_surface_per_tread(builtin_scenes) -> None:
    scene = builtin_scenes["stairs"]
    horizontal = [
        s
        for s in scene.surfaces_of(SurfaceKind.SUPPORT)
        if s.normal[2] > 1 - 1e-9 and abs(s.centroid[1]) < 1e-9
    ]
    for step in range(1, b.STAIRS_STEPS + 1):
        height = step * b.STAIRS_RISE
        at_height = [s for s in horizontal if abs(s.centroid[2] - height) < 1e-9]
        assert len(at_height) == 1, height
        depth = b.STAIRS_LANDING if step == b.STAIRS_STEPS else b.STAIRS_TREAD
        assert at_height[0].area == pytest.approx(depth * b.STAIRS_WIDTH)
        assert len(at_height[0].polygons) == 1 and len(at_height[0].polygons[0]) == 4
    ground = [s for s in horizontal if abs(s.centroid[2]) < 1e-9]
    assert len(ground) == 1
    # The handrail gives a sloped Support surface and Lean sides.
    assert any(0.8 < s.normal[2] < 0.95 for s in scene.surfaces_of(SurfaceKind.SUPPORT))


def test_builtin_scene_contents(builtin_scenes) -> None:
    twister = builtin_scenes["twister"]
    discs = [
        s
        for s in twister.surfaces_of(SurfaceKind.SUPPORT)
        if abs(s.centroid[2] - b.TWISTER_HEIGHT) < 1e-9
    ]
    assert len(discs) == len(b.twister_centers())
    centres = np.array(sorted(tuple(np.round(s.centroid[:2], 9)) for s in discs))
    assert np.allclose(centres, np.array(sorted(map(tuple, b.twister_centers()))), atol=1e-9)
    for disc in discs:
        assert disc.area == pytest.approx(np.pi * b.TWISTER_RADIUS**2, rel=0.02)

    gaps = builtin_scenes["gaps"]
    tops = sorted(
        (s for s in gaps.surfaces_of(SurfaceKind.SUPPORT) if s.centroid[2] > 0.1),
        key=lambda s: s.centroid[0],
    )
    assert [round(s.centroid[2], 9) for s in tops] == list(b.GAPS_HEIGHTS)

    chair = builtin_scenes["chair"]
    heights = sorted(round(s.centroid[2], 3) for s in chair.surfaces_of(SurfaceKind.SUPPORT))
    assert 0.45 in heights and 0.75 in heights

    wall = builtin_scenes["climbing_wall"]
    supports = wall.surfaces_of(SurfaceKind.SUPPORT)
    half_lane = b.CLIMB_LANE / 2.0
    lane = [s for s in supports if s.centroid[2] > 0.1 and abs(s.centroid[1]) < half_lane]
    towers = [s for s in supports if abs(s.centroid[1]) > half_lane]
    assert len(lane) == 2 * (b.CLIMB_ROWS - 1) + 1  # two foot holds a row, then the ledge
    assert len(towers) == 2 * b.CLIMB_ROWS
    for row in range(b.CLIMB_ROWS - 1):
        x = b.CLIMB_START_X + (row + 0.5) * b.CLIMB_DEPTH
        here = sorted(s.centroid[2] for s in lane if abs(s.centroid[0] - x) < 1e-6)
        assert here[1] - here[0] == pytest.approx(b.CLIMB_JITTER)  # the feet never level
        assert here[0] == pytest.approx(b.CLIMB_RISE * (row + 1))
        hands = [s.centroid[2] for s in towers if abs(s.centroid[0] - x) < 1e-6]
        assert hands == pytest.approx([here[0] + b.CLIMB_HOLD_HEIGHT] * 2)
    ledge = max(lane, key=lambda s: s.centroid[2])
    assert ledge.centroid[2] == pytest.approx(b.CLIMB_ROWS * b.CLIMB_RISE)
    assert wall.surfaces_of(SurfaceKind.LEAN)  # the risers and the towers' sides

    rubble = builtin_scenes["rubble"]
    tilted = [s for s in rubble.surfaces_of(SurfaceKind.SUPPORT) if s.normal[2] < 0.99]
    assert len(tilted) >= 6

    flat = builtin_scenes["flat"]
    assert len(flat.surfaces) == 1 and flat.surfaces[0].area == pytest.approx(100.0)


def test_hpp_scenes_give_sensible_surfaces(hpp_scenes) -> None:
    assert len(hpp_scenes) >= 5
    for name, scene in hpp_scenes.items():
        supports = scene.surfaces_of(SurfaceKind.SUPPORT)
        assert supports, name
        largest = max(supports, key=lambda s: s.area)
        assert largest.area > 1.0 and largest.normal[2] > 0.99, name
        assert all(len(s.polygons) >= 1 for s in scene.surfaces), name
    bauzil = hpp_scenes["bauzil_stairs"]
    tread_heights = {
        round(float(s.centroid[2]), 2)
        for s in bauzil.surfaces_of(SurfaceKind.SUPPORT)
        if s.normal[2] > 0.999 and s.area > 0.2
    }
    assert len(tread_heights) >= 5


def test_surfaces_are_deterministic(hpp_scenes) -> None:
    for make in (b.stairs_mesh, b.rubble_mesh):
        first, second = build_scene(make()), build_scene(make())
        _assert_same_surfaces(first, second)
    mesh = hpp_scenes["darpa"].mesh
    _assert_same_surfaces(build_scene(mesh), build_scene(mesh.copy()))


def _assert_same_surfaces(first: Scene, second: Scene) -> None:
    assert first.id == second.id
    assert len(first.surfaces) == len(second.surfaces)
    assert np.array_equal(first.face_surface, second.face_surface)
    for s1, s2 in zip(first.surfaces, second.surfaces, strict=True):
        assert (s1.id, s1.kind, s1.area) == (s2.id, s2.kind, s2.area)
        assert np.array_equal(s1.triangles, s2.triangles)
        assert all(np.array_equal(p1, p2) for p1, p2 in zip(s1.polygons, s2.polygons, strict=True))


def test_square_with_hole_keeps_the_hole() -> None:
    # A 3 x 3 grid of unit squares without the centre one.
    vertices, faces = [], []
    for i in range(3):
        for j in range(3):
            if i == j == 1:
                continue
            base = len(vertices)
            vertices += [[i, j, 0], [i + 1, j, 0], [i + 1, j + 1, 0], [i, j + 1, 0]]
            faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    mesh = trimesh.Trimesh(np.array(vertices, float), np.array(faces), process=False)
    mesh.merge_vertices()
    scene = build_scene(mesh)
    (surface,) = scene.surfaces
    assert surface.area == pytest.approx(8.0)
    from planner.scene.geometry2d import signed_area

    areas = sorted(signed_area(p) for p in surface.polygons_2d())
    assert areas == pytest.approx([-1.0, 9.0])
    inside = surface.contains_projection(
        np.array([[0.5, 0.5, 1.0], [1.5, 1.5, 0.0], [2.5, 1.5, -1.0]])
    )
    assert inside.tolist() == [True, False, True]
    assert surface.contains_projection(np.array([[0.5, 0.5, 0.0]]), margin=0.6).tolist() == [False]
    snapped = surface.closest_point(np.array([[1.5, 1.4, 2.0], [4.0, 0.5, 0.0], [0.5, 0.5, 3.0]]))
    assert np.allclose(snapped, [[1.5, 1.0, 0.0], [3.0, 0.5, 0.0], [0.5, 0.5, 0.0]])


def test_region_growing_respects_neighbour_margin() -> None:
    # Two squares sharing an edge, one tilted by 20 degrees: separate surfaces by default,
    # one surface when the neighbour margin allows 20 degrees.
    angle = np.deg2rad(20.0)
    far = 1 + np.cos(angle)
    vertices = np.array(
        [
            [0, 0, 0],
            [1, 0, 0],
            [1, 1, 0],
            [0, 1, 0],
            [far, 0, np.sin(angle)],
            [far, 1, np.sin(angle)],
        ]
    )
    faces = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert len(build_scene(mesh).surfaces) == 2
    loose = AffordanceParams(support_neighbour_margin=0.2)
    assert len(build_scene(mesh, params=loose).surfaces) == 1
    strict = AffordanceParams(support_min_area=1.5)
    assert len(build_scene(mesh, params=strict).surfaces) == 0


def test_params_are_validated() -> None:
    with pytest.raises(SceneError) as info:
        AffordanceParams(support_margin=-1.0)
    assert info.value.field == "support_margin"


def test_vertical_wall_is_lean_and_curved_surface_lifts_onto_mesh() -> None:
    wall = trimesh.Trimesh(
        np.array([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1.0]]),
        np.array([[0, 2, 1], [0, 3, 2]]),
        process=False,
    )
    (surface,) = build_scene(wall).surfaces
    assert surface.kind is SurfaceKind.LEAN
    assert np.allclose(np.abs(surface.normal), [1, 0, 0])
    # A gently folded floor (5 degrees): one region, not flat; points lift onto the mesh.
    fold = np.deg2rad(5.0)
    vertices = np.array(
        [
            [0, 0, 0],
            [1, 0, 0],
            [1, 1, 0],
            [0, 1, 0],
            [1 + np.cos(fold), 0, np.sin(fold)],
            [1 + np.cos(fold), 1, np.sin(fold)],
        ]
    )
    faces = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    (floor,) = build_scene(trimesh.Trimesh(vertices, faces, process=False)).surfaces
    assert floor.flatness > 1e-3
    x = 1 + 0.5 * np.cos(fold)  # above the tilted half
    lifted = floor.closest_point(np.array([[0.5, 0.5, 1.0], [x, 0.5, 1.0]]))
    assert lifted[0, 2] == pytest.approx(0.0, abs=1e-12)
    assert lifted[1, 0] > 1.0
    assert lifted[1, 2] == pytest.approx((lifted[1, 0] - 1.0) * np.tan(fold), abs=1e-12)


def test_pinch_vertex_and_high_degree_fan() -> None:
    from planner.scene.geometry2d import signed_area

    # Two triangles touching at one vertex (a bow tie): one region, two outer loops.
    vertices = np.array([[0, 0, 0], [1, -0.5, 0], [1, 0.5, 0], [-1, 0.5, 0], [-1, -0.5, 0.0]])
    mesh = trimesh.Trimesh(vertices, np.array([[0, 1, 2], [0, 3, 4]]), process=False)
    (surface,) = build_scene(mesh).surfaces
    assert len(surface.polygons) == 2
    assert [signed_area(p) for p in surface.polygons_2d()] == pytest.approx([0.5, 0.5])
    # A 200-triangle fan: the centre exceeds max_vertex_degree, edges still join the region.
    angles = np.linspace(0.0, 2.0 * np.pi, 201)[:-1]
    ring = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(200)])
    fan = trimesh.Trimesh(
        np.vstack([[0.0, 0.0, 0.0], ring]),
        np.array([[0, 1 + i, 1 + (i + 1) % 200] for i in range(200)]),
        process=False,
    )
    (disc,) = build_scene(fan, params=AffordanceParams(max_vertex_degree=8)).surfaces
    assert len(disc.triangles) == 200 and len(disc.polygons) == 1
    assert disc.area == pytest.approx(100 * np.sin(2 * np.pi / 200))
