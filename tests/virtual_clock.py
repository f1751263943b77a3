"""A virtual clock for deadline tests: every read of the planner's monotonic clock
(``planner.termination``) advances it by a fixed tick, so a deadline fires after the same
number of polls on any machine, busy or quiet, and the answer does not depend on speed."""

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
