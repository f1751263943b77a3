"""Reachability condition and root sampler: validity, batching, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from planner.contact.reachability import ReachabilityChecker, ground_limbs
from planner.contact.root_sampler import OrientationBounds, euler_matrices, sample_root_poses
from planner.poses import pose_matrix, poses_from
from planner.scene import SurfaceKind
from planner.shapes import Box
from tests.planner.contact.contact_helpers import (
    character_and_data,
    checker,
    scene,
    standing_pose,
)


@pytest.mark.parametrize(
    ("character_id", "scene_id", "xyz"),
    [
        ("humanoid", "flat", (0.0, 0.0, 0.0)),
        ("humanoid", "stairs", (1.45, 0.0, 0.3)),
        ("humanoid", "stairs", (3.1, 0.0, 0.9)),
        ("quadruped", "rubble", (-1.0, 0.0, 0.0)),
        ("hexapod", "twister", (0.5, 0.5, 0.0)),
    ],
)
def test_standing_poses_are_valid(
    character_id: str, scene_id: str, xyz: tuple[float, float, float]
) -> None:
    check = checker(character_id, scene_id)
    for yaw in (0.0, 1.0, -2.5):
        assert check.is_valid(standing_pose(character_id, xyz, yaw))


@pytest.mark.parametrize("x", [2.3, 2.6, 3.0, 3.5, 3.9])  # trunk in the blocks or the ledge
def test_trunk_through_the_wall_is_invalid(x: float) -> None:
    check = checker("humanoid", "climbing_wall")
    pose = standing_pose("humanoid", (x, 0.0, 0.0))
    assert not check.trunk_free(pose[None])[0]
    assert not check.is_valid(pose)


def test_flying_and_buried_poses_are_invalid() -> None:
    check = checker("humanoid", "flat")
    flying = standing_pose("humanoid", (0.0, 0.0, 2.0))
    touching = check.limbs_touching(flying[None])
    assert touching.shape == (1, 6)  # every limb, the two on-request sit bones included
    assert not touching.any()
    assert not check.is_valid(flying)
    buried = standing_pose("humanoid", (0.0, 0.0, -0.95))  # trunk through the floor
    assert not check.trunk_free(buried[None])[0]
    assert not check.is_valid(standing_pose("humanoid", (40.0, 0.0, 0.0)))  # out of bounds


@pytest.mark.parametrize(
    ("character_id", "scene_id"), [("humanoid", "stairs"), ("quadruped", "rubble")]
)
def test_batched_equals_one_by_one(character_id: str, scene_id: str) -> None:
    check = checker(character_id, scene_id)
    rng = np.random.default_rng(7)
    n = 150
    positions = rng.uniform([-1.0, -1.0, 0.0], [3.5, 1.0, 2.0], size=(n, 3))
    rotations = euler_matrices(
        rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n)
    )
    poses = poses_from(positions, rotations)
    batched = check.valid(poses)
    assert 0 < batched.sum() < n  # the sample mixes valid and invalid poses
    single = np.array([check.is_valid(p) for p in poses])
    np.testing.assert_array_equal(batched, single)
    trunk = check.trunk_free(poses)
    np.testing.assert_array_equal(trunk, [check.trunk_free(p[None])[0] for p in poses])
    touching = check.limbs_touching(poses)
    required = [check.limb_names.index(name) for name in check.required_limbs]
    expected = trunk & touching[:, required].all(axis=1) & check.in_bounds(poses)
    np.testing.assert_array_equal(batched, expected)


def test_defaults_and_options() -> None:
    character, data = character_and_data("humanoid")
    assert ground_limbs(character) == ("left_foot", "right_foot")
    check = checker("humanoid", "flat")
    assert check.required_limbs == ("left_foot", "right_foot")
    assert check.allowed_kinds["left_foot"] == frozenset({SurfaceKind.SUPPORT})
    assert check.allowed_kinds["left_hand"] == frozenset({SurfaceKind.SUPPORT, SurfaceKind.LEAN})
    assert ground_limbs(character_and_data("hexapod")[0]) == (
        "l1_foot",
        "l2_foot",
        "l3_foot",
        "r1_foot",
        "r2_foot",
        "r3_foot",
    )
    pose = standing_pose("humanoid", (0.0, 0.0, 0.0))
    # hands cannot reach the floor while standing: requiring them fails
    with_hands = ReachabilityChecker(
        scene("flat"), character, data, required_limbs=("left_foot", "left_hand")
    )
    assert not with_hands.is_valid(pose)
    # feet restricted to Lean surfaces: nothing to stand on in a flat scene
    lean_only = ReachabilityChecker(
        scene("flat"), character, data, allowed_kinds={"left_foot": [SurfaceKind.LEAN]}
    )
    assert not lean_only.is_valid(pose)
    # an obstacle around the trunk
    blocked = ReachabilityChecker(
        scene("flat"),
        character,
        data,
        obstacles=[(Box([0.3, 0.3, 0.3]), pose_matrix([0.0, 0.0, 1.2]))],
    )
    assert check.is_valid(pose)
    assert not blocked.is_valid(pose)
    with pytest.raises(ValueError, match="no limb"):
        ReachabilityChecker(scene("flat"), character, data, required_limbs=("tail",))


@pytest.mark.parametrize(
    ("character_id", "scene_id"),
    [("humanoid", "stairs"), ("quadruped", "rubble"), ("hexapod", "flat")],
)
def test_sampler_returns_valid_poses_deterministically(character_id: str, scene_id: str) -> None:
    check = checker(character_id, scene_id)
    poses = sample_root_poses(check, 40, rng=np.random.default_rng(3))
    assert poses.shape == (40, 4, 4)
    assert check.valid(poses).all()
    again = sample_root_poses(check, 40, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(poses, again)
    other = sample_root_poses(check, 40, rng=np.random.default_rng(4))
    assert not np.array_equal(poses, other)
    rotations = poses[:, :3, :3]
    np.testing.assert_allclose(
        rotations @ rotations.transpose(0, 2, 1),
        np.broadcast_to(np.eye(3), rotations.shape),
        atol=1e-12,
    )


def test_sampler_orientation_bounds_and_near() -> None:
    check = checker("humanoid", "stairs")
    bounds = OrientationBounds(yaw=(0.2, 0.4), pitch=(0.0, 0.0), roll=(0.0, 0.0))
    poses = sample_root_poses(check, 30, rng=np.random.default_rng(5), orientation_bounds=bounds)
    assert len(poses) == 30
    yaw = np.arctan2(poses[:, 1, 0], poses[:, 0, 0])
    assert np.all((yaw >= 0.2 - 1e-9) & (yaw <= 0.4 + 1e-9))
    np.testing.assert_allclose(poses[:, 2, :3], np.tile([0.0, 0.0, 1.0], (30, 1)), atol=1e-12)
    near = np.array([1.45, 0.0, 0.3])
    close = sample_root_poses(check, 20, rng=np.random.default_rng(6), near=near, near_radius=0.4)
    assert len(close) == 20
    assert check.valid(close).all()
    reach = max(float(np.linalg.norm(v[:2])) for v in check.offsets.values())
    assert np.all(np.linalg.norm(close[:, :2, 3] - near[:2], axis=1) <= 0.4 + reach + 1e-9)
    assert sample_root_poses(check, 0, rng=np.random.default_rng(0)).shape == (0, 4, 4)


@pytest.mark.parametrize("n", [10, 4096, 4097, 20000])
def test_support_indices_equal_argmax(n: int) -> None:
    """The chunked support points are argmax's over the whole product, ties included."""
    from planner.contact.reachability import _fibonacci_sphere, support_indices

    rng = np.random.default_rng(n)
    directions = _fibonacci_sphere(96)
    sphere = rng.normal(size=(n, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    # exact ties across and within chunks: the first of equal vertices is the support
    tied = np.concatenate([sphere, sphere[::-1], np.round(sphere, 1)])
    for vertices in (sphere, tied):
        expected = np.argmax(vertices @ directions.T, axis=0)
        assert np.array_equal(support_indices(vertices, directions), expected)


def test_simplified_workspace_cached_by_content() -> None:
    """A workspace loaded again (another object, the same arrays) gets the same
    simplification, cold cache or warm, in any order."""
    from planner.contact import reachability
    from planner.shapes import ConvexPolytope

    rng = np.random.default_rng(3)
    points = rng.normal(size=(6000, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    first = ConvexPolytope.from_points(points)
    again = ConvexPolytope(first.vertices.copy(), first.A.copy(), first.b.copy())
    other = ConvexPolytope.from_points(0.5 * points)
    cold = reachability._simplify(first, 96)
    reachability._SIMPLIFIED.clear()
    reachability._SIMPLIFIED_BY_CONTENT.clear()
    for workspace in (first, other, again, first):
        got = reachability.simplified_workspace(workspace, 96)
        want = cold if workspace is not other else reachability._simplify(other, 96)
        assert np.array_equal(got.vertices, want.vertices)
        assert np.array_equal(got.A, want.A) and np.array_equal(got.b, want.b)
    assert reachability.simplified_workspace(again, 96) is reachability.simplified_workspace(
        first, 96
    )
