"""Centroidal cones: axis from the summed normals, smallest mu, explicit force closure."""

from __future__ import annotations

import numpy as np
import pytest

from planner.ballistic.cones import centroidal_cone, centroidal_cones


def test_axis_is_the_normalised_sum_and_mu_the_minimum() -> None:
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]])
    normals = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    cone = centroidal_cone(points, normals, np.array([0.8, 0.5, 1.1]))
    total = normals[0] / 2 + normals[1] / np.sqrt(2) + normals[2]
    assert np.allclose(cone.axis, total / np.linalg.norm(total))
    assert cone.mu == 0.5
    assert not cone.force_closure
    assert np.allclose(cone.centre, points.mean(axis=0))
    assert not cone.axis.flags.writeable


def test_force_closure_is_flagged_with_a_zero_axis() -> None:
    points = np.array([[0.0, -0.3, 1.0], [0.0, 0.3, 1.0]])
    normals = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])  # chimney: opposite walls
    cone = centroidal_cone(points, normals, np.array([1.0, 1.0]))
    assert cone.force_closure
    assert np.all(cone.axis == 0.0)


def test_batched_matches_single_and_handles_padding() -> None:
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(20, 4, 3))
    mus = rng.uniform(0.2, 1.5, (20, 4))
    mask = rng.random((20, 4)) < 0.7
    mask[0] = False
    axes, mu, closure = centroidal_cones(normals, mus, mask)
    assert closure[0] and mu[0] == 0.0
    for i in range(1, 20):
        if not mask[i].any():
            continue
        one = centroidal_cone(np.zeros((mask[i].sum(), 3)), normals[i][mask[i]], mus[i][mask[i]])
        assert np.allclose(axes[i], one.axis) and mu[i] == one.mu


def test_validation() -> None:
    with pytest.raises(ValueError, match="k >= 1"):
        centroidal_cone(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    with pytest.raises(ValueError, match="non-zero"):
        centroidal_cone(np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1))
    with pytest.raises(ValueError, match="non-negative"):
        centroidal_cone(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), -np.ones(1))
