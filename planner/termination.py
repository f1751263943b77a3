"""Termination conditions that planners poll: deadlines, iteration budgets, and their union.

A termination is a callable taking no argument and returning True once the planner must stop.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

Termination = Callable[[], bool]


@dataclass(slots=True)
class Deadline:
    """True once ``seconds`` of wall-clock (monotonic) time have passed since creation."""

    seconds: float
    start: float = field(default_factory=lambda: time.monotonic())  # the module's clock, late-bound

    def __call__(self) -> bool:
        return time.monotonic() - self.start >= self.seconds

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


def any_of(*conditions: Termination) -> Termination:
    """Stop as soon as any condition says stop (all are polled, so budgets count evenly)."""

    def check() -> bool:
        results = [condition() for condition in conditions]  # poll all: budgets count evenly
        return any(results)

    return check


def never() -> bool:
    """A termination that never fires (use only with a bounded loop)."""
    return False
