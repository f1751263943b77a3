"""Equilibrium outlines drawn by the viewer: on flat ground, under gravity alone, the static
COM region is the convex hull of the contact points (the support polygon), whatever the
friction; a lone point foot or no contact draws nothing."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from planner.export import equilibrium_outline
from planner.scene.geometry2d import closest_on_segments

UP = np.array([0.0, 0.0, 1.0])
coordinate = st.floats(-1.0, 1.0, allow_nan=False)


def _patch(x: float, y: float, yaw: float) -> np.ndarray:
    """A 0.2 x 0.1 m foot sole on z = 0, centred at (x, y), turned by yaw rad."""
    corners = np.array([[0.1, 0.05], [-0.1, 0.05], [-0.1, -0.05], [0.1, -0.05]])
    turn = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    return np.column_stack([corners @ turn.T + [x, y], np.zeros(4)])


@given(
    feet=st.lists(
        st.tuples(coordinate, coordinate, st.floats(-np.pi, np.pi)), min_size=1, max_size=3
    ),
    mu=st.floats(0.3, 1.5),
    height=st.floats(-1.0, 2.0),
)
@example(feet=[(0.0, 0.0, 0.0), (0.0, 1.0, 5.960464477539063e-08)], mu=1.0, height=0.0)
def test_flat_ground_outline_is_the_support_polygon(
    feet: list[tuple[float, float, float]], mu: float, height: float
) -> None:
    patches = [_patch(*foot) for foot in feet]
    outline = equilibrium_outline([(p, UP, mu) for p in patches], 60.0, height)
    assert outline.shape[1] == 3 and np.allclose(outline[:, 2], height)
    points = np.vstack(patches)[:, :2]
    hull = ConvexHull(points)
    # Every outline vertex is on the hull (inside it and on one of its edges) ...
    corners = points[hull.vertices]
    inside = hull.equations[:, :2] @ outline[:, :2].T + hull.equations[:, 2:3]
    assert np.all(inside <= 1e-4)
    assert np.all(np.min(np.abs(inside), axis=0) <= 1e-4)
    # ... and every hull vertex is on the outline's boundary: the same polygon (a hull vertex
    # that is all but in line with its neighbours, two soles turned by 6e-8 rad, may be
    # drawn as a point of an outline edge rather than as a vertex of its own)
    ring = outline[:, :2]
    gaps, _, _ = closest_on_segments(corners, ring, np.roll(ring, -1, axis=0))
    assert np.all(gaps <= 1e-3), gaps
    # Counter-clockwise seen from above.
    x, y = outline[:, 0], outline[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0


def test_nothing_to_draw_without_an_area() -> None:
    assert equilibrium_outline([], 60.0, 0.0).shape == (0, 3)
    point_foot = (np.array([[0.0, 0.0, 0.0]]), UP, 0.8)
    assert equilibrium_outline([point_foot], 60.0, 0.0).shape == (0, 3)


def test_unbounded_region_is_clipped_around_the_contacts() -> None:
    """Hands pressing two opposite walls hold the COM anywhere between and along them."""
    left = np.array([[0.0, 0.5, 1.0], [0.1, 0.5, 1.0], [0.1, 0.5, 1.1], [0.0, 0.5, 1.1]])
    right = left * [1.0, -1.0, 1.0]
    walls = [(left, np.array([0.0, -1.0, 0.0]), 1.0), (right, np.array([0.0, 1.0, 0.0]), 1.0)]
    outline = equilibrium_outline(walls, 60.0, 0.0)
    assert len(outline) >= 3
    assert np.ptp(outline[:, 0]) > 1.0  # far beyond the 0.1 m hands, up to the drawing clip
    assert np.all(np.abs(outline[:, :2] - [0.05, 0.0]) <= 3.0 + 1e-6)
