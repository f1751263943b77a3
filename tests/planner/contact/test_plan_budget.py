"""The whole contact pipeline: its work budget decides, its wall-clock cap only caps (and
says so), and an answer comes within its time budget on a goal nothing can reach."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from planner.contact.planner import ContactPlan, Endpoint, plan_contact_motion
from planner.result import PlanResult, PlanStatus
from tests.planner.contact.contact_helpers import character_and_data, plan_into_the_pen, scene
from tests.virtual_clock import jumping_clock, virtual_clock


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


def _short_walk() -> PlanResult[ContactPlan]:
    """The humanoid's 0.5 m walk on a 0.5 s budget: the work budget cuts its keyframes."""
    character, data = character_and_data("humanoid")
    return plan_contact_motion(
        scene("flat"),
        character,
        data,
        Endpoint(stand_at=np.array([0.0, 0.0, 0.0])),
        Endpoint(stand_at=np.array([0.5, 0.0, 0.0])),
        rng=np.random.default_rng(1),
        time_budget_s=0.5,
    )


def _answer(result: PlanResult[ContactPlan]) -> tuple[Any, ...]:
    """Everything of a plan but its timings."""
    plan = result.value
    assert plan is not None and plan.motion is not None
    return (
        result.status,
        result.message,
        {k: v for k, v in result.stats.items() if "second" not in k},
        [s.q.tolist() for s in plan.states],
        [(k.t, k.q.tolist(), k.contacts) for k in plan.motion.keyframes],
        plan.motion.report,
    )


def test_the_work_budget_decides_whatever_the_clock_under_the_cap(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A clock standing still, and one jumping to just under the search's cap (80 % of the
    0.5 s) early in the search, give the same plan: the work decides."""
    with jumping_clock(monkeypatch, 0.0):
        still = _short_walk()
    with jumping_clock(monkeypatch, 0.39, at=3):
        late = _short_walk()
    assert still.stats["clock_cap_hit"] is False
    assert still.stats["work_used"] >= still.stats["work_units"]  # the work bound
    assert still.status is PlanStatus.APPROXIMATE and "budget ran out" in still.message
    assert _answer(late) == _answer(still)


def test_a_clock_past_the_cap_stops_the_plan_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with jumping_clock(monkeypatch, 0.6, at=3):  # past the whole cap: the search stops
        capped = _short_walk()
    assert capped.stats["clock_cap_hit"] is True
    assert "wall-clock cap" in capped.message and "replay may differ" in capped.message
    assert capped.stats["work_used"] < capped.stats["work_units"]
