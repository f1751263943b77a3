"""Jobs: long work running in the background (roadmap builds, asynchronous plans), read and
cancelled from any service worker."""

from __future__ import annotations

from typing import Any

from anyio import to_thread
from fastapi import APIRouter, Request

from service.errors import ApiError, not_found
from service.job_runner import JobRunner
from service.jobs import Job, JobStore
from service.schemas import ErrorBody, JobResult, JobStatus

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])
MAX_ID_LENGTH = 128
STORE_BUSY: dict[str, Any] = {
    "model": ErrorBody,
    "description": "the job store stayed locked by another process (store_busy), with Retry-After",
    "headers": {"Retry-After": {"description": "seconds to wait", "schema": {"type": "integer"}}},
}
JOB_404: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown job"},
    503: STORE_BUSY,
}
CANCEL_RESPONSES: dict[int | str, dict[str, Any]] = {
    **JOB_404,
    409: {"model": ErrorBody, "description": "the job has already finished"},
}


def job_status(job: Job) -> JobStatus:
    """The API's view of a stored job."""
    return JobStatus(
        id=job.id,
        kind=job.kind,
        status=job.state,
        progress=1.0 if job.state == "done" else job.progress,
        message=job.message,
        result=None if job.result is None else JobResult.model_validate(job.result),
        created_at=job.created_at,
        started_at=job.started_at,
        finished_at=job.finished_at,
    )


def runner_of(request: Request) -> JobRunner:
    """This service worker's job runner."""
    runner: JobRunner = request.app.state.jobs
    return runner


async def find_job(request: Request, job_id: str, field: str) -> Job:
    """The stored job, or a 404 naming ``field``."""
    if not job_id.isalnum() or len(job_id) > MAX_ID_LENGTH:
        raise not_found("job", job_id, field)
    store: JobStore = runner_of(request).store
    job = await to_thread.run_sync(store.get, job_id)
    if job is None:
        raise not_found("job", job_id, field)
    return job


async def cancel_job(request: Request, job_id: str, field: str) -> Job:
    """Cancel a queued or running job; 404 if unknown, 409 if it has finished."""
    await find_job(request, job_id, field)
    job = await runner_of(request).cancel(job_id)
    if job is None:
        raise not_found("job", job_id, field)
    if job.state != "cancelled":
        message = f"job {job_id} is {job.state}; only queued or running jobs can be cancelled"
        raise ApiError(409, "job_finished", message, field)
    return job


@router.get("/{job_id}", responses=JOB_404)
async def get_job(job_id: str, request: Request) -> JobStatus:
    """A job's status, progress in [0, 1] and, once done, where its result is."""
    return job_status(await find_job(request, job_id, "job_id"))


@router.delete("/{job_id}", responses=CANCEL_RESPONSES)
async def delete_job(job_id: str, request: Request) -> JobStatus:
    """Cancel a queued or running job (whichever service worker runs it stops it and frees
    its process); answers the job, now ``cancelled``."""
    return job_status(await cancel_job(request, job_id, "job_id"))
