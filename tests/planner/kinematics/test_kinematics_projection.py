"""project_contact: one limb onto a surface point, everything else untouched."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.kinematics import (
    FramePlacementTask,
    Priority,
    frame_placement,
    limb_dofs,
    project_contact,
    within_limits,
)

if TYPE_CHECKING:
    from conftest import Perturb, Robot


def _limb_q_indices(robot: Robot, dofs: np.ndarray) -> list[int]:
    model = robot.model
    idx_v = list(model.idx_vs)
    return [int(model.idx_qs[idx_v.index(int(v))]) for v in dofs]


def test_projects_foot_onto_reachable_points(robot: Robot, perturb: Perturb) -> None:
    model, rng = robot.model, np.random.default_rng(21)
    data = model.createData()
    dofs = limb_dofs(model, robot.leg_roots[0], robot.feet[0])
    limb_q = _limb_q_indices(robot, dofs)
    foot = robot.feet[1]
    hold = [FramePlacementTask(foot, frame_placement(model, robot.q_stand, foot), Priority.CONTACT)]
    for _ in range(10):
        q_target = robot.q_stand.copy()
        q_target[limb_q] = perturb(model, rng, robot.q_stand, 0.3)[limb_q]
        pose = frame_placement(model, q_target, robot.feet[0])
        result = project_contact(
            model,
            robot.q_stand,
            robot.leg_roots[0],
            robot.feet[0],
            pose[:3, 3],
            pose[:3, 2],
            hold=hold,
            reference=robot.q_stand,
            data=data,
        )
        assert result.success
        assert result.iterations <= 100
        reached = frame_placement(model, result.q, robot.feet[0])
        assert np.linalg.norm(reached[:3, 3] - pose[:3, 3]) <= 1e-4
        assert np.arccos(np.clip(reached[:3, 2] @ pose[:3, 2], -1, 1)) <= 1e-3
        others = np.setdiff1d(np.arange(model.nq), limb_q)
        assert np.array_equal(result.q[others], robot.q_stand[others])
        assert within_limits(model, result.q)


def test_projection_with_orientation_offset_and_clearance(biped: Robot, perturb: Perturb) -> None:
    model = biped.model
    q_target = perturb(model, np.random.default_rng(2), biped.q_stand, 0.3)
    pose = frame_placement(model, q_target, "right_hand")
    offset = np.array([0.0, 0.0, -0.05])
    point = pose[:3, 3] + pose[:3, :3] @ offset
    normal = pose[:3, 0]
    result = project_contact(
        model,
        biped.q_stand,
        "right_shoulder_y",
        "right_hand",
        point - 0.01 * normal,
        normal,
        contact_normal=(1.0, 0.0, 0.0),
        contact_offset=offset,
        orientation=pose[:3, :3],
        clearance=0.01,
    )
    assert result.success
    assert np.allclose(frame_placement(model, result.q, "right_hand"), pose, atol=2e-4)


def test_unreachable_projection_fails_gracefully(robot: Robot) -> None:
    model = robot.model
    far = frame_placement(model, robot.q_stand, robot.feet[0])[:3, 3] + [1.5, 0.0, -1.0]
    result = project_contact(
        model, robot.q_stand, robot.leg_roots[0], robot.feet[0], far, np.array([0.0, 0.0, 1.0])
    )
    assert not result.success
    assert np.all(np.isfinite(result.q))
    assert within_limits(model, result.q)
    assert result.iterations <= 100


def test_flipped_normal_fails_gracefully(biped: Robot) -> None:
    model = biped.model
    pose = frame_placement(model, biped.q_stand, "left_sole")
    result = project_contact(
        model, biped.q_stand, "left_hip_z", "left_sole", pose[:3, 3], -pose[:3, 2]
    )  # the sole would have to face the sky
    assert not result.success
    assert np.all(np.isfinite(result.q))
    assert within_limits(model, result.q)
