"""Ballistic jumps: persistent jump roadmaps (built in the background) and jump plans."""

from __future__ import annotations

import json
from concurrent.futures import Future
from typing import Any

from anyio import to_thread
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from planner.ballistic.planner import RoadmapStore
from service import compute
from service.deps import RegistryDep, SettingsDep
from service.errors import not_found
from service.routes.results import (
    RESULT_RESPONSES,
    FormatQuery,
    OverlaysQuery,
    SceneQuery,
    draw_seed,
    remember,
    stored_answer,
)
from service.schemas import ErrorBody, JumpRequest, JumpResponse, RoadmapRequest, RoadmapStatus

router = APIRouter(prefix="/v1", tags=["jumps"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character, scene or roadmap"},
    422: {"model": ErrorBody, "description": "invalid request"},
}
GRACE_S = 20.0


def _jobs(request: Request) -> dict[str, Future[None]]:
    jobs: dict[str, Future[None]] = request.app.state.roadmap_jobs
    return jobs


def _status(request: Request, store: RoadmapStore, rid: str) -> RoadmapStatus | None:
    if store.exists(rid):
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
    path = compute.status_path(store.directory, rid)
    if not path.exists():
        return None
    try:
        status = json.loads(path.read_text())
    except (OSError, ValueError):
        status = {"status": "running", "progress": 0.0}
    job = _jobs(request).get(rid)
    if status.get("status") in ("queued", "running") and (job is None or job.done()):
        # No live job behind it: the build was cut off (service restart or a dead worker).
        status["status"] = "interrupted"
        status["message"] = "the build stopped before finishing; POST the request again"
    return RoadmapStatus(
        id=rid,
        status=status.get("status", "running"),
        progress=float(status.get("progress", 0.0)),
        message=str(status.get("message", "")),
        seconds=float(status.get("seconds", 0.0)),
    )


@router.post(
    "/roadmaps",
    status_code=202,
    responses={
        **_ERRORS,
        200: {"model": RoadmapStatus, "description": "the roadmap is already built"},
        202: {"model": RoadmapStatus, "description": "queued or building; poll its id"},
    },
)
async def create_roadmap(
    body: RoadmapRequest, request: Request, registry: RegistryDep, settings: SettingsDep
) -> JSONResponse:
    """Start building a jump roadmap (or find the finished one); poll its id for progress."""
    rid = await to_thread.run_sync(compute.roadmap_id, body, registry)
    store = RoadmapStore(settings.roadmaps_path)
    current = _status(request, store, rid)
    if current is None or current.status in ("failed", "interrupted"):
        compute.write_status(store.directory, rid, status="queued", progress=0.0, seconds=0.0)
        job = request.app.state.pool.submit(compute.build_roadmap_job, body.model_dump_json(), rid)
        _jobs(request)[rid] = job
        current = _status(request, store, rid)
    assert current is not None
    code = 200 if current.status == "done" else 202
    return JSONResponse(current.model_dump(mode="json"), status_code=code)


@router.get("/roadmaps/{roadmap_id}", responses={404: _ERRORS[404]})
async def get_roadmap(roadmap_id: str, request: Request, settings: SettingsDep) -> RoadmapStatus:
    """Status (queued, running, done, failed, interrupted), progress in [0, 1] and size."""
    if not roadmap_id.isalnum() or len(roadmap_id) > 64:
        raise not_found("roadmap", roadmap_id, "roadmap_id")
    status = _status(request, RoadmapStore(settings.roadmaps_path), roadmap_id)
    if status is None:
        raise not_found("roadmap", roadmap_id, "roadmap_id")
    return status


@router.post(
    "/jumps",
    responses={
        **_ERRORS,
        503: {"model": ErrorBody, "description": "a planning process died; retry"},
        504: {"model": ErrorBody, "description": "the worker did not answer in time"},
    },
)
async def create_jumps(body: JumpRequest, request: Request) -> JumpResponse:
    """Plan a sequence of ballistic jumps (on a given roadmap, or one built within budget)."""
    seed = body.seed if body.seed is not None else draw_seed()
    answer = await request.app.state.pool.run(
        compute.run_jumps, body.model_dump_json(), seed, timeout_s=body.time_budget_s + GRACE_S
    )
    return JumpResponse.model_validate(await remember(request, "jump", body, seed, answer))


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
