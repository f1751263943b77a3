"""Scenes, characters and checkers shared by the reachability / root path / standing tests."""

from __future__ import annotations

from functools import cache

import numpy as np
from numpy.typing import NDArray

from planner.character import Character, get_character
from planner.contact.context import ContactContext, make_context
from planner.contact.planner import ContactPlan, Endpoint, plan_contact_motion
from planner.contact.reachability import ReachabilityChecker
from planner.offline import OfflineData, load_offline_data
from planner.poses import pose_matrix, yaw_matrix
from planner.result import PlanResult, PlanStatus
from planner.scene import Scene, load_builtin_scene
from planner.shapes import Box, Shape
from tests.paths import gecko_cache_dir

FloatArray = NDArray[np.float64]


@cache
def scene(scene_id: str) -> Scene:
    """A built-in scene, BVH from the shared cache."""
    return load_builtin_scene(scene_id, gecko_cache_dir())


@cache
def character_and_data(character_id: str) -> tuple[Character, OfflineData]:
    """A character and its offline data from the shared cache."""
    character = get_character(character_id)
    return character, load_offline_data(character, gecko_cache_dir())


@cache
def checker(character_id: str, scene_id: str) -> ReachabilityChecker:
    """The default reachability checker of a character in a built-in scene."""
    character, data = character_and_data(character_id)
    return ReachabilityChecker(scene(scene_id), character, data)


def standing_pose(
    character_id: str, xyz: tuple[float, float, float], yaw: float = 0.0
) -> FloatArray:
    """(4, 4) root pose of the reference standing posture with its feet at height xyz[2]."""
    character, _ = character_and_data(character_id)
    position = np.array(xyz, dtype=np.float64)
    position[2] += float(character.q_ref[2])
    return pose_matrix(position, yaw_matrix(np.array(yaw)))


def cage(
    centre: tuple[float, float], half: float = 1.0, height: float = 2.5
) -> list[tuple[Shape, FloatArray]]:
    """Four thin walls (boxes, ``height`` m tall) around ``centre``: a trunk cannot get in."""
    cx, cy = centre
    walls: list[tuple[Shape, FloatArray]] = []
    for sign in (-1.0, 1.0):
        walls.append(
            (
                Box([half + 0.05, 0.05, height / 2]),
                pose_matrix(np.array([cx, cy + sign * half, height / 2])),
            )
        )
        walls.append(
            (
                Box([0.05, half + 0.05, height / 2]),
                pose_matrix(np.array([cx + sign * half, cy, height / 2])),
            )
        )
    return walls


@cache
def flat_walk(character_id: str) -> PlanResult[ContactPlan]:
    """The character's plan 1 m straight ahead (+x) on the built-in flat scene, seed 4."""
    character, data = character_and_data(character_id)
    return plan_contact_motion(
        scene("flat"),
        character,
        data,
        Endpoint(stand_at=np.zeros(3)),
        Endpoint(stand_at=np.array([1.0, 0.0, 0.0])),
        rng=np.random.default_rng(4),
        time_budget_s=10.0,
    )


def solved_flat_walk(character_id: str) -> tuple[ContactPlan, ContactContext]:
    """:func:`flat_walk`'s plan, asserted SOLVED, and a contact context of the character in
    the flat scene."""
    character, data = character_and_data(character_id)
    plan = flat_walk(character_id)
    assert plan.status is PlanStatus.SOLVED and plan.value is not None, plan.message
    return plan.value, make_context(scene("flat"), character, data)


def plan_into_the_pen(seed: int, time_budget_s: float = 1.0) -> PlanResult[ContactPlan]:
    """The humanoid's plan from outside the closed ``pen`` scene to a goal inside its walls,
    a goal nothing reaches."""
    character, data = character_and_data("humanoid")
    return plan_contact_motion(
        scene("pen"),
        character,
        data,
        Endpoint(stand_at=np.array([0.0, 0.0, 0.0])),
        Endpoint(stand_at=np.array([3.0, 0.0, 0.0])),
        rng=np.random.default_rng(seed),
        time_budget_s=time_budget_s,
    )
