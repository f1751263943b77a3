"""Ballistic jumps: persistent jump roadmaps (built in the background) and jump plans."""

from __future__ import annotations

import time
from typing import Any

from anyio import to_thread
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, Response

from planner.ballistic.planner import RoadmapStore
from service import compute
from service.deps import RegistryDep, SettingsDep
from service.errors import not_found
from service.interactive import BUSY_RESPONSES
from service.job_runner import JobContext
from service.jobs import Job
from service.quota import QuotaExceeded
from service.roadmap_storage import check_room, quota_exceeded
from service.routes.jobs import (
    CANCEL_RESPONSES,
    STORE_BUSY,
    cancel_job,
    find_job,
    runner_of,
)
from service.routes.results import (
    RESULT_RESPONSES,
    FormatQuery,
    OverlaysQuery,
    SceneQuery,
    draw_seed,
    run_answer,
    stored_answer,
)
from service.schemas import ErrorBody, JumpRequest, JumpResponse, RoadmapRequest, RoadmapStatus

router = APIRouter(prefix="/v1", tags=["jumps"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character, scene or roadmap"},
    422: {"model": ErrorBody, "description": "invalid request"},
}
GRACE_S = 20.0
MAX_ROADMAP_ID = 64


def _done(store: RoadmapStore, rid: str) -> RoadmapStatus | None:
    """The status of a roadmap stored on disk, or None."""
    if not store.exists(rid):
        return None
    info = store.info(rid) or {}
    return RoadmapStatus(
        id=rid,
        status="done",
        progress=1.0,
        nodes=int(info.get("nodes", 0)),
        edges=int(info.get("edges", 0)),
        seconds=float(info.get("build_seconds", 0.0)),
        message="" if info.get("complete", True) else "build stopped before its budget",
    )


def _from_job(job: Job) -> RoadmapStatus:
    result = job.result or {}
    end = job.finished_at if job.finished_at is not None else time.time()
    return RoadmapStatus(
        id=job.id,
        status=job.state,
        progress=1.0 if job.state == "done" else job.progress,
        nodes=int(result.get("nodes", 0)),
        edges=int(result.get("edges", 0)),
        message=job.message,
        seconds=max(0.0, end - job.started_at) if job.started_at is not None else 0.0,
    )


def _roadmap_id(roadmap_id: str) -> str:
    if not roadmap_id.isalnum() or len(roadmap_id) > MAX_ROADMAP_ID:
        raise not_found("roadmap", roadmap_id, "roadmap_id")
    return roadmap_id


@router.post(
    "/roadmaps",
    status_code=202,
    responses={
        **_ERRORS,
        200: {"model": RoadmapStatus, "description": "the roadmap is already built"},
        202: {
            "model": RoadmapStatus,
            "description": "queued or building; poll its Location",
            "headers": {
                "Location": {"description": "/v1/roadmaps/{id}", "schema": {"type": "string"}}
            },
        },
        503: BUSY_RESPONSES[503],
        507: {
            "model": ErrorBody,
            "description": "the stored roadmaps' quota (GECKO_ROADMAPS_QUOTA_BYTES) has no "
            "room for a roadmap of this size",
        },
    },
)
async def create_roadmap(
    body: RoadmapRequest, request: Request, registry: RegistryDep, settings: SettingsDep
) -> JSONResponse:
    """Start building a jump roadmap (or find the finished or running one); a job in the
    background lane whose id is the roadmap's. Poll it; DELETE it to cancel the build, or
    to remove the roadmap once built. A build that would not fit in the roadmaps' quota is
    refused (507) before it starts."""
    rid = await to_thread.run_sync(compute.roadmap_id, body, registry)
    store = RoadmapStore(settings.roadmaps_path)
    done = await to_thread.run_sync(_done, store, rid)
    if done is not None:
        return JSONResponse(done.model_dump(mode="json"), status_code=200)
    try:
        await to_thread.run_sync(
            check_room, settings.roadmaps_path, body.nodes, settings.roadmaps_quota_bytes
        )
    except QuotaExceeded as exc:
        raise quota_exceeded(exc) from exc
    runner = runner_of(request)
    jobs_db = str(settings.jobs_db_path)

    async def work(context: JobContext) -> dict[str, Any]:
        return await runner.lane.run(
            compute.build_roadmap_job,
            body.model_dump_json(),
            rid,
            jobs_db,
            ticket=context.ticket,
            on_start=context.on_start,
        )

    job, _ = await runner.submit(rid, "roadmap", body.model_dump(mode="json"), work)
    return JSONResponse(
        _from_job(job).model_dump(mode="json"),
        status_code=202,
        headers={"Location": f"/v1/roadmaps/{rid}"},
    )


@router.get("/roadmaps/{roadmap_id}", responses={404: _ERRORS[404], 503: STORE_BUSY})
async def get_roadmap(roadmap_id: str, request: Request, settings: SettingsDep) -> RoadmapStatus:
    """Status (queued, running, done, failed, cancelled, interrupted), progress in [0, 1]
    and size; 404 for an unknown roadmap, or one removed with the scene it was built on."""
    rid = _roadmap_id(roadmap_id)
    done = await to_thread.run_sync(_done, RoadmapStore(settings.roadmaps_path), rid)
    if done is not None:
        return done
    job = await find_job(request, rid, "roadmap_id")
    if job.state == "done":  # built, then removed with the scene it was built on
        raise not_found("roadmap", rid, "roadmap_id")
    return _from_job(job)


@router.delete(
    "/roadmaps/{roadmap_id}",
    responses={
        **CANCEL_RESPONSES,
        200: {"model": RoadmapStatus, "description": "the build was cancelled"},
        204: {"description": "the finished roadmap was removed (its bytes freed)"},
    },
)
async def delete_roadmap(roadmap_id: str, request: Request, settings: SettingsDep) -> Response:
    """Cancel a queued or running build (its process is freed at once) and answer its
    status, now ``cancelled``; or remove a finished roadmap (204; its id then answers
    404, as does a second DELETE). A build that ended otherwise (failed, cancelled,
    interrupted) is a 409."""
    rid = _roadmap_id(roadmap_id)
    store = RoadmapStore(settings.roadmaps_path)
    if await to_thread.run_sync(store.delete, rid):
        return Response(status_code=204)
    if (await find_job(request, rid, "roadmap_id")).state == "done":  # removed already
        raise not_found("roadmap", rid, "roadmap_id")
    job = _from_job(await cancel_job(request, rid, "roadmap_id"))
    return JSONResponse(job.model_dump(mode="json"))


@router.post(
    "/jumps",
    responses={
        **_ERRORS,
        **BUSY_RESPONSES,
    },
    response_model=JumpResponse,
)
async def create_jumps(body: JumpRequest, request: Request) -> Response:
    """Plan a sequence of ballistic jumps (on a given roadmap, or one built within budget)."""
    seed = body.seed if body.seed is not None else draw_seed()
    return await run_answer(
        request,
        "jump",
        body,
        seed,
        budget_s=body.time_budget_s,
        answer_within_s=body.time_budget_s + GRACE_S,
    )


@router.get("/jumps/{jump_id}", responses=RESULT_RESPONSES, response_model=JumpResponse)
async def get_jumps(
    jump_id: str,
    request: Request,
    registry: RegistryDep,
    format: FormatQuery = None,
    scene: SceneQuery = False,
    overlays: OverlaysQuery = False,
) -> Any:
    """A stored jump answer by id: JSON, or ``/v1/jumps/{id}.glb`` (glTF 2.0)."""
    return await stored_answer(
        request, registry, "jump", jump_id, format, scene, overlays, JumpResponse
    )
