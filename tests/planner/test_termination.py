"""Work budgets decide by counted work; their wall-clock cap only binds when passed, and
says so."""

from __future__ import annotations

import pytest

import planner.termination
from planner import budgets
from planner.termination import Deadline, WorkBudget
from tests.virtual_clock import JumpingClock


def _polls_until_stop(budget: WorkBudget, cost: float, limit: float | None = None) -> int:
    stage = budget.stage(cost, limit)
    polls = 1
    while not stage():
        polls += 1
        assert polls < 10_000
    return polls


@pytest.mark.parametrize("jump", [0.0, 0.5, 4.99])
def test_the_work_decides_whatever_the_clock_below_the_cap(
    monkeypatch: pytest.MonkeyPatch, jump: float
) -> None:
    clock = JumpingClock(jump, at=3)  # the deadline is made at read 1: jumps after it
    monkeypatch.setattr(planner.termination, "time", clock)
    budget = WorkBudget(100.0, Deadline(5.0))
    assert _polls_until_stop(budget, 2.5, limit=80.0) == 32  # the search's share
    assert _polls_until_stop(budget, 5.0) == 4  # the 20 units it left
    assert not budget.cap_hit and budget.used == pytest.approx(100.0)
    assert budget.spent() and budget.left() == 0.0


def test_the_cap_stops_the_work_and_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = JumpingClock(5.01, at=10)
    monkeypatch.setattr(planner.termination, "time", clock)
    budget = WorkBudget(100.0, Deadline(5.0))
    polls = _polls_until_stop(budget, 2.5)
    assert polls < 40 and budget.cap_hit
    assert budget.cap is not None and budget.cap.fired
    assert not budget.spent()  # the clock stopped it, with work left


def test_spent_left_and_charge_read_no_clock(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    budget = WorkBudget(10.0, Deadline(5.0))
    clock = JumpingClock(100.0)
    monkeypatch.setattr(planner.termination, "time", clock)
    for _ in range(3):
        assert not budget.spent() and budget.left(4.0) == 4.0
    budget.charge(6.0)  # work done outside a poll: counted, nothing stops
    assert budget.left(4.0) == 0.0 and budget.left() == 4.0
    assert clock.reads == 0 and budget.used == 6.0 and not budget.cap_hit


def test_a_plan_budget_comes_from_the_time_budget_alone() -> None:
    """A request that waited in a queue keeps its work: only its cap is shorter."""
    waited = budgets.plan_budget(4.0, cap_s=1.5)
    fresh = budgets.plan_budget(4.0)
    assert waited.units == fresh.units == budgets.UNITS_PER_SECOND * 4.0
    assert waited.cap is not None and waited.cap.seconds == 1.5
    assert fresh.cap is not None and fresh.cap.seconds == 4.0
