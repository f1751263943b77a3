"""Reduced model on real scenes: trunk collision, contact estimate, node sampling, end points."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from planner.ballistic.nodes import ReducedModel, SceneSampler, TrunkCollider, reduced_hull
from planner.ballistic.planner import JumpParams, plan_jumps
from planner.character import Character, get_character
from planner.offline import OfflineData, load_offline_data
from planner.result import PlanStatus
from planner.scene import Scene, SurfaceKind, load_builtin_scene
from tests.paths import gecko_cache_dir


@cache
def _setup(character_id: str) -> tuple[Scene, Character, OfflineData]:
    character = get_character(character_id)
    return (
        load_builtin_scene("gaps", gecko_cache_dir()),
        character,
        load_offline_data(character, gecko_cache_dir()),
    )


def _standing(character: Character, x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = [x, y, z + character.q_ref[2]]
    return pose


def test_reduced_hull_is_inside_the_workspace() -> None:
    _, character, data = _setup("quadruped")
    full = data.limb(character.limbs[0].name).workspace
    small = reduced_hull(full)
    assert 8 <= len(small.vertices) <= 64
    assert full.contains(small.vertices, tolerance=1e-9).all()


def test_trunk_collider_inflation() -> None:
    scene, character, _ = _setup("quadruped")
    trunk = character.trunk[0]
    low = float(trunk.half_extents[2])  # type: ignore[union-attr]
    pose = np.eye(4)
    pose[:3, 3] = [-1.0, 0.0, low + 0.03]  # 3 cm above the ground, away from the platforms
    assert not TrunkCollider.of(scene, character, 0.0)(pose[None])[0]
    assert TrunkCollider.of(scene, character, 0.05)(pose[None])[0]


def test_contact_estimate_standing_on_the_ground() -> None:
    scene, character, data = _setup("quadruped")
    model = ReducedModel.build(scene, character, data)
    est = model.contacts(_standing(character, -1.5, 0.0, 0.0)[None])
    assert est.active.all()
    assert np.allclose(est.points[0, :, 2], 0.0, atol=1e-9)
    assert np.allclose(est.normals[0], [0.0, 0.0, 1.0])
    ground = max(scene.surfaces_of(SurfaceKind.SUPPORT), key=lambda s: s.area)
    assert (est.surfaces[0] == ground.id).all()
    nodes, valid = model.nodes(_standing(character, -1.5, 0.0, 0.0)[None], 4)
    assert valid.all() and len(nodes) == 1
    assert np.allclose(nodes.cone_axes[0], [0.0, 0.0, 1.0])
    assert nodes.mus[0] == pytest.approx(min(limb.mu for limb in character.limbs))
    # Floating 2 m up: no workspace meets a surface.
    high = _standing(character, -1.5, 0.0, 2.0)[None]
    assert not model.contacts(high).active.any()
    assert not model.nodes(high, 1)[1].any()


@pytest.mark.parametrize("character_id", ["humanoid", "quadruped", "hexapod"])
def test_sampler_is_seeded_and_valid(character_id: str) -> None:
    scene, character, data = _setup(character_id)
    model = ReducedModel.build(scene, character, data)
    sampler = SceneSampler(model, 2)
    a = sampler.sample(40, rng=np.random.default_rng(5))
    b = sampler.sample(40, rng=np.random.default_rng(5))
    assert len(a) == 40
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.contacts["points"], b.contacts["points"])
    poses = np.tile(np.eye(4), (len(a), 1, 1))
    from planner.poses import quaternion_to_matrix

    poses[:, :3, :3] = quaternion_to_matrix(a.orientations)
    poses[:, :3, 3] = a.positions
    assert not model.collider(poses).any()
    assert (a.contacts["active"].sum(axis=1) >= 2).all()
    assert np.allclose(np.linalg.norm(a.cone_axes, axis=1), 1.0)


def test_invalid_end_points() -> None:
    scene, character, data = _setup("hexapod")
    params = JumpParams(n_nodes=20)
    far = np.array([50.0, 50.0, 0.0])  # no surface within reach
    on_ground = np.array([-1.0, 0.0, 0.0])
    result = plan_jumps(
        scene, character, data, far, on_ground, rng=np.random.default_rng(0), params=params
    )
    assert result.status is PlanStatus.INVALID_START
    result = plan_jumps(
        scene, character, data, on_ground, far, rng=np.random.default_rng(0), params=params
    )
    assert result.status is PlanStatus.INVALID_GOAL
    with pytest.raises(ValueError):
        plan_jumps(
            scene,
            character,
            data,
            np.zeros(2),
            on_ground,
            rng=np.random.default_rng(0),
            params=params,
        )


def test_roadmap_of_another_scene_is_refused() -> None:
    scene, character, data = _setup("hexapod")
    params = JumpParams(n_nodes=30)
    start, goal = np.array([-1.0, 0.0, 0.0]), np.array([-2.0, 0.5, 0.0])
    first = plan_jumps(
        scene, character, data, start, goal, rng=np.random.default_rng(0), params=params
    )
    assert first.value is not None
    other = JumpParams(n_nodes=30, min_limbs=5)
    with pytest.raises(ValueError):
        plan_jumps(
            scene,
            character,
            data,
            start,
            goal,
            rng=np.random.default_rng(0),
            roadmap=first.value.roadmap,
            params=other,
        )


def test_deadline_builds_a_partial_roadmap_and_still_answers() -> None:
    from planner.termination import Deadline

    scene, character, data = _setup("quadruped")
    params = JumpParams(n_nodes=200_000)  # far more than 3 s can build
    start, goal = np.array([-1.0, 0.0, 0.0]), np.array([-2.5, 0.5, 0.0])
    result = plan_jumps(
        scene,
        character,
        data,
        start,
        goal,
        rng=np.random.default_rng(1),
        params=params,
        until=Deadline(3.0),
    )
    # The answer does not wait for the build: a jump path from the partial roadmap, with
    # keyframes for what the budget left (all of them on a quiet machine; a busy one may
    # cut the last phases, and then the status and message say so).
    assert result.value is not None
    assert len(result.value.roadmap.nodes) < 200_000
    assert result.value.roadmap.stats["stopped"] == 1
    assert result.value.jumps and result.value.keyframes
    assert result.status in (PlanStatus.SOLVED, PlanStatus.APPROXIMATE), result.message
    # the clock, not the roadmap's size, stopped the build: the answer says so
    assert result.stats["clock_cap_hit"] == 1 and "replay may differ" in result.message


def test_section_matches_contact_region() -> None:
    """The fast section (convex clip, and the general path) equals the scene's own
    ``contact_region`` of the same reduced hull."""
    from planner.ballistic.nodes import _section
    from planner.scene import contact_region

    scene, character, data = _setup("quadruped")
    model = ReducedModel.build(scene, character, data)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(30):
        pose = _standing(character, *rng.uniform([-1.0, -1.0, -0.2], [2.0, 1.0, 0.8]))
        k = int(rng.integers(len(model.workspaces)))
        hull = model.workspaces[k]
        world = hull.vertices @ pose[:3, :3].T + pose[:3, 3]
        for s_idx, surface in enumerate(model.surfaces):
            expect = contact_region(hull, pose, surface)
            fast = _section(world, model.edges[k], surface, model.convex[s_idx])
            general = _section(world, model.edges[k], surface, None)
            if expect is None:
                assert fast is None and general is None
                continue
            checked += 1
            for found in (fast, general):
                assert found is not None
                assert found[0] == pytest.approx(expect.area, rel=1e-6, abs=1e-9)
                assert np.allclose(found[1], expect.centroid, atol=1e-6)
    assert checked >= 10


def test_root_pose_end_points() -> None:
    from planner.poses import quaternion_to_matrix

    scene, character, data = _setup("quadruped")
    params = JumpParams(n_nodes=120)
    first = plan_jumps(
        scene,
        character,
        data,
        np.array([-1.0, 0.0, 0.0]),
        np.array([0.75, 0.0, 0.6]),
        rng=np.random.default_rng(2),
        params=params,
    )
    assert first.value is not None and first.value.jumps
    path = first.value.path
    pose = np.eye(4)
    pose[:3, :3] = quaternion_to_matrix(path.orientations[0])
    pose[:3, 3] = path.positions[0]
    again = plan_jumps(
        scene,
        character,
        data,
        pose,
        np.array([0.75, 0.0, 0.6]),
        rng=np.random.default_rng(2),
        roadmap=first.value.roadmap,
        params=params,
    )
    assert again.status in (PlanStatus.SOLVED, PlanStatus.APPROXIMATE), again.message
    assert again.value is not None
    # the root starts at the given pose; the jump's takeoff position is the COM's
    assert np.allclose(again.value.path.positions[0], path.positions[0])
    assert np.allclose(again.value.keyframes[0].q[:3], path.positions[0])
    assert np.allclose(again.value.keyframes[0].q[3:7], path.orientations[0])
