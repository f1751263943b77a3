"""The length that times a swing (``spec.swing_length``): its straight distance, plus its rise
along the contact normals beyond ``SWING_RISE_FREE`` weighted ``SWING_RISE_WEIGHT`` and its drop
beyond ``SWING_DROP_FREE`` weighted ``SWING_DROP_WEIGHT``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.motion import tuning
from planner.motion.spec import swing_length

UP = np.array([0.0, 0.0, 1.0])
coordinate = st.floats(-1.0, 1.0, allow_nan=False)
point = st.tuples(coordinate, coordinate, coordinate).map(np.array)


@settings(max_examples=200, deadline=None)
@given(point, st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_a_step_on_level_ground_counts_its_distance(start, dx, dy) -> None:  # type: ignore[no-untyped-def]
    end = start + np.array([dx, dy, 0.0])
    assert swing_length(start, end, [UP]) == pytest.approx(float(np.hypot(dx, dy)))


@settings(max_examples=200, deadline=None)
@given(point, st.floats(0.0, 0.5), st.floats(0.0, 0.5), st.booleans())
def test_a_step_up_counts_its_rise_and_a_step_down_its_drop_beyond_their_free_heights(  # type: ignore[no-untyped-def]
    start, forward, rise, down
) -> None:
    end = start + np.array([forward, 0.0, -rise if down else rise])
    if down:
        extra = tuning.SWING_DROP_WEIGHT * max(0.0, rise - tuning.SWING_DROP_FREE)
    else:
        extra = tuning.SWING_RISE_WEIGHT * max(0.0, rise - tuning.SWING_RISE_FREE)
    length = swing_length(start, end, [UP])
    assert length == pytest.approx(float(np.hypot(forward, rise)) + extra)
    assert length >= float(np.linalg.norm(end - start)) - 1e-12


@settings(max_examples=100, deadline=None)
@given(point, st.floats(0.0, 1.0))
def test_a_hand_moving_along_a_wall_does_not_rise_off_it(start, up) -> None:  # type: ignore[no-untyped-def]
    wall = np.array([-1.0, 0.0, 0.0])  # the wall's normal, horizontal
    end = start + np.array([0.0, 0.0, up])
    assert swing_length(start, end, [wall]) == pytest.approx(up)


def test_the_steeper_normal_counts() -> None:
    start, end = np.zeros(3), np.array([0.3, 0.0, 0.4])
    tilted = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5)])
    assert swing_length(start, end, [UP, tilted]) == swing_length(start, end, [UP])
    assert swing_length(start, end, []) == pytest.approx(0.5)


def test_a_stair_down_is_timed_longer_than_its_distance() -> None:
    """The humanoid's stair down (0.3 m on, 0.15 m down) counts its drop beyond the free
    height: 0.335 m of distance and 0.4 m more."""
    start, end = np.zeros(3), np.array([-0.3, 0.0, -0.15])
    distance = float(np.linalg.norm(end))
    assert swing_length(start, end, [UP]) == pytest.approx(
        distance + tuning.SWING_DROP_WEIGHT * (0.15 - tuning.SWING_DROP_FREE)
    )
    assert swing_length(start, end, [UP]) > 2 * distance
