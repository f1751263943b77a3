"""Contact plans: start and goal in, contact phases, COM curve and keyframes out."""

from __future__ import annotations

import secrets
from typing import Any

from fastapi import APIRouter, Request

from service import compute
from service.schemas import ErrorBody, PlanRequest, PlanResponse

router = APIRouter(prefix="/v1", tags=["plans"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character or scene"},
    422: {"model": ErrorBody, "description": "invalid request"},
    504: {"model": ErrorBody, "description": "the worker did not answer in time"},
}
GRACE_S = 15.0  # beyond the plan's own budget: keyframes, start-up of a fresh worker


@router.post("/plans", responses=_ERRORS)
async def create_plan(body: PlanRequest, request: Request) -> PlanResponse:
    """Plan a multi-contact motion; the answer's ``status`` says how it went (always 200)."""
    seed = body.seed if body.seed is not None else secrets.randbits(63)
    answer = await request.app.state.pool.run(
        compute.run_plan,
        body.model_dump_json(),
        seed,
        timeout_s=1.5 * body.time_budget_s + GRACE_S,
    )
    return PlanResponse.model_validate(answer)
