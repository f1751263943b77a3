"""Contact plans: start and goal in, contact phases, COM curve and keyframes out."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from service import compute
from service.deps import RegistryDep
from service.routes.results import (
    RESULT_RESPONSES,
    FormatQuery,
    OverlaysQuery,
    SceneQuery,
    draw_seed,
    remember,
    stored_answer,
)
from service.schemas import ErrorBody, PlanRequest, PlanResponse

router = APIRouter(prefix="/v1", tags=["plans"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character or scene"},
    422: {"model": ErrorBody, "description": "invalid request"},
    503: {"model": ErrorBody, "description": "a planning process died; retry"},
    504: {"model": ErrorBody, "description": "the worker did not answer in time"},
}
GRACE_S = 15.0  # beyond the plan's own budget: keyframes, start-up of a fresh worker


@router.post("/plans", responses=_ERRORS)
async def create_plan(body: PlanRequest, request: Request) -> PlanResponse:
    """Plan a multi-contact motion; the answer's ``status`` says how it went (always 200)."""
    seed = body.seed if body.seed is not None else draw_seed()
    answer = await request.app.state.pool.run(
        compute.run_plan,
        body.model_dump_json(),
        seed,
        timeout_s=1.5 * body.time_budget_s + GRACE_S,
    )
    return PlanResponse.model_validate(await remember(request, "plan", body, seed, answer))


@router.get("/plans/{plan_id}", responses=RESULT_RESPONSES, response_model=PlanResponse)
async def get_plan(
    plan_id: str,
    request: Request,
    registry: RegistryDep,
    format: FormatQuery = None,
    scene: SceneQuery = False,
    overlays: OverlaysQuery = False,
) -> Any:
    """A stored plan by id: ``/v1/plans/{id}`` (JSON) or ``/v1/plans/{id}.glb`` (glTF 2.0)."""
    return await stored_answer(
        request, registry, "plan", plan_id, format, scene, overlays, PlanResponse
    )
