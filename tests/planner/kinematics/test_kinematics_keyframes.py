"""Keyframe times and swing arcs."""

from __future__ import annotations

import numpy as np
import pytest

from planner.kinematics import (
    clearing_swing_trajectory,
    keyframe_times,
    swing_arc,
    swing_trajectory,
)


def test_keyframe_times() -> None:
    times = keyframe_times(0.0, 1.0, 30.0)
    assert times.size == 31 and times[0] == 0.0 and times[-1] == 1.0
    assert np.allclose(np.diff(times), 1 / 30)
    odd = keyframe_times(0.5, 0.6, 30.0)
    assert odd.tolist() == pytest.approx([0.5, 0.5 + 1 / 30, 0.5 + 2 / 30, 0.6])
    assert keyframe_times(1.0, 1.0).tolist() == [1.0]
    with pytest.raises(ValueError):
        keyframe_times(1.0, 0.0)


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


def test_a_clearing_swing_rises_before_it_moves_over() -> None:
    # a step 0.45 m ahead and 0.17 m up: the path rises to 0.1 m above the step before it
    # crosses, so a ridge right ahead of the lift-off is passed above, not through
    start = np.eye(4)
    end = np.eye(4)
    end[:3, 3] = [0.45, 0.0, 0.17]
    pose = clearing_swing_trajectory(start, end, 1.0, 2.0, rise=0.27, descend=0.1)
    assert np.allclose(pose(0.5), start) and np.allclose(pose(1.0), start)
    assert np.allclose(pose(2.0), end) and np.allclose(pose(2.5), end)
    points = np.array([pose(t)[:3, 3] for t in np.linspace(1.0, 2.0, 101)])
    # the rise alone first (tau < 0.2): straight up
    assert np.allclose(points[:21, 0], 0.0) and points[20, 2] == pytest.approx(0.5 * 0.27)
    # by the time it is 5 cm ahead it is above 0.2 m; it tops at the step's 0.1 m clearance
    ahead = points[points[:, 0] >= 0.05]
    assert ahead[0, 2] > 0.2
    assert points[:, 2].max() == pytest.approx(0.27, abs=1e-9)
    # the descent alone last: straight down onto the step, from 0.1 m above it
    assert np.allclose(points[80:, 0], 0.45) and points[80, 2] == pytest.approx(0.17 + 0.05)
    # continuous, no jumps between samples
    assert np.abs(np.diff(points, axis=0)).max() < 0.02
    with pytest.raises(ValueError):
        clearing_swing_trajectory(start, end, 1.0, 2.0, rise=0.1, descend=0.1, rise_share=0.5)
