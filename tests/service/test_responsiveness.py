"""What keeps the service process (its event loop, ``/health``) responsive under load, checked
without timing anything: no route or dependency hops through FastAPI's thread pool."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterator
from typing import Any

import fastapi.dependencies.utils
import fastapi.routing
import httpx
import pytest
from fastapi import FastAPI
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute

from service.app import create_app
from service.settings import Settings

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
