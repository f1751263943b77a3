"""Unit tests of the contact-sequence walker: parameters, gait order and the guide path."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from planner.contact.sequence import (
    ADVANCE_SHARE,
    CLIMB_ADVANCE_SHARE,
    CLIMB_SHARE,
    LOOP_CONTACT_TOLERANCE,
    ROUGH_ADVANCE,
    ROUGH_LOOKAHEAD,
    STRIDE_SHARE,
    SequenceParams,
    _Guide,
    _same_contacts,
    gait_lengths,
    gait_order,
    stuck_count,
)
from planner.contact.state import ContactState, LimbContact


def _line(n: int, step: float) -> np.ndarray:
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = np.arange(n) * step
    poses[:, 2, 3] = 0.9
    return poses


@pytest.mark.parametrize(
    "field, value",
    [
        ("spacing", 0.0),
        ("max_states", 0),
        ("lookahead", 3.0),
        ("advance", 0.0),
        ("jitter", 2.0),
        ("idle_rounds", 0),
        ("loop_visits", 1),
        ("backtracks", -1),
        ("backtracks", 21),
    ],
)
def test_params_out_of_range_are_refused(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        SequenceParams(**{field: value})


def test_gait_order_is_a_crawl_for_four_legs_and_alternates_for_two() -> None:
    legs = {
        "lf": np.array([0.3, 0.2, -0.5]),
        "rf": np.array([0.3, -0.2, -0.5]),
        "lh": np.array([-0.3, 0.2, -0.5]),
        "rh": np.array([-0.3, -0.2, -0.5]),
    }
    assert gait_order(legs, ["lf", "rf", "lh", "rh"]) == ("lh", "lf", "rh", "rf")
    feet = {"l": np.array([0.0, 0.1, -0.9]), "r": np.array([0.0, -0.1, -0.9])}
    assert gait_order(feet, ["r", "l"]) == ("l", "r")


def test_guide_interpolates_positions_and_clamps() -> None:
    guide = _Guide.of(_line(11, 0.1))
    assert np.isclose(guide.length, 1.0)
    assert np.allclose(guide.at(0.25)[:3, 3], [0.25, 0.0, 0.9])
    assert np.allclose(guide.at(-1.0)[:3, 3], [0.0, 0.0, 0.9])
    assert np.allclose(guide.at(5.0)[:3, 3], [1.0, 0.0, 0.9])


@given(st.floats(0.0, 1.0), st.floats(-0.2, 0.2))
def test_guide_progress_is_the_nearest_sample_and_never_far_behind(x: float, y: float) -> None:
    guide = _Guide.of(_line(21, 0.05))
    s = guide.progress(np.array([x, y, 0.9]), 0.0)
    assert abs(s - x) <= 0.025 + 1e-9
    assert guide.progress(np.array([0.0, 0.0, 0.9]), 0.8) >= 0.5 - 1e-9


def test_gait_lengths_scale_with_the_legs_unless_given() -> None:
    """Open-ground strides are a share of the leg length, rough-ground ones fixed and never
    longer; a look-ahead or advance given by the caller is used on any ground."""
    legs = {"left": np.array([0.0, 0.1, -1.0]), "right": np.array([0.0, -0.1, -1.0])}
    gait = gait_lengths(legs, ["left", "right"], SequenceParams())
    assert gait.open_lookahead == pytest.approx(STRIDE_SHARE * np.hypot(0.1, 1.0))
    assert gait.open_advance == pytest.approx(ADVANCE_SHARE * gait.open_lookahead)
    # a biped on its legs alone climbs a tread per step off open ground; with a hand on a
    # rail or a wall, or stuck, it takes the rough lengths
    length = np.hypot(0.1, 1.0)
    assert gait.of(False) == pytest.approx(
        (CLIMB_SHARE * length, CLIMB_ADVANCE_SHARE * CLIMB_SHARE * length)
    )
    assert gait.of(False, stuck=True) == (ROUGH_LOOKAHEAD, ROUGH_ADVANCE)
    handed = gait_lengths(legs, ["left", "right"], SequenceParams(), legs_only=False)
    assert handed.of(False) == (ROUGH_LOOKAHEAD, ROUGH_ADVANCE)
    assert handed.of(True) == gait.of(True)
    short = {k: 0.2 * v for k, v in legs.items()}
    small = gait_lengths(short, ["left", "right"], SequenceParams())
    assert (
        small.rough_lookahead <= small.open_lookahead and small.rough_advance <= small.open_advance
    )
    assert small.of(False) == (small.rough_lookahead, small.rough_advance)  # no climb gait
    given = gait_lengths(legs, ["left", "right"], SequenceParams(lookahead=0.3, advance=0.2))
    assert given.of(True) == given.of(False) == (0.3, 0.2)


def _state(positions: dict[str, tuple[float, float, float]]) -> ContactState:
    contacts = []
    for limb, position in positions.items():
        placement = np.eye(4)
        placement[:3, 3] = position
        contacts.append(
            LimbContact(limb, placement, np.array([position]), np.array([0.0, 0.0, 1.0]), 0.7)
        )
    return ContactState(np.zeros(7), tuple(contacts))


@given(
    st.lists(st.floats(-2.0, 2.0), min_size=6, max_size=6),
    st.floats(0.0, 0.999),
    st.floats(1.001, 3.0),
    st.sampled_from(["a", "b"]),
)
def test_same_contacts_are_the_same_limbs_each_within_the_tolerance(
    coordinates: list[float], near: float, far: float, moved: str
) -> None:
    """The walker's loop test: two states hold the same contacts when the same limbs are in
    contact, in any order, each within ``LOOP_CONTACT_TOLERANCE`` of the other's."""
    a = {"a": tuple(coordinates[:3]), "b": tuple(coordinates[3:])}
    first = _state(a)
    shifted = dict(a)
    x, y, z = a[moved]
    shifted[moved] = (x + near * LOOP_CONTACT_TOLERANCE, y, z)
    assert _same_contacts(first, _state(dict(reversed(list(shifted.items())))))
    shifted[moved] = (x, y, z - far * LOOP_CONTACT_TOLERANCE)
    assert not _same_contacts(first, _state(shifted))
    assert not _same_contacts(first, _state({"a": a["a"]}))
    assert not _same_contacts(first, _state({"a": a["a"], "c": a["b"]}))


def test_a_walk_stays_stuck_until_its_body_moves_on() -> None:
    """The stuck count: back to 0 once the body moved on (with or without a step), unchanged
    after a step alone, one more after a cycle with neither."""
    assert stuck_count(2, moved=True, stepped=False) == 0
    assert stuck_count(2, moved=True, stepped=True) == 0
    assert stuck_count(2, moved=False, stepped=True) == 2
    assert stuck_count(0, moved=False, stepped=True) == 0
    assert stuck_count(2, moved=False, stepped=False) == 3
