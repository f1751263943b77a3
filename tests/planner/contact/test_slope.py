"""Root paths laid along the terrain: pitched for a trunk that may pitch (the hexapod on
steps), level for one that may not when the straight line between its ends leaves its legs'
reach (the humanoid down a flight of stairs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.contact.planner import Endpoint, plan_contact_motion
from planner.contact.root_path import edge_valid
from planner.contact.slope import (
    LEVEL_PITCH,
    body_span,
    follow_slope,
    straight_slope_path,
    terrain_fit,
    terrain_line,
)
from planner.contact.standing import standing_state
from planner.kinematics import frame_placement
from planner.result import PlanStatus
from planner.scene import builtin as b
from tests.planner.contact.contact_helpers import character_and_data, checker, scene

LANE_SLOPE = math.atan(b.CLIMB_RISE / b.CLIMB_DEPTH)  # rad, 34 degrees


def _pitch(pose: np.ndarray) -> float:
    """Nose-up angle (rad) of a root pose (4, 4): its x axis above the horizontal."""
    return float(math.asin(np.clip(pose[2, 0], -1.0, 1.0)))


def _facing_x(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def test_the_hexapod_may_pitch_and_the_humanoid_stays_level() -> None:
    assert character_and_data("hexapod")[0].max_pitch > LEVEL_PITCH
    assert character_and_data("humanoid")[0].max_pitch <= LEVEL_PITCH


def test_terrain_line_is_level_on_flat_ground_and_follows_the_stairs() -> None:
    half_length, half_width, stand = body_span(checker("hexapod", "flat"))
    assert 0.05 < stand < 0.3 and half_length >= 0.3 and half_width > 0.2
    flat = terrain_line(scene("flat"), _facing_x(0.0, 0.0, 0.2), half_length, half_width)
    assert flat is not None
    assert flat[0] == pytest.approx(0.0, abs=1e-9) and flat[1] == pytest.approx(0.0, abs=1e-9)
    # mid-flight on the stairs (0.15 m rises, 0.3 m treads): about half a metre per metre
    x = b.STAIRS_START_X + 2.5 * b.STAIRS_TREAD
    line = terrain_line(scene("stairs"), _facing_x(x, 0.0, 0.6), half_length, half_width)
    assert line is not None
    assert line[1] == pytest.approx(b.STAIRS_RISE / b.STAIRS_TREAD, abs=0.15)


def test_straight_path_up_the_wall_lies_along_the_lane() -> None:
    check = checker("hexapod", "climbing_wall")
    character = check.character
    start, goal = _facing_x(0.4, 0.0, 0.13), _facing_x(3.4, 0.0, 1.53)
    poses = straight_slope_path(check, start, goal, spacing=0.05, max_pitch=character.max_pitch)
    assert poses is not None
    np.testing.assert_allclose(poses[0], start)
    np.testing.assert_allclose(poses[-1], goal)
    assert all(check.is_valid(p) for p in poses)
    pitches = np.array([_pitch(p) for p in poses])
    assert np.all(np.abs(pitches) <= character.max_pitch + 1e-9)
    on_lane = [
        _pitch(p)
        for p in poses
        if b.CLIMB_START_X + 0.5 < p[0, 3] < b.CLIMB_START_X + 0.5 + 3 * b.CLIMB_DEPTH
    ]
    assert on_lane and np.all(np.abs(np.array(on_lane) - LANE_SLOPE) < 0.15)
    heights = poses[1:-1, 2, 3]  # the ends are the given roots, at their own heights
    assert np.all(np.diff(heights) > -0.03)  # climbs, give or take a smoothing wobble


def test_even_ground_is_walked_at_standing_height_and_rough_ground_with_clearance() -> None:
    """The guide stands the trunk at its standing height over even ground (raised over it,
    the hexapod's body rose to the guide at every advance and sank at every step), and a
    few centimetres higher over rough ground, where the terrain strays from its line."""
    flat = checker("hexapod", "flat")
    half_length, half_width, stand = body_span(flat)
    start, goal = _facing_x(0.0, 0.0, stand), _facing_x(1.0, 0.0, stand)
    poses = straight_slope_path(flat, start, goal, spacing=0.05, max_pitch=0.7)
    assert poses is not None
    np.testing.assert_allclose(poses[:, 2, 3], stand, atol=1e-9)
    even = terrain_fit(scene("flat"), _facing_x(0.5, 0.0, stand), half_length, half_width)
    assert even is not None and even[2] == pytest.approx(0.0, abs=1e-9)
    wall = checker("hexapod", "climbing_wall")
    x = b.CLIMB_START_X + 0.5 + b.CLIMB_DEPTH
    rough = terrain_fit(scene("climbing_wall"), _facing_x(x, 0.0, 0.6), half_length, half_width)
    assert rough is not None and rough[2] > 0.01
    line = follow_slope(
        wall,
        np.stack([_facing_x(x + d, 0.0, 0.6 + 0.5 * d) for d in (-0.1, 0.0, 0.1)]),
        max_pitch=0.7,
    )
    height = rough[0]
    pitch = _pitch(line[1])
    assert line[1][2, 3] > height + stand / math.cos(pitch) + 0.03


def test_straight_path_is_refused_when_blocked() -> None:
    """Through the pen's wall there is no straight line: the RRT has to search."""
    check = checker("hexapod", "pen")
    inside, outside = _facing_x(*b.PEN_CENTRE, 0.13), _facing_x(0.0, 0.0, 0.13)
    assert straight_slope_path(check, inside, outside, spacing=0.05, max_pitch=0.7) is None


def test_follow_slope_keeps_the_ends_and_pitches_the_middle() -> None:
    check = checker("hexapod", "climbing_wall")
    xs = np.linspace(0.4, 3.4, 40)
    poses = np.stack([_facing_x(x, 0.0, 0.13 + 1.4 * (x - 0.4) / 3.0) for x in xs])
    laid = follow_slope(check, poses, max_pitch=0.7)
    np.testing.assert_allclose(laid[0], poses[0])
    np.testing.assert_allclose(laid[-1], poses[-1])
    middle = [_pitch(p) for p in laid if 1.6 < p[0, 3] < 2.2]
    assert middle and min(middle) > 0.3


def test_hexapod_stands_along_the_lane() -> None:
    character, data = character_and_data("hexapod")
    x = b.CLIMB_START_X + 2.5 * b.CLIMB_DEPTH
    found = standing_state(
        scene("climbing_wall"),
        character,
        data,
        np.array([x, 0.02, 3 * b.CLIMB_RISE]),
        rng=np.random.default_rng(0),
        yaw=0.0,
        checker=checker("hexapod", "climbing_wall"),
    )
    assert found.status is PlanStatus.SOLVED, found.message
    assert found.value is not None
    root = frame_placement(character.model, found.value.q, 1)
    assert _pitch(root) > 0.3


def test_a_level_trunk_goes_down_the_stairs_at_standing_height_over_each_step() -> None:
    """From the stairs' top landing to the floor, the straight line between the two standing
    roots runs too high over the lower steps for the humanoid's feet (the search then
    wandered): laid over the terrain with no pitch, every pose of the line is level, valid,
    descends, and stands at about the standing height above the steps under it."""
    check = checker("humanoid", "stairs")
    _, _, stand = body_span(check)
    top = b.STAIRS_RISE * b.STAIRS_STEPS  # the top landing
    start = _facing_x(3.1, 0.0, top + stand)
    goal = _facing_x(0.4, 0.0, stand)
    assert not edge_valid(check, start, goal, 0.05)
    poses = straight_slope_path(check, start, goal, spacing=0.05, max_pitch=0.0)
    assert poses is not None
    assert all(check.is_valid(p) for p in poses)
    np.testing.assert_allclose(poses[:, 2, 2], 1.0, atol=1e-9)  # level: z axis vertical
    heights = poses[1:-1, 2, 3]
    # descends, give or take the clearance added where the ground turns rough (the edge)
    assert np.all(np.diff(heights) < 0.07)
    assert heights[0] - heights[-1] > top - 0.1
    on_flight = [
        p[2, 3] - b.STAIRS_RISE * ((p[0, 3] - b.STAIRS_START_X) / b.STAIRS_TREAD)
        for p in poses
        if b.STAIRS_START_X + 0.3 < p[0, 3] < b.STAIRS_START_X + 4 * b.STAIRS_TREAD
    ]
    # over the ramp through the steps' back edges: the standing height, plus at most a rise
    # (the line fitted to the treads) and the clearance over rough ground
    above = np.array(on_flight) - stand
    assert len(above) and np.all(above >= 0.0) and np.all(above <= b.STAIRS_RISE + 0.07)


def test_a_plan_down_the_stairs_walks_the_level_terrain_guide_first() -> None:
    """The humanoid down the stairs: its walk follows the terrain guide (stats
    ``terrain_path``), one tread per step, and the plan is SOLVED."""
    character, data = character_and_data("humanoid")
    top = b.STAIRS_RISE * b.STAIRS_STEPS  # the top landing
    result = plan_contact_motion(
        scene("stairs"),
        character,
        data,
        Endpoint(stand_at=np.array([3.1, 0.0, top])),
        Endpoint(stand_at=np.array([0.4, 0.0, 0.0])),
        rng=np.random.default_rng(1),
        time_budget_s=30.0,
        cap_s=600.0,
    )
    assert result.status is PlanStatus.SOLVED, result.message
    assert result.stats.get("terrain_path") == 1
    assert result.value is not None
    guide = result.value.root_path
    np.testing.assert_allclose(guide[:, 1, 3], 0.0, atol=1e-6)  # straight down the middle
