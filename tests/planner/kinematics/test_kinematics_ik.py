"""solve_ik: reachable targets are reached, limits hold, failures are graceful, runs repeat."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pytest

from planner.kinematics import (
    ComTask,
    ContactNormalTask,
    FrameAxisTask,
    FramePlacementTask,
    FramePositionTask,
    IkProblem,
    PostureTask,
    Priority,
    com_position,
    frame_placement,
    solve_ik,
    within_limits,
)

if TYPE_CHECKING:
    from conftest import Perturb, Robot


def _posture(robot: Robot) -> PostureTask:
    weights = np.ones(robot.model.nv)
    weights[:6] = 0.0
    return PostureTask(robot.q_stand, weights)


def _whole_body_tasks(robot: Robot, q_target: np.ndarray) -> list:
    model = robot.model
    tasks: list = [FramePlacementTask(f, frame_placement(model, q_target, f)) for f in robot.feet]
    tasks.append(ComTask(com_position(model, q_target)))
    tasks.append(
        FramePositionTask(robot.hands[0], frame_placement(model, q_target, robot.hands[0])[:3, 3])
    )
    tasks.append(_posture(robot))
    return tasks


def test_reaches_targets_from_random_configurations(robot: Robot, perturb: Perturb) -> None:
    model, rng = robot.model, np.random.default_rng(7)
    data = model.createData()
    for _ in range(8):
        q_target = perturb(model, rng, robot.q_stand, 0.3)
        q_target[:3] += rng.uniform(-0.05, 0.05, 3)
        tasks = _whole_body_tasks(robot, q_target)
        result = solve_ik(model, robot.q_stand, tasks, data=data)
        assert result.success, result.residuals
        assert np.all(result.residuals[:-1, 0] <= 1e-4)
        assert np.all(result.residuals[:-1, 1] <= 1e-3)
        assert within_limits(model, result.q)
        for f in robot.feet:  # independent check by forward kinematics
            assert np.allclose(
                frame_placement(model, result.q, f), frame_placement(model, q_target, f), atol=2e-4
            )
        assert np.linalg.norm(com_position(model, result.q) - com_position(model, q_target)) < 1e-4


def test_unreachable_targets_fail_gracefully_within_limits(robot: Robot) -> None:
    model = robot.model
    feet = [FramePlacementTask(f, frame_placement(model, robot.q_stand, f)) for f in robot.feet]
    far = frame_placement(model, robot.q_stand, robot.hands[0])[:3, 3] + [1.5, 0.8, 2.0]
    tasks = [
        *feet,
        FramePositionTask(robot.hands[0], far, priority=Priority.CONTACT),
        FramePositionTask(robot.hands[1], far),
    ]
    result = solve_ik(model, robot.q_stand, tasks, max_iterations=60)
    assert not result.success
    assert np.all(np.isfinite(result.q))
    assert within_limits(model, result.q)
    assert result.iterations <= 60
    assert result.residuals[2, 0] > 0.5


def test_joint_limits_hold_when_pushed_against_them(biped: Robot) -> None:
    model = biped.model
    pose = frame_placement(model, biped.q_stand, "left_sole")
    pose[2, 3] += 0.6  # knee folds to its limit and beyond what the leg can do
    pose[0, 3] += 0.4
    result = solve_ik(model, biped.q_stand, [FramePlacementTask("left_sole", pose)], lock_root=True)
    assert within_limits(model, result.q)
    assert not result.success
    start = biped.q_stand.copy()
    start[7:] = 10.0  # starting outside the limits is clipped first
    assert within_limits(model, solve_ik(model, start, [_posture(biped)], max_iterations=3).q)


def test_a_settled_solve_stops_where_more_iterations_would_leave_it(
    biped: Robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A target a metre above the sole: once its undamped steps no longer move the leg (the
    knee against its limit), the solve stops, where the iterations it would have gone on
    with (until their lack of progress stopped them) leave it."""
    import planner.kinematics.ik as ik

    model = biped.model
    sole = frame_placement(model, biped.q_stand, "left_sole")[:3, 3]
    tasks = [FramePositionTask("left_sole", sole + np.array([0.0, 0.0, 1.0]))]  # the knee folds up
    settled = solve_ik(model, biped.q_stand, tasks, lock_root=True)
    monkeypatch.setattr(ik, "_SETTLED_STEP", 0.0)
    patient = solve_ik(model, biped.q_stand, tasks, lock_root=True)
    assert not settled.success and not patient.success
    assert settled.iterations < patient.iterations
    np.testing.assert_allclose(settled.q, patient.q, atol=1e-9)
    np.testing.assert_allclose(settled.residuals, patient.residuals, atol=1e-9)


def test_deterministic(robot: Robot, perturb: Perturb) -> None:
    model = robot.model
    q_target = perturb(model, np.random.default_rng(11), robot.q_stand, 0.3)
    tasks = _whole_body_tasks(robot, q_target)
    first = solve_ik(model, robot.q_stand, tasks)
    second = solve_ik(model, robot.q_stand, tasks, data=model.createData())
    assert np.array_equal(first.q, second.q)
    assert first.iterations == second.iterations
    assert np.array_equal(first.residuals, second.residuals)


def test_locked_root_and_active_mask(biped: Robot, perturb: Perturb) -> None:
    model = biped.model
    q_target = perturb(model, np.random.default_rng(5), biped.q_stand, 0.3)
    target = frame_placement(model, q_target, "left_hand")[:3, 3]
    task = FramePositionTask("left_hand", target)
    locked = solve_ik(model, biped.q_stand, [task], lock_root=True)
    assert np.array_equal(locked.q[:7], biped.q_stand[:7])
    arm = np.zeros(model.nv, dtype=bool)
    arm[
        [
            model.idx_vs[model.getJointId(n)]
            for n in ("left_shoulder_y", "left_shoulder_x", "left_shoulder_z", "left_elbow")
        ]
    ] = True
    masked = solve_ik(model, q_target, [task], active=arm)
    assert masked.success
    moved = np.flatnonzero(masked.q != q_target)
    arm_q = [model.idx_qs[model.idx_vs.tolist().index(v)] for v in np.flatnonzero(arm)]
    assert set(moved.tolist()) <= set(arm_q)


def test_normal_task_leaves_yaw_free(biped: Robot, perturb: Perturb) -> None:
    model = biped.model
    q_target = perturb(model, np.random.default_rng(9), biped.q_stand, 0.3)
    pose = frame_placement(model, q_target, "left_sole")
    task = ContactNormalTask("left_sole", pose[:3, 3], pose[:3, 2])
    result = solve_ik(model, biped.q_stand, [task], lock_root=True)
    assert result.success
    reached = frame_placement(model, result.q, "left_sole")
    assert np.linalg.norm(reached[:3, 3] - pose[:3, 3]) <= 1e-4
    assert np.arccos(np.clip(reached[:3, 2] @ pose[:3, 2], -1, 1)) <= 1e-3


def test_com_xy_only(biped: Robot) -> None:
    model = biped.model
    feet = [FramePlacementTask(f, frame_placement(model, biped.q_stand, f)) for f in biped.feet]
    target = com_position(model, biped.q_stand) + np.array([0.04, -0.03, 5.0])  # z is ignored
    result = solve_ik(model, biped.q_stand, [*feet, ComTask(target, (True, True, False))])
    assert result.success
    assert np.allclose(com_position(model, result.q)[:2], target[:2], atol=1e-4)


def test_contacts_win_over_an_unreachable_com(robot: Robot) -> None:
    model = robot.model
    feet = [FramePlacementTask(f, frame_placement(model, robot.q_stand, f)) for f in robot.feet]
    target = com_position(model, robot.q_stand) + np.array([0.0, 0.0, 0.5])  # too high
    result = solve_ik(model, robot.q_stand, [*feet, ComTask(target), _posture(robot)])
    assert not result.success
    assert result.residuals[2, 0] > 0.05
    assert np.all(result.residuals[:2, 0] < 1e-3)


def test_rejects_malformed_input(biped: Robot) -> None:
    model = biped.model
    with pytest.raises(ValueError, match="q0"):
        solve_ik(model, np.zeros(3), [])
    with pytest.raises(ValueError, match="at most one"):
        solve_ik(model, biped.q_stand, [_posture(biped), _posture(biped)])
    with pytest.raises(ValueError, match="no frame"):
        solve_ik(model, biped.q_stand, [FramePositionTask("nose", np.zeros(3))])
    with pytest.raises(ValueError, match="orthonormal"):
        FramePlacementTask("left_sole", 2.0 * np.eye(4))
    with pytest.raises(TypeError, match="not an IK task"):
        solve_ik(model, biped.q_stand, [np.eye(4)])
    with pytest.raises(ValueError, match="active"):
        solve_ik(model, biped.q_stand, [], active=np.ones(3, dtype=bool))


def test_problem_with_moved_targets_solves_like_solve_ik(robot: Robot, perturb: Perturb) -> None:
    from planner.kinematics import IkProblem

    model, rng = robot.model, np.random.default_rng(3)
    problem = IkProblem(model, _whole_body_tasks(robot, robot.q_stand))
    com_index, hand_index = len(robot.feet), len(robot.feet) + 1
    q = robot.q_stand
    for _ in range(4):
        q_target = perturb(model, rng, robot.q_stand, 0.2)
        tasks = _whole_body_tasks(robot, q_target)
        for i, task in enumerate(tasks[:-1]):
            problem.set_target(i, task.target)
        reused = problem.solve(q)
        fresh = solve_ik(model, q, tasks)
        assert np.array_equal(reused.q, fresh.q)
        assert np.array_equal(reused.residuals, fresh.residuals)
        assert reused.iterations == fresh.iterations
        q = reused.q
    with pytest.raises(ValueError):
        problem.set_target(len(robot.feet) + 2, np.zeros(3))  # the posture
    with pytest.raises(ValueError):
        problem.set_target(com_index, np.zeros(4))
    with pytest.raises(ValueError):
        problem.set_target(0, np.zeros(3))  # a placement needs a pose
    with pytest.raises(ValueError):
        problem.set_target(hand_index, np.full(3, np.nan))
    with pytest.raises(ValueError):
        problem.solve(q, max_iterations=-1)


def test_axis_task_turns_one_axis_leaving_yaw_and_position_free(
    biped: Robot, perturb: Perturb
) -> None:
    model = biped.model
    q_target = perturb(model, np.random.default_rng(11), biped.q_stand, 0.3)
    pose = frame_placement(model, q_target, "left_sole")
    task = FrameAxisTask("left_sole", pose[:3, 2])
    result = solve_ik(model, biped.q_stand, [task], lock_root=True)
    assert result.success
    reached = frame_placement(model, result.q, "left_sole")
    assert np.arccos(np.clip(reached[:3, 2] @ pose[:3, 2], -1, 1)) <= 1e-3
    # the two rows it adds leave the sole free to move and to turn about the axis: held in
    # place with the same axis, it reaches that too
    start = frame_placement(model, biped.q_stand, "left_sole")
    held = FramePositionTask("left_sole", start[:3, 3], priority=Priority.CONTACT)
    both = solve_ik(model, biped.q_stand, [held, task], lock_root=True)
    assert both.success
    placed = frame_placement(model, both.q, "left_sole")
    assert np.linalg.norm(placed[:3, 3] - start[:3, 3]) <= 1e-4
    with pytest.raises(ValueError, match="non-zero"):
        FrameAxisTask("left_sole", np.zeros(3))
    # a compiled problem turns the axis toward a moved direction as a fresh one does
    problem = IkProblem(model, [FrameAxisTask("left_sole", start[:3, 2])], lock_root=True)
    problem.set_target(0, 2.0 * pose[:3, 2])
    moved = problem.solve(biped.q_stand)
    assert np.array_equal(moved.q, result.q)
    with pytest.raises(ValueError, match="non-zero"):
        problem.set_target(0, np.zeros(3))
