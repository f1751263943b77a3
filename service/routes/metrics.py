"""Prometheus metrics of this service process, as text."""

from __future__ import annotations

from anyio import to_thread
from fastapi import APIRouter, Request
from fastapi.responses import Response
from prometheus_client import CONTENT_TYPE_LATEST

from service.metrics import Metrics

router = APIRouter(tags=["health"])


@router.get(
    "/metrics",
    response_class=Response,
    responses={200: {"content": {CONTENT_TYPE_LATEST: {}}, "description": "Prometheus text"}},
)
async def metrics(request: Request) -> Response:
    """Request counts and latencies per route and status, answers by status, planning tasks,
    pool restarts and roadmap builds by state (every uvicorn worker's: see service.metrics).

    Collected in a thread: a scrape reads the job store (SQLite), the scenes directory and,
    with several uvicorn workers, every worker's files (milliseconds, more with many jobs),
    which the event loop (and /health) must not wait for."""
    registry: Metrics = request.app.state.metrics
    text = await to_thread.run_sync(registry.exposition)
    return Response(text, media_type=CONTENT_TYPE_LATEST)
