"""The admission gate's order: Twister steps (short work) in their own bounded queue, served
before the plans and jumps waiting, and a slot left to them while they keep coming.

A plain :class:`service.lanes.Gate` runs its work in the test's event loop: each piece of
work holds its slot until the test releases it, so every assertion is about order, never
about time (the one wait, for the reservation to lapse, is for an event with a bound).
"""

from __future__ import annotations

import asyncio

import pytest

from service import lanes
from service.errors import ApiError
from service.lanes import Gate, ShortLine
from service.metrics import Metrics

WAIT_S = 30.0  # the longest any wait below may take before the test fails


class _Work:
    """A piece of work in ``gate``: admitted at once, holds a slot until :meth:`finish`."""

    def __init__(self, gate: Gate, started: list[str], name: str, short: bool) -> None:
        self.ticket = gate.admit(short)
        self.done = asyncio.Event()
        self.running = asyncio.Event()

        async def run() -> None:
            await gate.take_slot(None, short)
            started.append(name)
            self.running.set()
            try:
                await self.done.wait()
            finally:
                gate.give_slot(short)
                self.ticket.release()

        self.task = asyncio.create_task(run())

    async def finish(self) -> None:
        self.done.set()
        await asyncio.wait_for(self.task, WAIT_S)


def _gate(slots: int, reserved: int = 0, short_queue: int = 4) -> Gate:
    return Gate(
        "interactive",
        slots=slots,
        queue=4,
        setting="GECKO_INTERACTIVE_QUEUE",
        metrics=Metrics(),
        short=ShortLine(short_queue, "GECKO_STEP_QUEUE", reserved),
    )


async def _settle() -> None:
    for _ in range(5):  # let every task that can run reach its next wait
        await asyncio.sleep(0)


@pytest.mark.anyio
async def test_a_step_waiting_is_served_before_the_plans_waiting() -> None:
    gate, started = _gate(slots=1), []
    jump = _Work(gate, started, "jump", short=False)
    await _settle()
    plan = _Work(gate, started, "plan", short=False)
    step = _Work(gate, started, "step", short=True)
    await _settle()
    assert started == ["jump"] and gate.waiting == 2
    await jump.finish()
    await asyncio.wait_for(step.running.wait(), WAIT_S)
    assert started == ["jump", "step"]  # arrived last, started first
    await step.finish()
    await plan.finish()
    assert started == ["jump", "step", "plan"]
    assert (gate.running, gate.waiting) == (0, 0)


@pytest.mark.anyio
async def test_plans_use_every_slot_until_steps_come_then_leave_them_one() -> None:
    gate, started = _gate(slots=2, reserved=1), []
    # no step yet: two plans run side by side
    first, second = (_Work(gate, started, name, short=False) for name in ("p1", "p2"))
    await _settle()
    assert started == ["p1", "p2"]
    await first.finish()
    await second.finish()
    # a step arrives: from then on plans hold one slot, and a slot stays free for steps
    step = _Work(gate, started, "s1", short=True)
    await step.finish()
    plans = [_Work(gate, started, name, short=False) for name in ("p3", "p4")]
    await _settle()
    assert started[-1] == "p3" and (gate.running, gate.waiting) == (1, 1)
    step = _Work(gate, started, "s2", short=True)
    await _settle()
    assert started[-1] == "s2"  # the slot left free: no wait behind the plan
    await step.finish()
    await plans[0].finish()
    await asyncio.wait_for(plans[1].running.wait(), WAIT_S)
    await plans[1].finish()


@pytest.mark.anyio
async def test_the_reservation_lapses_when_steps_stop(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lanes, "SHORT_DEMAND_S", 0.2)
    gate, started = _gate(slots=2, reserved=1), []
    step = _Work(gate, started, "step", short=True)
    await step.finish()
    plans = [_Work(gate, started, name, short=False) for name in ("p1", "p2")]
    await _settle()
    assert started == ["step", "p1"]  # held back while steps may still come
    # no step since: the second plan takes the free slot without anything else happening
    await asyncio.wait_for(plans[1].running.wait(), WAIT_S)
    assert started == ["step", "p1", "p2"]
    for plan in plans:
        await plan.finish()


@pytest.mark.anyio
async def test_steps_past_their_queue_are_refused_at_once_naming_the_limit() -> None:
    gate, started = _gate(slots=1, short_queue=1), []
    jump = _Work(gate, started, "jump", short=False)
    await _settle()
    waiting = _Work(gate, started, "step", short=True)
    with pytest.raises(ApiError) as refused:
        gate.admit(short=True)
    assert refused.value.status == 503 and refused.value.code == "queue_full"
    assert "GECKO_STEP_QUEUE=1" in refused.value.message
    assert refused.value.headers == {"Retry-After": "1"}
    # the plans' queue is separate: a plan is still admitted
    plan = _Work(gate, started, "plan", short=False)
    await jump.finish()
    await waiting.finish()
    await plan.finish()
    assert started == ["jump", "step", "plan"]


def test_a_gate_keeps_a_slot_for_long_work() -> None:
    with pytest.raises(ValueError, match="reserved"):
        _gate(slots=2, reserved=2)
    assert _gate(slots=1, reserved=0).short.reserved == 0
