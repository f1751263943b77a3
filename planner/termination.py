"""Termination conditions that planners poll: deadlines, iteration budgets, work budgets and
their union.

A termination is a callable taking no argument and returning True once the planner must stop.

A search whose answer must replay on any machine is stopped by counted work, never by the
clock: a :class:`WorkBudget` charges a fixed number of work units per poll and says stop once
they are spent, whatever the time. Its wall-clock ``cap`` (a :class:`Deadline`) only keeps
the answer within its time on a very slow or loaded machine; when the cap is what stopped
the work, ``cap_hit`` says so (and the answer may then differ from a replay).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

Termination = Callable[[], bool]


@dataclass(slots=True)
class Deadline:
    """True once ``seconds`` of wall-clock (monotonic) time have passed since creation;
    ``fired`` records whether a poll ever found it passed (the clock decided)."""

    seconds: float
    start: float = field(default_factory=lambda: time.monotonic())  # the module's clock, late-bound
    fired: bool = False

    def __call__(self) -> bool:
        if time.monotonic() - self.start >= self.seconds:
            self.fired = True
        return self.fired

    def remaining(self) -> float:
        """Seconds left, never negative."""
        return max(0.0, self.seconds - (time.monotonic() - self.start))


@dataclass(slots=True)
class IterationBudget:
    """True after it has been polled ``iterations`` times."""

    iterations: int
    used: int = 0

    def __call__(self) -> bool:
        self.used += 1
        return self.used > self.iterations


@dataclass(slots=True)
class WorkBudget:
    """``units`` of work shared by the stages of a plan, under an optional wall-clock ``cap``.

    Each stage polls a termination from :meth:`stage`, which charges the stage's cost per
    poll: the work, counted, decides when a stage stops, so the same inputs stop at the same
    poll on any machine. ``cap`` only bounds the wall-clock time; ``cap_hit`` becomes True
    when a poll found a cap passed before the work was spent (the clock, not the work,
    stopped the stage: a replay may differ).
    """

    units: float
    cap: Deadline | None = None
    used: float = 0.0
    cap_hit: bool = False

    def left(self, limit: float | None = None) -> float:
        """Units left before ``limit`` (units used in all; None: the whole budget)."""
        end = self.units if limit is None else min(limit, self.units)
        return max(0.0, end - self.used)

    def spent(self, limit: float | None = None) -> bool:
        """Whether the work is spent up to ``limit`` (see :meth:`left`); charges nothing,
        reads no clock."""
        return self.left(limit) <= 0.0

    def charge(self, cost: float) -> None:
        """Count ``cost`` units of work done outside any poll (nothing stops here)."""
        self.used += cost

    def poll(self, cost: float, limit: float | None = None, cap: Deadline | None = None) -> bool:
        """Charge ``cost`` units; True when the work is spent up to ``limit`` or, failing
        that, when the cap (``cap``, else the budget's own) has passed."""
        self.used += cost
        if self.spent(limit):
            return True
        deadline = self.cap if cap is None else cap
        if deadline is not None and deadline():
            self.cap_hit = True
            return True
        return False

    def stage(
        self, cost: float, limit: float | None = None, cap: Deadline | None = None
    ) -> Termination:
        """A termination charging ``cost`` units per poll (see :meth:`poll`)."""
        return lambda: self.poll(cost, limit, cap)


def any_of(*conditions: Termination) -> Termination:
    """Stop as soon as any condition says stop (all are polled, so budgets count evenly)."""

    def check() -> bool:
        results = [condition() for condition in conditions]  # poll all: budgets count evenly
        return any(results)

    return check


def never() -> bool:
    """A termination that never fires (use only with a bounded loop)."""
    return False
