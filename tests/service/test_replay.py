"""Replay: the same plan request and seed give the same body (timings aside) on a quiet
machine and on one whose every core is busy with a CPU-burning neighbour.

The request's budget is small enough that its work budget is what stops the plan (the
contact search stops at its share of the units, keyframes when the rest is spent), so a
plan stopped by the clock would differ under load. The wall-clock cap is set far beyond
(``run_plan``'s ``deadline``), so it cannot bind on any machine: no timing is asserted.
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from service import compute
from service.schemas import PlanRequest
from tests.cpu_burner import cpu_burners

FAR_CAP_S = 600.0  # s: a cap no machine reaches on this plan

RUBBLE = PlanRequest.model_validate(
    {
        "character": "quadruped",
        "scene": "rubble",
        "start": {"stand_at": [-0.3, 1.5, 0.0]},
        "goal": {"stand_at": [2.8, 1.5, 0.0]},
        "seed": 1,
        "time_budget_s": 4,  # 30 s solves it; 4 s of work walks part of the way
    }
)


def _plan(request: PlanRequest) -> dict[str, Any]:
    assert request.seed is not None
    body = compute.run_plan(
        request.model_dump_json(), request.seed, deadline=time.monotonic() + FAR_CAP_S
    )
    return {k: v for k, v in body.items() if k != "timings"}


@pytest.mark.usefixtures("in_process_worker")
def test_same_request_same_body_with_a_cpu_burning_neighbour() -> None:
    quiet = _plan(RUBBLE)
    with cpu_burners() as burning:
        assert burning >= 1
        loaded = _plan(RUBBLE)
    # the work budget, not the clock, stopped it: part of the way, keyframes cut short
    stats = quiet["report"]["stats"]
    assert quiet["report"]["clock_cap_hit"] is False
    assert stats["work_used"] >= stats["work_units"]
    assert quiet["status"] == "APPROXIMATE" and quiet["report"]["cut_short"]
    assert loaded == quiet
