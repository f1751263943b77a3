"""Contact plans: start and goal in, contact phases, COM curve and keyframes out."""

from __future__ import annotations

import uuid
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from service import compute
from service.deps import RegistryDep
from service.interactive import BUSY_RESPONSES
from service.job_runner import JobContext
from service.routes.jobs import job_status, runner_of
from service.routes.results import (
    RESULT_RESPONSES,
    FormatQuery,
    OverlaysQuery,
    SceneQuery,
    draw_seed,
    remember_answer,
    run_answer,
    stored_answer,
)
from service.schemas import ErrorBody, JobStatus, PlanRequest, PlanResponse

router = APIRouter(prefix="/v1", tags=["plans"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character or scene"},
    422: {"model": ErrorBody, "description": "invalid request"},
    **BUSY_RESPONSES,
    202: {
        "model": JobStatus,
        "description": 'with "async": true, the queued job; poll its Location',
        "headers": {"Location": {"description": "/v1/jobs/{id}", "schema": {"type": "string"}}},
    },
}
GRACE_S = 15.0  # beyond the plan's own budget: keyframes, start-up of a fresh worker
BUDGET_FACTOR = 1.5  # a plan answers within this many budgets (plus the grace) or gets 504


def _answer_within_s(body: PlanRequest) -> float:
    return BUDGET_FACTOR * body.time_budget_s + GRACE_S


@router.post("/plans", responses=_ERRORS, response_model=PlanResponse)
async def create_plan(body: PlanRequest, request: Request) -> Any:
    """Plan a multi-contact motion; the answer's ``status`` says how it went (200). With
    ``"async": true`` the plan is a job instead: 202 at once, ``Location: /v1/jobs/{id}``."""
    seed = body.seed if body.seed is not None else draw_seed()
    if body.run_async:
        return await _plan_job(body, seed, request)
    return await run_answer(
        request,
        "plan",
        body,
        seed,
        budget_s=body.time_budget_s,
        answer_within_s=_answer_within_s(body),
    )


async def _plan_job(body: PlanRequest, seed: int, request: Request) -> JSONResponse:
    runner = runner_of(request)
    state = request.app.state

    async def work(context: JobContext) -> dict[str, Any]:
        answer = await runner.lane.run(
            compute.run_plan,
            body.model_dump_json(),
            seed,
            None,  # a job's budget counts from its start
            ticket=context.ticket,
            run_for_s=_answer_within_s(body),
            on_start=context.on_start,
        )
        answer = await remember_answer(state, "plan", body, seed, answer)
        rid = answer["id"]
        return {"kind": "plan", "id": rid, "url": f"/v1/plans/{rid}", "status": answer["status"]}

    request_json = {**body.model_dump(mode="json"), "seed": seed}
    job, _ = await runner.submit(uuid.uuid4().hex, "plan", request_json, work)
    location = f"/v1/jobs/{job.id}"
    return JSONResponse(
        job_status(job).model_dump(mode="json"), status_code=202, headers={"Location": location}
    )


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
