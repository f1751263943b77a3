"""Forward kinematics helpers, configuration conversions and index tables."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
import pytest

from planner.kinematics import (
    bounded_dofs,
    clamp_to_limits,
    com_position,
    configuration_from,
    configuration_parts,
    frame_id,
    frame_placement,
    frame_placements,
    limb_dofs,
    limb_reach,
    within_limits,
)

if TYPE_CHECKING:
    from conftest import Perturb, Robot


def test_configuration_round_trip(robot: Robot, perturb: Perturb) -> None:
    model = robot.model
    q = perturb(model, np.random.default_rng(3), robot.q_stand, 0.5)
    position, quat, joints = configuration_parts(model, q)
    assert np.allclose(np.linalg.norm(quat), 1.0)
    assert len(joints) == model.nv - 6
    rebuilt = configuration_from(model, position, 2.0 * quat, joints)
    assert np.allclose(rebuilt, q)


def test_configuration_from_defaults_and_errors(biped: Robot) -> None:
    model = biped.model
    q = configuration_from(
        model, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0]), {"left_knee": 0.7}
    )
    assert q[model.idx_qs[model.getJointId("left_knee")]] == 0.7
    assert q[model.idx_qs[model.getJointId("right_knee")]] == 0.0
    with pytest.raises(ValueError, match="no joint named"):
        configuration_from(model, np.zeros(3), np.array([0.0, 0, 0, 1]), {"tail": 1.0})
    with pytest.raises(ValueError, match="non-zero"):
        configuration_from(model, np.zeros(3), np.zeros(4))


def test_forward_kinematics_matches_pinocchio(robot: Robot, perturb: Perturb) -> None:
    model = robot.model
    q = perturb(model, np.random.default_rng(4), robot.q_stand, 0.5)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    pose = frame_placement(model, q, robot.feet[0])
    assert np.allclose(pose, data.oMf[model.getFrameId(robot.feet[0])].homogeneous)
    poses = frame_placements(model, q, [robot.feet[1], robot.hands[0]])
    assert poses.shape == (2, 4, 4)
    assert np.allclose(poses[0], frame_placement(model, q, robot.feet[1]))
    assert np.allclose(com_position(model, q), pin.centerOfMass(model, model.createData(), q))


def test_limb_dofs_and_limits(biped: Robot) -> None:
    model = biped.model
    dofs = limb_dofs(model, "left_hip_z", "left_sole")
    assert dofs.tolist() == list(range(6, 12))
    assert limb_dofs(model, "left_knee", "left_sole").tolist() == [9, 10, 11]
    with pytest.raises(ValueError, match="does not move"):
        limb_dofs(model, "right_hip_z", "left_sole")
    with pytest.raises(ValueError, match="no frame"):
        frame_id(model, "nose")
    v_idx, q_idx, lower, upper = bounded_dofs(model)
    assert v_idx.size == model.nv - 6 and np.all(q_idx == v_idx + 1)
    assert np.all(lower < upper)
    q = biped.q_stand.copy()
    q[q_idx] = upper + 1.0
    assert not within_limits(model, q)
    assert within_limits(model, clamp_to_limits(model, q))


def test_cached_tables_follow_limit_changes(biped: Robot) -> None:
    model = pin.Model(biped.model)  # a copy: the session model stays untouched
    _, _, _, upper = bounded_dofs(model)
    assert upper[0] == pytest.approx(0.8)
    limits = model.upperPositionLimit.copy()
    limits[7] = 0.1
    model.upperPositionLimit = limits
    assert bounded_dofs(model)[3][0] == pytest.approx(0.1)


def test_limb_reach_bounds_every_posture_of_the_limb(biped: Robot, perturb: Perturb) -> None:
    """``limb_reach``: the sum of the leg's segments (hip to knee 0.4 m, knee to ankle 0.4 m,
    ankle to sole 0.08 m, plus an offset in the sole's frame); no posture of the leg puts
    that point further from the hip, and the straight leg reaches it."""
    model = biped.model
    offset = np.array([0.03, 0.0, 0.0])
    reach = limb_reach(model, "left_hip_z", "left_sole", offset)
    assert reach == pytest.approx(0.8 + float(np.hypot(0.08, 0.03)))
    assert limb_reach(model, "left_knee", "left_sole", np.zeros(3)) == pytest.approx(0.48)
    with pytest.raises(ValueError, match="does not move"):
        limb_reach(model, "right_hip_z", "left_sole", np.zeros(3))
    data = model.createData()
    hip, sole = model.getJointId("left_hip_z"), model.getFrameId("left_sole")
    rng = np.random.default_rng(5)
    farthest = 0.0
    for _ in range(200):
        q = perturb(model, rng, biped.q_stand, 2.0)
        pin.framesForwardKinematics(model, data, q)
        point = data.oMf[sole].act(offset)
        farthest = max(farthest, float(np.linalg.norm(point - data.oMi[hip].translation)))
    assert farthest <= reach + 1e-9
    straight = biped.q_stand.copy()
    straight[7:] = 0.0
    pin.framesForwardKinematics(model, data, straight)
    sole_origin = data.oMf[sole].translation - data.oMi[hip].translation
    assert float(np.linalg.norm(sole_origin)) == pytest.approx(0.88)
