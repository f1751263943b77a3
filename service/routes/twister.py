"""The interactive one-step mode (the Twister game): make or break one contact."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import Response

from service.deps import RegistryDep
from service.interactive import BUSY_RESPONSES
from service.routes.results import (
    RESULT_RESPONSES,
    FormatQuery,
    OverlaysQuery,
    SceneQuery,
    draw_seed,
    run_answer,
    stored_answer,
)
from service.schemas import ErrorBody, TwisterStepRequest, TwisterStepResponse

router = APIRouter(prefix="/v1/twister", tags=["twister"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character or scene"},
    422: {"model": ErrorBody, "description": "invalid request"},
    **BUSY_RESPONSES,
}
GRACE_S = 15.0


@router.post("/step", responses=_ERRORS, response_model=TwisterStepResponse)
async def twister_step(body: TwisterStepRequest, request: Request) -> Response:
    """One move: ``create`` or ``break`` a limb's contact, or ``auto`` (the game picks).

    A move that cannot be made answers 200 with status INFEASIBLE and a ``failure`` saying
    why (nothing reachable, not balanced, collision); the state is then unchanged.
    """
    seed = body.seed if body.seed is not None else draw_seed()
    return await run_answer(
        request,
        "step",
        body,
        seed,
        budget_s=body.time_budget_s,
        answer_within_s=body.time_budget_s + GRACE_S,
    )


@router.get("/steps/{step_id}", responses=RESULT_RESPONSES, response_model=TwisterStepResponse)
async def get_step(
    step_id: str,
    request: Request,
    registry: RegistryDep,
    format: FormatQuery = None,
    scene: SceneQuery = False,
    overlays: OverlaysQuery = False,
) -> Any:
    """A stored Twister step by id: JSON, or ``/v1/twister/steps/{id}.glb`` (glTF 2.0)."""
    return await stored_answer(
        request, registry, "step", step_id, format, scene, overlays, TwisterStepResponse
    )
