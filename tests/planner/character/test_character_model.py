"""Characters: loading, joint order, reference posture, limbs, self-collision geometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner.character import (
    Character,
    builtin_character_ids,
    character_spec_path,
    get_character,
    load_character,
    real_robot_ids,
)
from planner.character.batch_fk import (
    TreeKinematics,
    center_of_mass,
    frame_jacobian,
    frame_placement,
    joint_placements,
)
from planner.character.collision import SelfCollisionChecker

ALL_IDS = builtin_character_ids() + real_robot_ids()


def _support_polygon_contains(points: np.ndarray, xy: np.ndarray) -> bool:
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points[:, :2])
    return bool(np.all(hull.equations[:, :2] @ xy + hull.equations[:, 2] < -1e-3))


def test_builtin_ids() -> None:
    assert builtin_character_ids() == ("humanoid", "quadruped", "hexapod")


@pytest.mark.parametrize("cid", builtin_character_ids())
def test_builtin_character_shapes(cid: str) -> None:
    c = get_character(cid)
    assert c.id == cid
    assert c.model.nq == 7 + c.n_joints
    assert c.joint_names == tuple(c.model.names[2:])
    assert np.all(c.lower < c.upper)
    expected = {
        "humanoid": (4, 60.0, 70.0),
        "quadruped": (4, 20.0, 30.0),
        "hexapod": (6, 3.0, 10.0),
    }[cid]
    assert len(c.default_limbs) == expected[0]
    assert expected[1] <= c.mass <= expected[2]
    assert c.mass == pytest.approx(pin.computeTotalMass(c.model))
    assert len(c.geometry.geometryObjects) > 0 and len(c.geometry.collisionPairs) > 0
    on_request = [limb.name for limb in c.limbs if limb.on_request]
    assert on_request == (["left_seat", "right_seat"] if cid == "humanoid" else [])
    for limb in c.default_limbs:
        assert cid == "humanoid" or limb.n_joints == 3
        assert limb.contact == ("patch" if cid == "humanoid" else "point")


def test_humanoid_joints_and_patches() -> None:
    c = get_character("humanoid")
    assert c.n_joints >= 28
    assert [limb.n_joints for limb in c.limbs] == [6, 6, 7, 7, 3, 3]  # feet, hands, sit bones
    assert c.limb("left_foot").contact_points().shape == (4, 3)
    np.testing.assert_allclose(c.limb("left_foot").half_size, [0.11, 0.05])
    np.testing.assert_allclose(c.limb("left_hand").half_size, [0.04, 0.04])
    height = c.q_ref[2]
    assert 0.9 < height < 1.1
    data = c.model.createData()
    pin.framesForwardKinematics(c.model, data, c.q_ref)
    head = c.model.getFrameId("head")  # about 1.7 m tall: head sphere centre + radius
    assert 1.6 < data.oMf[head].translation[2] + 0.13 + 0.1 < 1.8


@pytest.mark.parametrize("cid", ALL_IDS)
def test_reference_posture_on_ground(cid: str) -> None:
    c = get_character(cid)
    data = c.model.createData()
    pin.framesForwardKinematics(c.model, data, c.q_ref)
    com = pin.centerOfMass(c.model, data, c.q_ref)
    np.testing.assert_allclose(c.q_ref[3:7], [0, 0, 0, 1])
    contacts = []
    for limb in c.limbs:
        oMf = data.oMf[limb.frame_id]
        pts = limb.contact_points() @ np.asarray(oMf.rotation).T + oMf.translation
        contacts.append(pts)
    lowest = min(float(p[:, 2].min()) for p in contacts)
    assert lowest == pytest.approx(0.0, abs=1e-9)
    feet = [p for limb, p in zip(c.limbs, contacts, strict=True) if "foot" in limb.name]
    assert len(feet) >= 2
    tolerance = 1e-9 if cid in builtin_character_ids() else 1e-2  # real robots: tilted frames
    for pts in feet:  # every foot touches the ground
        np.testing.assert_allclose(pts[:, 2], 0.0, atol=tolerance)
    assert _support_polygon_contains(np.concatenate(feet), com[:2])
    assert com[2] > 0.1


def test_batch_fk_matches_pinocchio() -> None:
    rng = np.random.default_rng(3)
    for cid in builtin_character_ids():
        c = get_character(cid)
        kin = TreeKinematics.from_model(c.model)
        q = rng.uniform(c.lower, c.upper, size=(20, c.n_joints))
        rot, trans = joint_placements(kin, q)
        com = center_of_mass(kin, rot, trans)
        data = c.model.createData()
        for k in range(len(q)):
            qf = np.concatenate([[0, 0, 0, 0, 0, 0, 1], q[k]])
            pin.framesForwardKinematics(c.model, data, qf)
            np.testing.assert_allclose(com[k], pin.centerOfMass(c.model, data, qf), atol=1e-12)
            for limb in c.limbs:
                frame = c.model.frames[limb.frame_id]
                r_f, t_f = frame_placement(
                    rot[k : k + 1],
                    trans[k : k + 1],
                    frame.parentJoint,
                    frame.placement.rotation,
                    frame.placement.translation,
                )
                np.testing.assert_allclose(t_f[0], data.oMf[limb.frame_id].translation, atol=1e-12)
                np.testing.assert_allclose(r_f[0], data.oMf[limb.frame_id].rotation, atol=1e-12)
                jac = pin.computeFrameJacobian(
                    c.model, data, qf, limb.frame_id, pin.LOCAL_WORLD_ALIGNED
                )
                mine = frame_jacobian(
                    kin, rot[k : k + 1], trans[k : k + 1], np.asarray(limb.joint_ids), t_f
                )
                np.testing.assert_allclose(mine[0], jac[:, limb.idx_v], atol=1e-12)


@pytest.mark.parametrize("cid", builtin_character_ids())
def test_self_collision_checker_matches_pinocchio(cid: str) -> None:
    c = get_character(cid)
    kin = TreeKinematics.from_model(c.model)
    checker = SelfCollisionChecker.from_geometry_model(c.geometry)
    rng = np.random.default_rng(7)
    q = rng.uniform(c.lower, c.upper, size=(300, c.n_joints))
    rot, trans = joint_placements(kin, q)
    mine = checker.colliding(rot, trans)
    data = c.model.createData()
    ref = np.array(
        [  # a fresh GeometryData per sample: coal caches GJK guesses between calls
            pin.computeCollisions(
                c.model,
                data,
                c.geometry,
                pin.GeometryData(c.geometry),
                np.concatenate([[0, 0, 0, 0, 0, 0, 1], qk]),
                True,
            )
            for qk in q
        ]
    )
    # coal's GJK may flip on grazing contacts: any disagreement must be one
    for k in np.nonzero(mine != ref)[0]:
        gdata = pin.GeometryData(c.geometry)
        pin.computeDistances(
            c.model, data, c.geometry, gdata, np.concatenate([[0, 0, 0, 0, 0, 0, 1], q[k]])
        )
        assert min(r.min_distance for r in gdata.distanceResults) < 1e-4
    assert np.sum(mine != ref) <= 3
    assert 0 < ref.sum() < len(q)
    assert not checker.colliding(*joint_placements(kin, c.q_ref_joints[None]))[0]


def test_adjacent_pairs_removed() -> None:
    c = get_character("humanoid")
    names = {
        (
            c.geometry.geometryObjects[p.first].parentJoint,
            c.geometry.geometryObjects[p.second].parentJoint,
        )
        for p in c.geometry.collisionPairs
    }
    thigh = c.model.getJointId("l_hip_pitch")
    shin = c.model.getJointId("l_knee")
    assert (thigh, shin) not in names and (shin, thigh) not in names
    assert all(a != b for a, b in names)


def test_load_character_returns_frozen_values() -> None:
    c = load_character(character_spec_path("quadruped"))
    assert isinstance(c, Character)
    with pytest.raises(ValueError):
        c.q_ref[0] = 1.0
    with pytest.raises(AttributeError):
        c.id = "x"  # type: ignore[misc]


@pytest.mark.skipif(not real_robot_ids(), reason="example-robot-data is not installed")
def test_real_robots_load() -> None:
    talos = get_character("talos")
    assert talos.n_joints == 32
    assert talos.q_ref[2] == pytest.approx(1.019, abs=0.01)
    assert [limb.n_joints for limb in talos.limbs] == [6, 6, 7, 7]
    hyq = get_character("hyq")
    assert hyq.n_joints == 12
    assert [limb.joint_names[0] for limb in hyq.limbs] == [
        "lf_haa_joint",
        "rf_haa_joint",
        "lh_haa_joint",
        "rh_haa_joint",
    ]
    assert 70 < hyq.mass < 100


def test_unknown_id() -> None:
    with pytest.raises(KeyError):
        character_spec_path("dragon")


def test_stored_urdfs_match_the_generator(tmp_path: Path) -> None:
    from planner.character.urdfgen import write_all

    for path in write_all(tmp_path):
        stored = character_spec_path(path.parent.name).with_name(path.name)
        assert stored.read_text() == path.read_text()


@pytest.mark.skipif(not real_robot_ids(), reason="example-robot-data is not installed")
@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_capsule_mode_shapes_end_at_the_effectors(cid: str) -> None:
    """In ``capsules`` mode no shape of a foot hangs below its contact plane (a foot capsule
    reaching under the sole read as a collision on every swing foot near the ground), and a
    patch effector's whole contact area is covered by a shape (a sole's toe and heel)."""
    import coal

    c = get_character(cid)
    model, geometry = c.model, c.geometry
    data = model.createData()
    pin.framesForwardKinematics(model, data, c.q_ref)
    gdata = pin.GeometryData(geometry)
    pin.updateGeometryPlacements(model, data, geometry, gdata)
    for limb in c.limbs:
        frame = data.oMf[limb.frame_id]
        normal = frame.rotation @ limb.normal
        points = (frame.rotation @ limb.contact_points().T).T + frame.translation
        lowest = np.inf
        for i, obj in enumerate(geometry.geometryObjects):
            if int(obj.parentJoint) != int(model.frames[limb.frame_id].parentJoint):
                continue
            placement = gdata.oMg[i]
            halfspace = coal.Halfspace(normal, float(normal @ points[0]))
            request, result = coal.DistanceRequest(), coal.DistanceResult()
            request.enable_signed_distance = True
            shape = coal.Transform3s(placement.rotation, placement.translation)
            d = coal.distance(obj.geometry, shape, halfspace, coal.Transform3s(), request, result)
            lowest = min(lowest, d)
        if limb.name.endswith("foot"):  # Talos' gripper fingers do reach past its palm
            assert lowest >= -1e-6, limb.name
        if limb.contact == "patch":
            assert lowest == pytest.approx(0.0, abs=1e-6) or not limb.name.endswith("foot")
            covered = [
                any(
                    coal.distance(
                        obj.geometry,
                        coal.Transform3s(gdata.oMg[i].rotation, gdata.oMg[i].translation),
                        coal.Sphere(1e-4),
                        coal.Transform3s(np.eye(3), p + 1e-3 * normal),
                        coal.DistanceRequest(),
                        coal.DistanceResult(),
                    )
                    <= 1e-3
                    for i, obj in enumerate(geometry.geometryObjects)
                )
                for p in points
            ]
            assert all(covered), limb.name


@pytest.mark.skipif(not real_robot_ids(), reason="example-robot-data is not installed")
@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_capsule_mode_motion_geometry_is_the_urdf_meshes_hulls(cid: str) -> None:
    """The whole-body motion's shapes are the URDF's own collision elements, meshes as their
    convex hulls (what the independent audit checks), with self-collision pairs declared;
    the planner's capsules stay in ``geometry``."""
    import coal

    c = get_character(cid)
    motion = c.motion_geometry
    assert motion is not c.geometry
    names = [str(o.name) for o in motion.geometryObjects]
    assert not any("_capsule_" in n or n.endswith("_plate") for n in names)
    hulls = [o for o in motion.geometryObjects if isinstance(o.geometry, coal.ConvexBase)]
    assert len(hulls) >= 9 and all(o.geometry.num_points >= 4 for o in hulls)
    assert not any(isinstance(o.geometry, coal.BVHModelBase) for o in motion.geometryObjects)
    assert len(motion.collisionPairs) > 0
    # no declared pair touches in the reference posture, none is on one joint
    data = c.model.createData()
    pin.framesForwardKinematics(c.model, data, c.q_ref)
    gdata = pin.GeometryData(motion)
    pin.updateGeometryPlacements(c.model, data, motion, gdata)
    assert not pin.computeCollisions(motion, gdata, False)
    for pair in motion.collisionPairs:
        first, second = motion.geometryObjects[pair.first], motion.geometryObjects[pair.second]
        assert first.parentJoint != second.parentJoint


def test_urdf_mode_motion_geometry_is_the_geometry() -> None:
    c = get_character("humanoid")
    assert c.motion_geometry is c.geometry
