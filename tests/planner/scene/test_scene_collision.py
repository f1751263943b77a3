"""Collision world: agreement with an exact box-triangle test, caching, distances, obstacles."""

from __future__ import annotations

import coal
import numpy as np
import pytest
import trimesh

from planner.poses import normalize_quaternion, pose_matrix, poses_from, quaternion_to_matrix
from planner.scene import CollisionWorld, Scene, build_scene
from planner.scene.builtin import stairs_mesh
from planner.scene.collision import bvh_cache_bytes, bvh_cache_path
from planner.shapes import Box, Capsule, ConvexPolytope

TOUCH_TOLERANCE = 1e-6


def sat_box_triangles(
    half: np.ndarray, pose: np.ndarray, triangles: np.ndarray
) -> tuple[bool, float]:
    """Exact separating-axis test of a box (half extents, (4, 4) pose) against (t, 3, 3)
    triangles. Returns (overlaps, margin): margin is the smallest penetration over all axes
    when overlapping, minus the largest separation otherwise (near 0: touching)."""
    # Broad phase: only triangles whose bounding box comes within 1 mm of the box's.
    reach = np.abs(pose[:3, :3]) @ half + 1e-3
    lo, hi = triangles.min(axis=1), triangles.max(axis=1)
    near = np.all((lo <= pose[:3, 3] + reach) & (hi >= pose[:3, 3] - reach), axis=1)
    if not np.any(near):
        return False, 1e-3
    triangles = triangles[near]
    local = (triangles - pose[:3, 3]) @ pose[:3, :3]  # (t, 3, 3) in the box frame
    edges = np.stack(
        [local[:, 1] - local[:, 0], local[:, 2] - local[:, 1], local[:, 0] - local[:, 2]], axis=1
    )  # (t, 3, 3)
    normal = np.cross(edges[:, 0], edges[:, 1])[:, None, :]
    box_axes = np.broadcast_to(np.eye(3), (len(local), 3, 3))
    crosses = np.cross(np.eye(3)[None, :, None, :], edges[:, None, :, :]).reshape(len(local), 9, 3)
    axes = np.concatenate([box_axes, normal, crosses], axis=1)  # (t, 13, 3)
    length = np.linalg.norm(axes, axis=2)
    usable = length > 1e-12
    axes = axes / np.where(usable, length, 1.0)[..., None]
    projection = np.einsum("tak,tvk->tav", axes, local)
    radius = np.abs(axes) @ half
    gap = np.maximum(projection.min(axis=2) - radius, -radius - projection.max(axis=2))
    gap = np.where(usable, gap, -np.inf)
    separation = gap.max(axis=1)  # > 0: separated along some axis
    overlapping = separation <= 0.0
    if np.any(overlapping):
        return True, float(-separation[overlapping].max())
    return False, float(-separation.min())


def random_boxes(rng: np.random.Generator, bounds: np.ndarray, count: int):
    lo, hi = bounds[0] - 0.3, bounds[1] + 0.3
    centres = rng.uniform(lo, hi, size=(count, 3))
    rotations = quaternion_to_matrix(normalize_quaternion(rng.normal(size=(count, 4))))
    halves = rng.uniform(0.02, 0.4, size=(count, 3))
    return poses_from(centres, rotations), halves


def _check_agreement(scene: Scene, seed: int, count: int) -> None:
    rng = np.random.default_rng(seed)
    poses, halves = random_boxes(rng, scene.bounds, count)
    triangles = scene.vertices[scene.faces]
    agree = collide_count = skipped = 0
    for pose, half in zip(poses, halves, strict=True):
        box = Box(half_extents=half)
        expected, margin = sat_box_triangles(half, pose, triangles)
        if abs(margin) < TOUCH_TOLERANCE:
            skipped += 1
            continue
        got = scene.collision.collides(box, pose)
        assert got == expected, (pose, half, margin)
        agree += 1
        collide_count += expected
    assert agree >= 0.99 * count
    assert 0.1 * agree < collide_count < 0.9 * agree  # both outcomes well represented
    batched = scene.collision.collides_many(Box(half_extents=halves[0]), poses[:200])
    single = [scene.collision.collides(Box(half_extents=halves[0]), p) for p in poses[:200]]
    assert batched.tolist() == single


def test_collision_agrees_with_exact_test_on_stairs(builtin_scenes) -> None:
    _check_agreement(builtin_scenes["stairs"], seed=1, count=3000)


def test_collision_agrees_with_exact_test_on_hpp_scene(hpp_scenes) -> None:
    _check_agreement(hpp_scenes["bauzil_stairs"], seed=2, count=3000)


def test_sat_oracle_sanity() -> None:
    triangle = np.array([[[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]]])
    half = np.array([0.1, 0.1, 0.1])
    for z, expected in [(0.05, True), (0.15, False), (-0.09, True), (-0.2, False)]:
        pose = np.eye(4)
        pose[2, 3] = z
        assert sat_box_triangles(half, pose, triangle)[0] is expected


def test_distance_is_signed(builtin_scenes) -> None:
    world = builtin_scenes["flat"].collision
    box = Box(half_extents=[0.1, 0.1, 0.1])
    heights = np.array([0.3, 0.15, 0.05])
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, 2, 3] = heights
    distances = world.distance_many(box, poses)
    assert distances == pytest.approx([0.2, 0.05, -0.05], abs=1e-6)
    assert world.distance(box, poses[0]) == pytest.approx(0.2, abs=1e-6)


def test_shape_offsets_and_other_shapes(builtin_scenes) -> None:
    world = builtin_scenes["flat"].collision
    lifted = np.eye(4)
    lifted[2, 3] = 1.0
    offset_down = np.eye(4)
    offset_down[2, 3] = -0.95
    assert world.collides(Box(half_extents=[0.1, 0.1, 0.1], offset=offset_down), lifted)
    assert not world.collides(Box(half_extents=[0.1, 0.1, 0.1]), lifted)
    capsule = Capsule(radius=0.1, half_length=0.5)
    assert world.collides(capsule, lifted @ offset_down) is True
    assert not world.collides(capsule, lifted)  # bottom sphere at 0.4
    hull = ConvexPolytope.from_points(np.random.default_rng(0).uniform(-0.2, 0.2, (30, 3)))
    assert not world.collides(hull, lifted)
    assert world.collides(hull, np.eye(4) + _z(0.1))


def _z(height: float) -> np.ndarray:
    out = np.zeros((4, 4))
    out[2, 3] = height
    return out


def test_obstacles_extend_a_world_without_touching_it(builtin_scenes) -> None:
    world = builtin_scenes["flat"].collision
    other = Box(half_extents=[0.3, 0.3, 0.9])
    other_pose = np.eye(4)
    other_pose[:3, 3] = [2.0, 0.0, 0.9]
    crowded = world.with_obstacles([(other, other_pose)])
    probe = Box(half_extents=[0.2, 0.2, 0.2])
    pose = np.eye(4)
    pose[:3, 3] = [2.4, 0.0, 1.0]
    assert crowded.collides(probe, pose)
    assert not world.collides(probe, pose)
    assert crowded.obstacle_count == 1 and world.obstacle_count == 0
    assert crowded.bvh is world.bvh
    pose[:3, 3] = [2.8, 0.0, 1.0]
    assert crowded.distance(probe, pose) == pytest.approx(0.3, abs=1e-6)


def test_bvh_cache_round_trip(tmp_path) -> None:
    mesh = stairs_mesh()
    first = build_scene(mesh, cache_dir=tmp_path)
    path = bvh_cache_path(tmp_path, first.content_hash)
    assert not first.collision.from_cache and path.is_file()
    stamp = path.stat().st_mtime_ns
    second = build_scene(mesh, cache_dir=tmp_path)
    assert second.collision.from_cache
    assert path.stat().st_mtime_ns == stamp
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary files left
    rng = np.random.default_rng(5)
    poses, _ = random_boxes(rng, first.bounds, 500)
    box = Box(half_extents=[0.15, 0.1, 0.2])
    assert np.array_equal(
        first.collision.collides_many(box, poses), second.collision.collides_many(box, poses)
    )
    assert np.array_equal(
        first.collision.distance_many(box, poses[:100]),
        second.collision.distance_many(box, poses[:100]),
    )
    # A damaged cache file is rebuilt, not trusted.
    path.write_bytes(b"not a bvh")
    third = build_scene(mesh, cache_dir=tmp_path)
    assert not third.collision.from_cache
    assert np.array_equal(
        third.collision.collides_many(box, poses), first.collision.collides_many(box, poses)
    )
    assert path.stat().st_size > 100


def test_the_cached_bvh_size_is_foreseen_from_the_counts(tmp_path) -> None:
    """The uploads' quota refuses a scene by its BVH's size before building it: the estimate
    from the triangle and vertex counts must be the cached file's size, give or take a few
    hundred bytes, from a tetrahedron to a mesh of thousands of triangles."""
    meshes = [trimesh.creation.icosphere(subdivisions=k) for k in range(4)]
    meshes += [stairs_mesh(), trimesh.creation.box(extents=(1.0, 2.0, 3.0))]
    for mesh in meshes:
        scene = build_scene(mesh, cache_dir=tmp_path)
        real = bvh_cache_path(tmp_path, scene.content_hash).stat().st_size
        foreseen = bvh_cache_bytes(len(scene.faces), len(scene.vertices))
        assert abs(foreseen - real) <= 512, (len(scene.faces), foreseen, real)


def test_scene_id_is_a_content_hash() -> None:
    mesh = stairs_mesh()
    a, b = build_scene(mesh), build_scene(mesh.copy())
    assert a.id == b.id == a.content_hash and len(a.id) == 32
    moved = mesh.copy()
    moved.vertices = moved.vertices + np.array([0.0, 0.0, 1e-9])
    assert build_scene(moved).id != a.id
    assert build_scene(mesh, scene_id="mine", name="n").id == "mine"


def test_colliding_triangles(builtin_scenes) -> None:
    scene = builtin_scenes["stairs"]
    pose = np.eye(4)
    pose[:3, 3] = [1.15, 0.0, 0.15]
    ids = scene.collision.colliding_triangles(Box(half_extents=[0.05, 0.05, 0.05]), pose)
    assert len(ids) > 0
    tread = scene.face_surface[ids]
    assert any(scene.surfaces[s].centroid[2] == pytest.approx(0.15) for s in tread if s >= 0)


def test_world_without_scene_mesh_is_usable() -> None:
    from planner.scene.collision import build_bvh

    mesh = trimesh.creation.box((1.0, 1.0, 1.0))
    world = CollisionWorld(build_bvh(np.asarray(mesh.vertices), np.asarray(mesh.faces)))
    assert world.triangle_count == 12
    assert world.collides(Box(half_extents=[0.2, 0.2, 0.2]), np.eye(4) + _z(0.5))


def test_queries_from_several_threads_agree(builtin_scenes) -> None:
    from concurrent.futures import ThreadPoolExecutor

    scene = builtin_scenes["rubble"]
    poses, _ = random_boxes(np.random.default_rng(9), scene.bounds, 400)
    box = Box(half_extents=[0.2, 0.15, 0.3])
    expected = scene.collision.collides_many(box, poses)
    chunks = np.array_split(poses, 8)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda chunk: scene.collision.collides_many(box, chunk), chunks))
    assert np.array_equal(np.concatenate(results), expected)


def test_push_direction_points_out_of_what_is_touched(builtin_scenes) -> None:
    box = coal.Box(0.2, 0.2, 0.2)
    stairs = builtin_scenes["stairs"].collision
    # sunk 1 cm into the ground: up; 5 cm into the first riser (x = 1): back
    for centre, expected in (((0.0, 0.0, 0.09), (0, 0, 1)), ((0.95, 0.0, 0.05), (-1, 0, 0))):
        push = stairs.push_direction(box, pose_matrix(np.array(centre)))
        assert push is not None
        np.testing.assert_allclose(push, expected, atol=1e-6)
    assert stairs.push_direction(box, pose_matrix(np.array([0.0, 0.0, 0.5]))) is None
