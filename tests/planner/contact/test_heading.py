"""A searched root path turned to face the way it goes: positions, tilt and ends kept, every
pose still accepted by the reduced model, and a trunk that fits only sideways left sideways."""

from __future__ import annotations

from functools import cache

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.contact.heading import EASE_M, MIN_TRAVEL_SHARE, TOLERANCE, face_the_way
from planner.contact.reachability import ReachabilityChecker
from planner.contact.root_path import RootPath, plan_root_path
from planner.poses import pose_matrix
from planner.result import PlanStatus
from planner.shapes import Box, Shape
from planner.termination import Deadline
from tests.planner.contact.contact_helpers import character_and_data, checker, scene
from tests.planner.contact.contact_helpers import standing_pose as stand

SPACING = 0.05  # m between the poses of a resampled path


@cache
def _flat() -> ReachabilityChecker:
    return checker("humanoid", "flat")


def _yaw(poses: np.ndarray) -> np.ndarray:
    return np.arctan2(poses[..., 1, 0], poses[..., 0, 0])


def _angle(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """|a - b| wrapped to [0, pi]."""
    return np.abs((np.asarray(a) - np.asarray(b) + np.pi) % (2.0 * np.pi) - np.pi)


def _resampled(poses: list[np.ndarray], radius: float) -> tuple[np.ndarray, float]:
    path = RootPath.from_poses(np.array(poses), radius)
    out = path.resample(SPACING)
    return out, path.length / (len(out) - 1)


@settings(max_examples=25, deadline=None)
@given(
    start=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),
    heading=st.floats(-np.pi, np.pi),
    length=st.floats(0.5, 3.0),  # inside the flat scene's 10 m square
    yaws=st.tuples(st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi)),
)
def test_a_straight_path_faces_its_direction_between_its_eased_ends(
    start: tuple[float, float],
    heading: float,
    length: float,
    yaws: tuple[float, float],
) -> None:
    check = _flat()
    end = np.array(start) + length * np.array([np.cos(heading), np.sin(heading)])
    a = stand("humanoid", (*start, 0.0), yaw=yaws[0])
    b = stand("humanoid", (float(end[0]), float(end[1]), 0.0), yaw=yaws[1])
    poses, spacing = _resampled([a, b], check.radius)
    out = face_the_way(check, poses, spacing)
    np.testing.assert_array_equal(out[:, :3, 3], poses[:, :3, 3])  # positions kept
    np.testing.assert_allclose(out[:, 2, :3], poses[:, 2, :3], atol=1e-12)  # tilt kept
    np.testing.assert_array_equal(out[[0, -1]], poses[[0, -1]])  # the ends kept
    for rotation in out[:, :3, :3]:
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert check.valid(poses).all()
    assert check.valid(out).all()
    arc = spacing * np.arange(len(out))
    total = arc[-1]
    if total < 2.0 * EASE_M or length < MIN_TRAVEL_SHARE * total:
        # too short to turn and turn back, or a turn on the spot more than a walk
        np.testing.assert_array_equal(out, poses)
        return
    middle = (arc >= EASE_M - 1e-9) & (arc <= total - EASE_M + 1e-9)
    assert (_angle(_yaw(out[middle]), heading) < TOLERANCE + 1e-6).all()
    within = _angle(_yaw(poses), heading) <= TOLERANCE
    np.testing.assert_array_equal(out[within], poses[within])  # near enough: left as is


def test_a_searched_detour_walks_facing_its_way() -> None:
    """The detour around a wall that the root path search finds (random yaws) walks facing
    the way it goes once turned; every pose is still accepted."""
    character, data = character_and_data("humanoid")
    wall: list[tuple[Shape, np.ndarray]] = [
        (Box([0.1, 2.0, 1.5]), pose_matrix(np.array([0.0, -0.8, 1.5])))
    ]
    check = ReachabilityChecker(scene("flat"), character, data, obstacles=wall)
    a, b = stand("humanoid", (-1.5, 0.0, 0.0)), stand("humanoid", (1.5, 0.0, 0.0))
    found = plan_root_path(check, a, b, rng=np.random.default_rng(11), until=Deadline(20.0))
    assert found.status is PlanStatus.SOLVED and found.value is not None
    poses = found.value.resample(SPACING)
    spacing = found.value.length / (len(poses) - 1)
    out = face_the_way(check, poses, spacing)
    assert check.valid(out).all()
    reach = round(0.3 / spacing)
    travel = out[2 * reach :, :2, 3] - out[: -2 * reach, :2, 3]
    along = _angle(_yaw(out[reach:-reach]), np.arctan2(travel[:, 1], travel[:, 0]))
    before = _angle(_yaw(poses[reach:-reach]), np.arctan2(travel[:, 1], travel[:, 0]))
    arc = spacing * np.arange(reach, len(out) - reach)
    inner = (arc >= EASE_M) & (arc <= spacing * (len(out) - 1) - EASE_M)
    assert np.degrees(before[inner].max()) > 30.0  # the search's yaws wander
    assert along[inner].max() < TOLERANCE + np.radians(1.0)


def test_a_trunk_that_fits_only_sideways_stays_sideways() -> None:
    """A corridor narrower than the trunk's width and wider than its depth: a path through
    it sideways keeps its yaw inside and faces the way outside."""
    character, data = character_and_data("humanoid")
    half_gap, length = 0.14, 0.5  # the trunk's box: 0.12 m deep and 0.16 m wide (halves)
    walls: list[tuple[Shape, np.ndarray]] = [
        (Box([length, 0.05, 1.25]), pose_matrix(np.array([0.0, side * (half_gap + 0.05), 1.25])))
        for side in (-1.0, 1.0)
    ]
    check = ReachabilityChecker(scene("flat"), character, data, obstacles=walls)
    sideways = np.pi / 2
    a, b = (
        stand("humanoid", (-2.0, 0.0, 0.0), sideways),
        stand("humanoid", (2.0, 0.0, 0.0), sideways),
    )
    poses, spacing = _resampled([a, b], check.radius)
    assert check.valid(poses).all()
    inside = np.abs(poses[:, 0, 3]) < length
    assert not check.valid(stand("humanoid", (0.0, 0.0, 0.0))[None])[0]  # facing: too wide
    out = face_the_way(check, poses, spacing)
    assert check.valid(out).all()
    np.testing.assert_array_equal(out[inside], poses[inside])
    arc = spacing * np.arange(len(out))
    open_ground = ~inside & (arc >= EASE_M) & (arc <= arc[-1] - EASE_M)
    open_ground &= np.abs(poses[:, 0, 3]) > length + 0.5  # clear of the trunk's reach
    assert open_ground.any()
    assert _angle(_yaw(out[open_ground]), 0.0).max() < TOLERANCE + 1e-6
