"""Unit tests of the contact-sequence walker helpers and parameters."""

from __future__ import annotations

import numpy as np
import pytest

from planner.contact.sequence import SequenceParams, _heading, _toward


def _line(n: int, step: float) -> np.ndarray:
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = np.arange(n) * step
    poses[:, 2, 3] = 0.9
    return poses


def test_params_validated() -> None:
    with pytest.raises(ValueError):
        SequenceParams(spacing=0.0)
    with pytest.raises(ValueError):
        SequenceParams(max_states=0)
    assert SequenceParams().stride > 0


def test_heading_is_unit_and_horizontal() -> None:
    poses = _line(10, 0.05)
    poses[:, 2, 3] = np.linspace(0.9, 1.2, 10)  # climbing path
    h = _heading(poses, 3)
    assert h[2] == 0.0
    assert np.isclose(np.linalg.norm(h), 1.0)
    assert h[0] > 0.99


def test_heading_of_a_standing_path_follows_the_root_axis() -> None:
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    assert np.allclose(_heading(poses, 1), [1.0, 0.0, 0.0])


def test_toward_limits_the_root_jump() -> None:
    q = np.zeros(10)
    q[:3] = [0.0, 0.0, 0.8]
    q[6] = 1.0
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.0, 0.9]
    out = _toward(q, pose, 0.05)
    assert np.isclose(np.linalg.norm(out[:3, 3] - q[:3]), 0.075)
    near = np.eye(4)
    near[:3, 3] = [0.03, 0.0, 0.8]
    assert np.allclose(_toward(q, near, 0.05), near)
