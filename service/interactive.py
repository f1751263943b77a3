"""Interactive work (plans, Twister steps, jumps) in the interactive lane, on the request's
clock: its budget counts from its arrival (time queued is deducted), and it stops, freeing
its process, as soon as its client goes away."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from typing import Any, TypeVar

from fastapi import Request
from starlette.types import Receive

from service.context import annotate, arrival_time
from service.errors import ApiError
from service.lanes import Lane
from service.schemas import ErrorBody

T = TypeVar("T")
CLIENT_CLOSED = 499  # the status logged for a request whose client went away (nginx's)


async def _disconnected(receive: Receive) -> None:
    """Return once the client has gone (the server reports ``http.disconnect``)."""
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            return


async def run_interactive(
    request: Request,
    function: Callable[..., T],
    request_json: str,
    seed: int,
    *,
    budget_s: float,
    answer_within_s: float,
    short: bool = False,
) -> T:
    """``function(request_json, seed, deadline)`` in the interactive lane.

    ``deadline`` is the request's arrival plus ``budget_s``: a request still queued then is
    refused (503 ``queue_timeout``); one running past arrival plus ``answer_within_s`` is
    stopped (504). A full queue is a 503 at once; a client that disconnects stops the work.
    ``short`` work (a Twister step) waits in its own queue, served first (:class:`Gate`).
    """
    lane: Lane = request.app.state.lanes.interactive
    arrived = arrival_time()
    deadline = arrived + budget_s
    ticket = lane.admit(short)  # a full queue refuses before anything is started
    work = asyncio.create_task(
        lane.run(
            function,
            request_json,
            seed,
            deadline,
            ticket=ticket,
            start_by=deadline,
            finish_by=arrived + answer_within_s,
            on_start=lambda: annotate(queued_s=round(time.monotonic() - arrived, 6)),
        )
    )
    watcher = asyncio.create_task(_disconnected(request.receive))
    try:
        await asyncio.wait({work, watcher}, return_when=asyncio.FIRST_COMPLETED)
        if work.done():
            return work.result()
        work.cancel()  # the client went away: kill the process, free the slot
        with contextlib.suppress(asyncio.CancelledError, ApiError):
            await work
        raise ApiError(CLIENT_CLOSED, "client_closed", "the client closed the connection")
    finally:
        for task in (work, watcher):
            task.cancel()


RETRY_HEADER = {
    "Retry-After": {"description": "seconds to wait before retrying", "schema": {"type": "integer"}}
}
BUSY_RESPONSES: dict[int | str, dict[str, Any]] = {
    503: {
        "model": ErrorBody,
        "description": "the queue is full (queue_full) or the request waited out its budget "
        "in it (queue_timeout), with Retry-After; or a planning process died (worker_lost)",
        "headers": RETRY_HEADER,
    },
    504: {"model": ErrorBody, "description": "no answer within the time budget"},
}
