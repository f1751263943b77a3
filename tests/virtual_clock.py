"""Virtual clocks for deadline tests, replacing the planner's monotonic clock
(``planner.termination``): one advancing by a fixed tick per read, so a deadline fires after
the same number of polls on any machine, busy or quiet; one standing still, then jumping
ahead at a given read (a machine stalled at that point)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import pytest

import planner.termination


@dataclass(slots=True)
class VirtualClock:
    """``monotonic()`` returns ``now`` and then advances it by ``tick`` seconds."""

    tick: float
    now: float = 0.0
    reads: int = 0

    def monotonic(self) -> float:
        value = self.now
        self.now += self.tick
        self.reads += 1
        return value


@contextmanager
def virtual_clock(monkeypatch: pytest.MonkeyPatch, tick: float = 1e-3) -> Iterator[VirtualClock]:
    """Replace the deadline clock of ``planner.termination`` while the block runs."""
    clock = VirtualClock(tick)
    with monkeypatch.context() as patch:
        patch.setattr(planner.termination, "time", clock)
        yield clock


@dataclass(slots=True)
class JumpingClock:
    """``monotonic()`` stands still, then jumps ``jump`` seconds ahead at read ``at`` (0: the
    first read) and stays there."""

    jump: float
    at: int = 0
    reads: int = 0

    def monotonic(self) -> float:
        self.reads += 1
        return 1000.0 + (self.jump if self.reads > self.at else 0.0)


@contextmanager
def jumping_clock(
    monkeypatch: pytest.MonkeyPatch, jump: float, at: int = 0
) -> Iterator[JumpingClock]:
    """Replace the deadline clock of ``planner.termination`` while the block runs."""
    clock = JumpingClock(jump, at)
    with monkeypatch.context() as patch:
        patch.setattr(planner.termination, "time", clock)
        yield clock
