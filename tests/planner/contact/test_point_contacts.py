"""Point contacts (sphere feet) follow one rule everywhere: the contact point is the lowest point
of a ball of radius ``|offset|`` centred on the effector frame origin, however the frame turns
(HyQ's foot frames are tilted by 44 degrees in ``q_ref``)."""

from __future__ import annotations

from xml.etree import ElementTree

import numpy as np
import pinocchio as pin
import pytest

from planner.character import get_character, real_robot_ids
from planner.contact.body import (
    body_geometry,
    contact_placement,
    contact_points,
    point_radius,
    sphere_centre,
)
from planner.contact.checks import check_state, hold_error, make_contact
from planner.contact.context import make_context
from planner.contact.standing import CONTACT_TOLERANCE, standing_state
from planner.offline import load_offline_data
from planner.result import PlanStatus
from planner.scene import hpp_environment_meshes
from tests.paths import gecko_cache_dir
from tests.scenarios.jumps.scenes import load_scenario_scene

POINT_CHARACTERS = ["quadruped", "hexapod", *(["hyq"] if "hyq" in real_robot_ids() else [])]
needs_hyq = pytest.mark.skipif("hyq" not in real_robot_ids(), reason="no example-robot-data")


def _unit(v: list[float]) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    return a / np.linalg.norm(a)


@pytest.mark.parametrize("cid", POINT_CHARACTERS)
def test_contact_point_is_the_lowest_point_of_the_sphere_whatever_the_rotation(cid: str) -> None:
    character = get_character(cid)
    rng = np.random.default_rng(0)
    for limb in character.limbs:
        assert limb.contact == "point"
        for normal in (_unit([0, 0, 1]), _unit([0.26, 0, 0.97]), _unit([0, -0.3, 1])):
            target = rng.normal(size=3)
            centre = sphere_centre(limb, target, normal)
            assert np.linalg.norm(centre - target) == pytest.approx(point_radius(limb))
            placement = np.eye(4)
            placement[:3, :3] = pin.exp3(rng.normal(size=3))  # any frame rotation
            placement[:3, 3] = centre
            np.testing.assert_allclose(contact_points(limb, placement, normal)[0], target)


@pytest.mark.parametrize("cid", POINT_CHARACTERS)
def test_sphere_radius_matches_the_foot_ball(cid: str) -> None:
    """The offset's length is the radius (within 1 mm) of the URDF's collision sphere of the
    foot link, centred on the effector frame: the rule is the robot's geometry."""
    character = get_character(cid)
    root = ElementTree.fromstring(character.urdf_text)
    for limb in character.limbs:
        frame = character.model.frames[limb.frame_id]
        joint = root.find(f"joint[@name='{frame.name}']")
        link = frame.name if joint is None else joint.find("child").get("link")  # type: ignore[union-attr]
        collision = root.find(f"link[@name='{link}']/collision")
        assert collision is not None
        origin = collision.find("origin")
        xyz = (
            [0.0] * 3 if origin is None else [float(x) for x in origin.get("xyz", "0 0 0").split()]
        )
        np.testing.assert_allclose(xyz, 0.0, atol=1e-9)
        sphere = collision.find("geometry/sphere")
        assert sphere is not None
        assert float(sphere.get("radius", "nan")) == pytest.approx(point_radius(limb), abs=1e-3)


@needs_hyq
def test_hyq_reference_feet_are_tilted_but_contacts_are_consistent() -> None:
    hyq = get_character("hyq")
    data = hyq.model.createData()
    pin.framesForwardKinematics(hyq.model, data, hyq.q_ref)
    up = np.array([0.0, 0.0, 1.0])
    for limb in hyq.limbs:
        frame = data.oMf[limb.frame_id]
        tilt = np.degrees(np.arccos(np.clip(frame.rotation[2, 2], -1.0, 1.0)))
        assert tilt > 30.0  # the case that broke: origin + R offset is not the lowest point
        placement = contact_placement(hyq, limb.name, hyq.q_ref, data)
        point = contact_points(limb, placement, up)[0]
        np.testing.assert_allclose(point, frame.translation - point_radius(limb) * up)
        np.testing.assert_allclose(sphere_centre(limb, point, up), frame.translation)


@needs_hyq
def test_hyq_contact_shapes_reach_below_the_sole_by_their_true_depth() -> None:
    """The shin capsule (radius 4 cm) ends at the foot frame, the foot sphere's centre: its
    axis stops a radius short of the frame. It reaches no lower than the sphere's lowest
    point, so it needs no extra lift when the foot stands (it hung 4 cm - |offset| below
    before, and read as a collision on every swing foot near the ground)."""
    hyq = get_character("hyq")
    body = body_geometry(hyq)
    for limb in hyq.limbs:
        (g,) = body.exempt[limb.name]
        assert point_radius(limb) > 0.0
        assert body.depth[(limb.name, g)] == pytest.approx(0.0, abs=1e-6)


@needs_hyq
@pytest.mark.parametrize(
    ("scene_name", "point"),
    [("ground", (0.0, 0.0, 0.0)), ("ground", (1.0, 0.5, 0.0)), ("darpa", (-2.0, 0.0, 0.0))],
)
def test_hyq_stands_on_hpp_scenes(scene_name: str, point: tuple[float, float, float]) -> None:
    if scene_name not in hpp_environment_meshes():
        pytest.skip("hpp-environments not installed")
    world = load_scenario_scene({"kind": "hpp", "name": scene_name})
    assert world is not None
    hyq = get_character("hyq")
    data = load_offline_data(hyq, gecko_cache_dir())
    result = standing_state(world, hyq, data, np.array(point), rng=np.random.default_rng(0))
    assert result.status is PlanStatus.SOLVED, result.message
    state = result.value
    assert state is not None and len(state.contacts) == 4
    ctx = make_context(world, hyq, data)
    report = check_state(ctx, state)
    assert report.valid, report
    assert hold_error(ctx, state.q, state.contacts) <= 1e-6
    for contact in state.contacts:
        surface = world.surfaces[contact.surface]
        assert np.abs(surface.height(contact.points)).max() <= CONTACT_TOLERANCE
        again = make_contact(ctx, contact.limb, state.q, contact.surface)
        np.testing.assert_allclose(again.points, contact.points, atol=1e-12)
