"""Standing states: contacts on surfaces, balanced, within limits, collision-free, seeded."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.contact.body import self_collides
from planner.contact.reachability import ground_limbs
from planner.contact.standing import (
    CONTACT_TOLERANCE,
    GRAVITY,
    StandingParams,
    body_collides_scene,
    standing_state,
    state_from_root_pose,
)
from planner.contact.state import ContactState
from planner.kinematics import com_position, frame_placement, within_limits
from planner.result import PlanStatus
from planner.scene import SurfaceKind
from tests.planner.contact.contact_helpers import (
    character_and_data,
    checker,
    scene,
    standing_pose,
)
from trajectory import Contact, ContactPhase, equilibrium_margin, is_static_equilibrium

CASES = [
    ("humanoid", "flat", (0.3, 0.2, 0.0)),
    ("humanoid", "stairs", (1.45, 0.0, 0.3)),
    ("humanoid", "rubble", (-1.0, 0.5, 0.0)),
    ("humanoid", "rubble", (0.5, 1.2, 0.2)),
    ("humanoid", "twister", (0.2, 0.1, 0.0)),
    ("quadruped", "flat", (0.0, 0.0, 0.0)),
    ("quadruped", "stairs", (1.45, 0.0, 0.3)),
    ("quadruped", "rubble", (1.05, -0.12, 0.09)),
    ("quadruped", "twister", (-0.5, 0.5, 0.0)),
    ("hexapod", "flat", (0.0, 0.0, 0.0)),
    ("hexapod", "stairs", (3.1, 0.0, 0.9)),
    ("hexapod", "stairs", (1.45, 0.0, 0.3)),
    ("hexapod", "rubble", (-1.0, 0.0, 0.0)),
    ("hexapod", "twister", (0.2, 0.1, 0.0)),
]


def assert_valid_standing(character_id: str, scene_id: str, state: ContactState) -> None:
    character, _ = character_and_data(character_id)
    world = scene(scene_id)
    model = character.model
    assert state.limbs == ground_limbs(character)
    assert within_limits(model, state.q)
    for contact in state.contacts:
        limb = character.limb(contact.limb)
        surface = world.surfaces[contact.surface]
        assert surface.kind is SurfaceKind.SUPPORT
        effector = frame_placement(model, state.q, limb.frame_id)
        if limb.contact == "patch":
            np.testing.assert_allclose(effector, contact.placement, atol=1e-9)
        else:  # a point contact is recorded at the effector, in the root's orientation
            np.testing.assert_allclose(effector[:3, 3], contact.placement[:3, 3], atol=1e-9)
            root = frame_placement(model, state.q, 1)
            np.testing.assert_allclose(root[:3, :3], contact.placement[:3, :3], atol=1e-9)
        assert np.abs(surface.height(contact.points)).max() <= CONTACT_TOLERANCE
        assert surface.contains_projection(contact.points).all()
        np.testing.assert_allclose(contact.normal, surface.normal, atol=1e-12)
        if limb.contact == "patch":
            axis = contact.placement[:3, :3] @ limb.normal
            assert float(axis @ surface.normal) >= np.cos(0.02)
    assert not body_collides_scene(world, character, state.q, state.contacts)
    model = character.model
    assert not self_collides(
        character, state.q, model.createData(), pin.GeometryData(character.geometry)
    )
    pose = np.eye(4)
    pose[:3, :3] = pin.Quaternion(state.q[3:7]).toRotationMatrix()
    pose[:3, 3] = state.q[:3]
    assert checker(character_id, scene_id).is_valid(pose)
    phase = ContactPhase(
        [Contact(c.points, c.normal, c.mu) for c in state.contacts], mass=character.mass
    )
    com = com_position(model, state.q)
    assert is_static_equilibrium(phase, com)
    margin = equilibrium_margin(phase, com)
    needed = StandingParams().margin * character.mass * GRAVITY / len(phase.wrench_generators)
    assert margin.feasible
    assert margin.margin >= needed


@pytest.mark.parametrize(("character_id", "scene_id", "point"), CASES)
def test_standing_state(
    character_id: str, scene_id: str, point: tuple[float, float, float]
) -> None:
    character, data = character_and_data(character_id)
    result = standing_state(
        scene(scene_id),
        character,
        data,
        np.array(point),
        rng=np.random.default_rng(0),
        checker=checker(character_id, scene_id),
    )
    assert result.status is PlanStatus.SOLVED, result.message
    assert result.value is not None
    assert_valid_standing(character_id, scene_id, result.value)
    feet = np.mean([c.points.mean(axis=0) for c in result.value.contacts], axis=0)
    assert np.linalg.norm(feet[:2] - np.array(point[:2])) < 0.3


def test_standing_state_is_seeded_and_honours_yaw() -> None:
    character, data = character_and_data("humanoid")
    world = scene("flat")
    one = standing_state(world, character, data, np.zeros(3), rng=np.random.default_rng(9))
    two = standing_state(world, character, data, np.zeros(3), rng=np.random.default_rng(9))
    assert one.value is not None and two.value is not None
    np.testing.assert_array_equal(one.value.q, two.value.q)
    turned = standing_state(
        world, character, data, np.zeros(3), rng=np.random.default_rng(9), yaw=1.2
    )
    assert turned.value is not None
    rotation = pin.Quaternion(turned.value.q[3:7]).toRotationMatrix()
    assert np.arctan2(rotation[1, 0], rotation[0, 0]) == pytest.approx(1.2)


@pytest.mark.parametrize("character_id", ["humanoid", "quadruped", "hexapod"])
def test_state_from_root_pose(character_id: str) -> None:
    character, data = character_and_data(character_id)
    world = scene("flat")
    pose = standing_pose(character_id, (0.5, -0.5, 0.0), yaw=0.7)
    result = state_from_root_pose(world, character, data, pose)
    assert result.status is PlanStatus.SOLVED, result.message
    assert result.value is not None
    np.testing.assert_allclose(result.value.q[:3], pose[:3, 3])
    assert_valid_standing(character_id, "flat", result.value)


def test_failures_are_reported() -> None:
    character, data = character_and_data("humanoid")
    world = scene("flat")
    off_scene = standing_state(
        world, character, data, np.array([20.0, 0.0, 0.0]), rng=np.random.default_rng(0)
    )
    assert off_scene.status is PlanStatus.INFEASIBLE
    assert "Support" in off_scene.message
    flying = state_from_root_pose(
        world, character, data, standing_pose("humanoid", (0.0, 0.0, 1.5))
    )
    assert flying.status is PlanStatus.INFEASIBLE
    timed_out = standing_state(
        world, character, data, np.zeros(3), rng=np.random.default_rng(0), until=lambda: True
    )
    assert timed_out.status is PlanStatus.TIMEOUT
