"""What keeps the service process (its event loop, ``/health``) responsive under load, checked
without timing anything: no route or dependency hops through FastAPI's thread pool, the
compute processes run, every thread of them, at the configured lower priority, and what may
wait for a lock or take tens of ms (job store writes, metrics scrapes, stored answers
validated and serialised) runs off the event loop's thread."""

from __future__ import annotations

import asyncio
import inspect
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

import fastapi.dependencies.utils
import fastapi.routing
import httpx
import pytest
from fastapi import FastAPI
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute
from pydantic import TypeAdapter

from service.app import create_app
from service.jobs import SqliteJobStore
from service.lanes import Lane
from service.metrics import Metrics
from service.registry import Registry
from service.routes import scenes as scenes_route
from service.schemas import TwisterStepResponse
from service.settings import Settings
from service.workers import compute_niceness
from tests.live_fixtures import LIVE_PLAN, LIVE_STEP

pytestmark = pytest.mark.anyio


def _calls(dependant: Dependant) -> Iterator[Callable[..., Any]]:
    """The endpoint and every (sub-)dependency FastAPI calls for a route."""
    if dependant.call is not None:
        yield dependant.call
    for sub in dependant.dependencies:
        yield from _calls(sub)


def test_no_route_or_dependency_runs_in_the_thread_pool(settings: Settings) -> None:
    """A plain ``def`` endpoint or dependency runs in FastAPI's thread pool: each request
    then waits for a free thread and for the GIL, and hops back to the loop."""
    app: FastAPI = create_app(settings)
    routes = [route for route in app.routes if isinstance(route, APIRoute)]
    assert routes
    sync = [
        f"{route.path}: {getattr(call, '__qualname__', call)}"
        for route in routes
        for call in _calls(route.dependant)
        if not inspect.iscoroutinefunction(call)
    ]
    assert sync == []


async def test_health_and_listings_never_use_the_thread_pool(
    client: httpx.AsyncClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    hops: list[str] = []

    async def refuse(function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        hops.append(getattr(function, "__qualname__", repr(function)))
        return function(*args, **kwargs)

    monkeypatch.setattr(fastapi.dependencies.utils, "run_in_threadpool", refuse)
    monkeypatch.setattr(fastapi.routing, "run_in_threadpool", refuse)
    for path in ("/health", "/v1/characters", "/v1/characters/humanoid"):
        assert (await client.get(path)).status_code == 200, path
    assert hops == []


def _thread_niceness() -> list[int]:
    """In a compute process: the niceness of each of its threads (Linux)."""
    tasks = os.listdir("/proc/self/task")
    return [os.getpriority(os.PRIO_PROCESS, int(tid)) for tid in tasks]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread niceness: Linux")
async def test_compute_processes_run_every_thread_at_the_configured_niceness(
    settings: Settings,
) -> None:
    nice = 3
    lane = Lane(
        "interactive",
        processes=1,
        queue=0,
        setting="GECKO_INTERACTIVE_QUEUE",
        settings=settings.model_copy(update={"worker_nice": nice}),
        metrics=Metrics(),
    )
    try:
        expected = min(19, os.getpriority(os.PRIO_PROCESS, 0) + nice)
        assert lane.niceness == expected == compute_niceness(nice)
        # Niced as soon as it is started, by the lane: its start-up (imports, registry: a
        # second of CPU) does not compete with the service process. Read at once, while the
        # child is still importing; the lane set it before _spawn returned, so this is no race.
        worker = lane._spawn()
        assert worker.process.pid is not None
        assert os.getpriority(os.PRIO_PROCESS, worker.process.pid) == expected
        lane._idle.append(worker)
        # Every thread of the process runs niced, and the service process itself does not.
        niceness = await lane.run(_thread_niceness)
        assert niceness and set(niceness) == {expected}
        assert os.getpriority(os.PRIO_PROCESS, 0) == expected - nice or expected == 19
    finally:
        lane.shutdown()


async def test_a_job_is_marked_running_off_the_event_loop_thread(
    client: httpx.AsyncClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Marking a job running is a SQLite write that may wait (up to the store's busy
    timeout) for another process's write lock: never on the event loop's thread."""
    loop_thread = threading.get_ident()
    threads: list[int] = []
    start = SqliteJobStore.start

    def recording_start(store: SqliteJobStore, job_id: str) -> bool:
        threads.append(threading.get_ident())
        return start(store, job_id)

    monkeypatch.setattr(SqliteJobStore, "start", recording_start)
    posted = await client.post("/v1/plans", json={**LIVE_PLAN, "async": True})
    assert posted.status_code == 202, posted.text
    location = posted.headers["location"]
    for _ in range(600):
        job = (await client.get(location)).json()
        if job["status"] not in ("queued", "running"):
            break
        await asyncio.sleep(0.1)
    assert job["status"] == "done", job
    assert threads and loop_thread not in threads


async def test_a_metrics_scrape_is_collected_off_the_event_loop_thread(
    client: httpx.AsyncClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    loop_thread = threading.get_ident()
    threads: list[int] = []
    exposition = Metrics.exposition

    def recording_exposition(metrics: Metrics) -> bytes:
        threads.append(threading.get_ident())
        return exposition(metrics)

    monkeypatch.setattr(Metrics, "exposition", recording_exposition)
    scraped = await client.get("/metrics")
    assert scraped.status_code == 200 and b"gecko_http_requests_total" in scraped.content
    assert threads and loop_thread not in threads


async def test_a_stored_answer_is_validated_and_serialised_off_the_event_loop_thread(
    client: httpx.AsyncClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A stored plan of a few MB takes tens of ms to validate and serialise: in a thread.
    The body is what FastAPI's ``response_model`` serialisation gave (by alias)."""
    posted = await client.post("/v1/twister/step", json=LIVE_STEP)
    assert posted.status_code == 200, posted.text
    step_id = posted.json()["id"]
    loop_thread = threading.get_ident()
    threads: list[int] = []
    validate = TwisterStepResponse.model_validate

    def recording_validate(cls: type[TwisterStepResponse], obj: Any) -> TwisterStepResponse:
        threads.append(threading.get_ident())
        return validate(obj)

    monkeypatch.setattr(TwisterStepResponse, "model_validate", classmethod(recording_validate))
    stored = await client.get(f"/v1/twister/steps/{step_id}")
    assert stored.status_code == 200, stored.text
    assert stored.headers["content-type"] == "application/json"
    assert threads and loop_thread not in threads
    expected = TypeAdapter(TwisterStepResponse).dump_json(validate(posted.json()), by_alias=True)
    assert stored.content == expected


async def test_the_scene_listing_takes_two_trips_to_a_thread(
    client: httpx.AsyncClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each trip to a thread waits for a free one and for the GIL (ms under load): the
    listing takes one for the built-in scenes and one for the uploaded ones, whatever their
    number."""
    trips: list[str] = []
    run_sync = scenes_route.to_thread.run_sync

    async def counting(function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        # anyio's run_sync is one function for the whole process: count the listing's trips,
        # not those background tasks (the job store's heartbeat) happen to make meanwhile
        if getattr(function, "__module__", None) == scenes_route.__name__:
            trips.append(getattr(function, "__qualname__", repr(function)))
        return await run_sync(function, *args, **kwargs)

    monkeypatch.setattr(scenes_route.to_thread, "run_sync", counting)
    listed = await client.get("/v1/scenes")
    assert listed.status_code == 200
    assert len(listed.json()) == len(Registry.builtin_scene_ids()) > 1
    assert len(trips) == 2, trips
