"""The whole contact pipeline honours its time budget on a goal nothing can reach."""

from __future__ import annotations

import numpy as np
import pytest

from planner.contact.planner import Endpoint, plan_contact_motion
from planner.result import PlanStatus
from tests.planner.contact.contact_helpers import character_and_data, plan_into_the_pen, scene
from tests.virtual_clock import virtual_clock


def test_unreachable_goal_answers_within_its_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a virtual clock (every deadline poll is 1 ms), so the same on any machine: the
    search stops at its deadline and nothing keeps polling long after it."""
    with virtual_clock(monkeypatch) as clock:
        result = plan_into_the_pen(seed=3)  # the goal stands inside four 2.5 m walls
    assert result.status in (PlanStatus.TIMEOUT, PlanStatus.INFEASIBLE), result.message
    assert result.value is not None and len(result.value.states) == 1  # the start, kept
    assert clock.now < 1.5 + 0.3


def test_a_long_plan_answers_within_its_budget_with_what_it_found(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The search stops at its share of the budget; keyframes use the rest (virtual clock:
    every deadline poll is 1 ms, the same on any machine)."""
    character, data = character_and_data("humanoid")
    with virtual_clock(monkeypatch) as clock:
        result = plan_contact_motion(
            scene("stairs"),
            character,
            data,
            Endpoint(stand_at=np.array([0.4, 0.0, 0.0])),
            Endpoint(stand_at=np.array([3.1, 0.0, 0.9])),
            rng=np.random.default_rng(1),
            time_budget_s=1.5,
        )
    assert clock.now < 1.5 + 0.3
    assert result.status in (PlanStatus.APPROXIMATE, PlanStatus.SOLVED, PlanStatus.TIMEOUT)
    plan = result.value
    assert plan is not None and len(plan.states) > 1  # partial plans are kept
    assert plan.motion is not None and plan.motion.keyframes
