"""Root path planner: solutions are valid when re-checked edge by edge, seeded, bounded in time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.contact.reachability import ReachabilityChecker
from planner.contact.root_path import (
    RootPath,
    edge_poses,
    first_invalid,
    plan_root_path,
    pose_distance,
    shortcut,
)
from planner.poses import pose_matrix
from planner.result import PlanStatus
from planner.shapes import Box, Shape
from planner.termination import Deadline
from tests.planner.contact.contact_helpers import (
    cage,
    character_and_data,
    checker,
    scene,
    standing_pose,
)
from tests.virtual_clock import virtual_clock

STEP = 0.05


def assert_path_valid(
    check: ReachabilityChecker, path: RootPath, start: np.ndarray, goal: np.ndarray
) -> None:
    """Endpoints kept; every edge re-checked at <= STEP spacing passes the condition."""
    np.testing.assert_allclose(path.poses[0], start, atol=1e-12)
    np.testing.assert_allclose(path.poses[-1], goal, atol=1e-12)
    for i in range(len(path.poses) - 1):
        a, b = path.lengths[i], path.lengths[i + 1]
        k = max(1, math.ceil((b - a) / STEP - 1e-9))
        poses = path.interpolate(np.linspace(a, b, k + 1))
        spacing = [pose_distance(poses[j], poses[j + 1], check.radius) for j in range(k)]
        assert max(spacing) <= STEP + 1e-9
        assert check.valid(poses).all(), f"edge {i} fails"


def _plan(
    check: ReachabilityChecker, start: np.ndarray, goal: np.ndarray, seed: int, budget: float = 20.0
):  # type: ignore[no-untyped-def]
    return plan_root_path(
        check, start, goal, rng=np.random.default_rng(seed), until=Deadline(budget)
    )


def _walled(
    character_id: str, scene_id: str, obstacles: list[tuple[Shape, np.ndarray]]
) -> ReachabilityChecker:
    character, data = character_and_data(character_id)
    return ReachabilityChecker(scene(scene_id), character, data, obstacles=obstacles)


@pytest.mark.parametrize(
    ("character_id", "scene_id", "start", "goal"),
    [
        ("humanoid", "flat", (-2.0, 0.0, 0.0), (2.0, 1.0, 0.0)),
        ("humanoid", "stairs", (0.0, 0.0, 0.0), (3.1, 0.0, 0.9)),
        ("quadruped", "rubble", (-1.5, 0.0, 0.0), (3.6, 0.0, 0.0)),
        ("quadruped", "rubble", (0.5, -2.6, 0.0), (1.5, 2.6, 0.0)),
    ],
)
def test_solved_and_valid(
    character_id: str,
    scene_id: str,
    start: tuple[float, float, float],
    goal: tuple[float, float, float],
) -> None:
    check = checker(character_id, scene_id)
    a, b = standing_pose(character_id, start), standing_pose(character_id, goal, yaw=0.5)
    result = _plan(check, a, b, seed=1)
    assert result.status is PlanStatus.SOLVED
    assert result.value is not None
    assert_path_valid(check, result.value, a, b)


def test_detour_around_a_wall_is_valid_and_seeded() -> None:
    wall: list[tuple[Shape, np.ndarray]] = [
        (Box([0.1, 2.0, 1.5]), pose_matrix(np.array([0.0, -0.8, 1.5])))
    ]
    check = _walled("humanoid", "flat", wall)
    a = standing_pose("humanoid", (-1.5, 0.0, 0.0))
    b = standing_pose("humanoid", (1.5, 0.0, 0.0), yaw=1.0)
    assert not check.valid(np.linspace(a, b, 50)).all()  # the straight line is blocked
    first = _plan(check, a, b, seed=11)
    assert first.status is PlanStatus.SOLVED
    assert first.value is not None
    assert len(first.value.poses) >= 3
    assert_path_valid(check, first.value, a, b)
    second = _plan(check, a, b, seed=11)
    assert second.value is not None
    np.testing.assert_array_equal(first.value.poses, second.value.poses)
    np.testing.assert_array_equal(first.value.lengths, second.value.lengths)


def test_stairs_path_is_reproducible() -> None:
    check = checker("humanoid", "stairs")
    a = standing_pose("humanoid", (0.0, 0.0, 0.0))
    b = standing_pose("humanoid", (3.1, 0.0, 0.9))
    one, two = _plan(check, a, b, seed=5), _plan(check, a, b, seed=5)
    assert one.value is not None and two.value is not None
    np.testing.assert_array_equal(one.value.poses, two.value.poses)


def test_unreachable_goal_stops_at_the_deadline(monkeypatch: pytest.MonkeyPatch) -> None:
    """Virtual clock (every deadline poll is 1 ms): the same number of iterations on any
    machine, and the search stops at its deadline, not at its iteration cap."""
    check = _walled("humanoid", "flat", cage((3.0, 0.0)))
    a = standing_pose("humanoid", (0.0, 0.0, 0.0))
    b = standing_pose("humanoid", (3.0, 0.0, 0.0))
    assert check.is_valid(b)
    with virtual_clock(monkeypatch) as clock:
        result = _plan(check, a, b, seed=2, budget=1.0)
    assert result.status in (PlanStatus.TIMEOUT, PlanStatus.INFEASIBLE)
    assert result.value is None
    assert clock.now < 1.0 + 0.05


def test_invalid_endpoints() -> None:
    check = checker("humanoid", "flat")
    good = standing_pose("humanoid", (0.0, 0.0, 0.0))
    flying = standing_pose("humanoid", (1.0, 0.0, 2.0))
    assert _plan(check, flying, good, seed=0).status is PlanStatus.INVALID_START
    assert _plan(check, good, flying, seed=0).status is PlanStatus.INVALID_GOAL


def test_root_path_interpolation() -> None:
    a = standing_pose("humanoid", (0.0, 0.0, 0.0))
    b = standing_pose("humanoid", (1.0, 0.0, 0.0), yaw=0.5)
    c = standing_pose("humanoid", (1.0, 1.0, 0.0), yaw=0.5)
    path = RootPath.from_poses(np.stack([a, b, c]), radius=0.8)
    assert path.lengths[0] == 0.0
    assert path.length == pytest.approx(1.0 + 1.0)  # max(|dp|, 0.8 * 0.5) = 1 per edge
    np.testing.assert_allclose(path.interpolate(path.lengths), path.poses, atol=1e-12)
    np.testing.assert_allclose(path.interpolate(-1.0), a)
    np.testing.assert_allclose(path.interpolate(10.0), c, atol=1e-12)
    middle = path.interpolate(0.5)
    np.testing.assert_allclose(middle[:3, 3], [0.5, 0.0, a[2, 3]], atol=1e-12)
    yaw = math.atan2(middle[1, 0], middle[0, 0])
    assert yaw == pytest.approx(0.25)
    dense = path.resample(0.05)
    assert len(dense) == 41
    steps = [pose_distance(dense[i], dense[i + 1], 0.8) for i in range(len(dense) - 1)]
    assert max(steps) <= 0.05 + 1e-9


def test_first_invalid_matches_a_full_check() -> None:
    check = checker("humanoid", "climbing_wall")
    a = standing_pose("humanoid", (-1.0, 0.0, 0.0))
    for x in (-0.5, 1.1, 2.5):  # before, inside and past the wall
        poses = edge_poses(a, standing_pose("humanoid", (x, 0.3, 0.0), yaw=0.4), STEP, check.radius)
        ok = check.valid(poses)
        expected = len(poses) if ok.all() else int(np.argmin(ok))
        for stride in (1, 3, 8):
            assert first_invalid(check, poses, stride) == expected


def test_shortcut_keeps_validity_and_never_lengthens() -> None:
    wall: list[tuple[Shape, np.ndarray]] = [
        (Box([0.1, 2.0, 1.5]), pose_matrix(np.array([0.0, -0.8, 1.5])))
    ]
    check = _walled("humanoid", "flat", wall)
    a = standing_pose("humanoid", (-1.5, 0.0, 0.0))
    b = standing_pose("humanoid", (1.5, 0.0, 0.0))
    result = plan_root_path(
        check, a, b, rng=np.random.default_rng(4), until=Deadline(20.0), shortcut_iterations=0
    )
    assert result.value is not None
    raw = result.value
    short = shortcut(check, raw, rng=np.random.default_rng(0), until=Deadline(20.0))
    assert short.length <= raw.length + 1e-9
    assert_path_valid(check, short, a, b)
