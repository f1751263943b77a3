"""The whole contact pipeline honours its time budget on a goal nothing can reach."""

from __future__ import annotations

import time

import numpy as np

from planner.contact.planner import Endpoint, plan_contact_motion
from planner.result import PlanStatus
from tests.planner.contact.contact_helpers import character_and_data, plan_into_the_pen, scene


def test_unreachable_goal_answers_within_one_and_a_half_seconds() -> None:
    clock = time.monotonic()
    result = plan_into_the_pen(seed=3)  # the goal stands inside four 2.5 m walls
    elapsed = time.monotonic() - clock
    assert result.status in (PlanStatus.TIMEOUT, PlanStatus.INFEASIBLE), result.message
    assert result.value is not None and len(result.value.states) == 1  # the start, kept
    assert elapsed < 1.5


def test_a_long_plan_answers_within_its_budget_with_what_it_found() -> None:
    """The search stops at its share of the budget; keyframes use the rest."""
    character, data = character_and_data("humanoid")
    clock = time.monotonic()
    result = plan_contact_motion(
        scene("stairs"),
        character,
        data,
        Endpoint(stand_at=np.array([0.4, 0.0, 0.0])),
        Endpoint(stand_at=np.array([3.1, 0.0, 0.9])),
        rng=np.random.default_rng(1),
        time_budget_s=1.5,
    )
    elapsed = time.monotonic() - clock
    assert elapsed < 1.5 + 0.3  # one IK solve may finish after the deadline
    assert result.status in (PlanStatus.APPROXIMATE, PlanStatus.SOLVED, PlanStatus.TIMEOUT)
    plan = result.value
    assert plan is not None and len(plan.states) > 1  # partial plans are kept
    assert plan.motion is not None and plan.motion.keyframes
