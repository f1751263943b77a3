"""track_com keyframes and swing arcs."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pytest

from planner.kinematics import (
    com_position,
    frame_placement,
    hold_contacts,
    keyframe_times,
    swing_arc,
    swing_trajectory,
    track_com,
    within_limits,
)

if TYPE_CHECKING:
    from conftest import Robot


def test_keyframe_times() -> None:
    times = keyframe_times(0.0, 1.0, 30.0)
    assert times.size == 31 and times[0] == 0.0 and times[-1] == 1.0
    assert np.allclose(np.diff(times), 1 / 30)
    odd = keyframe_times(0.5, 0.6, 30.0)
    assert odd.tolist() == pytest.approx([0.5, 0.5 + 1 / 30, 0.5 + 2 / 30, 0.6])
    assert keyframe_times(1.0, 1.0).tolist() == [1.0]
    with pytest.raises(ValueError):
        keyframe_times(1.0, 0.0)


def test_contacts_hold_while_the_com_moves(robot: Robot) -> None:
    model = robot.model
    start = com_position(model, robot.q_stand)
    shift = np.array([0.04, 0.05, -0.04])
    stance = hold_contacts(model, robot.q_stand, robot.feet)

    def com(t: float) -> np.ndarray:
        return start + shift * t

    track = track_com(model, robot.q_stand, com, stance=stance, t_start=0.0, t_end=1.0)
    assert track.times.size == 31
    assert track.all_success
    assert np.all(track.contact_errors < 1e-3)
    assert np.all(track.com_errors <= 1e-4)
    for t, q in zip(track.times, track.configurations, strict=True):
        assert within_limits(model, q)
        assert np.linalg.norm(com_position(model, q) - com(t)) <= 1e-4
        for task in stance:  # independent check by forward kinematics
            assert (
                np.abs(frame_placement(model, q, task.frame)[:3, 3] - task.target[:3, 3]).max()
                < 1e-3
            )
    again = track_com(model, robot.q_stand, com, stance=stance, t_start=0.0, t_end=1.0)
    assert np.array_equal(again.configurations, track.configurations)


def test_samples_and_swing_foot(biped: Robot) -> None:
    model = biped.model
    q = biped.q_stand
    start = frame_placement(model, q, "right_sole")
    end = start.copy()
    end[0, 3] += 0.15
    swing = swing_trajectory(start, end, 0.0, 0.6, lift=0.08)
    com0 = com_position(model, q)
    samples = (np.array([0.0, 0.6]), np.stack([com0, com0 + np.array([0.03, 0.02, 0.0])]))
    track = track_com(
        model,
        q,
        samples,
        stance=hold_contacts(model, q, ["left_sole"]),
        swing_frame="right_sole",
        swing=swing,
        rate=50.0,
    )
    assert track.times.size == 31
    assert track.all_success, (track.swing_errors, track.com_errors)
    assert np.all(track.swing_errors <= 1e-4)
    assert np.allclose(
        frame_placement(model, track.configurations[-1], "right_sole"), end, atol=2e-4
    )
    heights = [frame_placement(model, c, "right_sole")[2, 3] for c in track.configurations]
    assert max(heights) > start[2, 3] + 0.07


def test_swing_arc_shape() -> None:
    start = np.eye(4)
    end = np.eye(4)
    end[:3, 3] = [0.3, 0.1, 0.0]
    s = np.linspace(0.0, 1.0, 11)
    arc = swing_arc(start, end, s, lift=0.1)
    assert arc.shape == (11, 3)
    assert np.allclose(arc[0], start[:3, 3]) and np.allclose(arc[-1], end[:3, 3])
    assert arc[5, 2] == pytest.approx(0.1)
    assert np.all(arc[1:-1, 2] > 0.0)
    departure = swing_arc(start, end, np.array([1e-4]), lift=0.1)[0] - start[:3, 3]
    assert departure[2] > 10 * np.linalg.norm(departure[:2])  # leaves along the normal
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        swing_arc(start, end, np.array([1.5]))
    pose = swing_trajectory(start, end, 1.0, 2.0, lift=0.1)
    assert np.allclose(pose(1.0), start) and np.allclose(pose(2.0), end)
    assert pose(1.5)[2, 3] == pytest.approx(0.1)


def test_unreachable_com_is_flagged_not_raised(biped: Robot) -> None:
    model, q = biped.model, biped.q_stand
    com0 = com_position(model, q)
    samples = (np.array([0.0, 0.2]), np.stack([com0, com0 + np.array([0.0, 0.0, 0.6])]))
    track = track_com(
        model, q, samples, stance=hold_contacts(model, q, biped.feet), max_iterations=30
    )
    assert not track.all_success
    assert not track.success[-1]
    assert np.all(np.isfinite(track.configurations))
    assert all(within_limits(model, c) for c in track.configurations)
    assert np.all(track.contact_errors < 5e-3)  # contacts still win over the COM
    with pytest.raises(ValueError, match="t_start and t_end"):
        track_com(model, q, lambda t: com0, stance=[])


def test_predicted_warm_start_tracks_as_well(robot: Robot) -> None:
    model = robot.model
    start = com_position(model, robot.q_stand)
    stance = hold_contacts(model, robot.q_stand, robot.feet)

    def com(t: float) -> np.ndarray:
        return start + np.array([0.04, 0.05, -0.04]) * np.sin(0.5 * np.pi * t)

    plain = track_com(model, robot.q_stand, com, stance=stance, t_start=0.0, t_end=1.0)
    predicted = track_com(
        model, robot.q_stand, com, stance=stance, t_start=0.0, t_end=1.0, predict=True
    )
    assert plain.all_success and predicted.all_success
    assert np.all(predicted.contact_errors <= 1e-4)
    assert np.all(predicted.com_errors <= 1e-4)
    assert all(within_limits(model, q) for q in predicted.configurations)
    assert np.abs(predicted.configurations - plain.configurations).max() < 1e-2
    again = track_com(
        model, robot.q_stand, com, stance=stance, t_start=0.0, t_end=1.0, predict=True
    )
    assert np.array_equal(again.configurations, predicted.configurations)
