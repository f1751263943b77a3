"""Keyframe times and swing arcs."""

from __future__ import annotations

import numpy as np
import pytest

from planner.kinematics import keyframe_times, swing_arc, swing_trajectory


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
