"""Fixtures for HTTP tests: the real app (registry, planners) behind an httpx client."""

from __future__ import annotations

from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import httpx
import pytest
from asgi_lifespan import LifespanManager

from service import workers
from service.app import create_app
from service.settings import Settings
from tests.paths import gecko_cache_dir


@pytest.fixture(scope="session")
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    return Settings(
        home=tmp_path,
        cache_dir=gecko_cache_dir(),
        scenes_dir=tmp_path / "scenes",
        characters="humanoid,quadruped,hexapod",
        max_upload_bytes=2_000_000,
        max_triangles=10_000,
    )


@pytest.fixture
async def client(settings: Settings) -> AsyncIterator[httpx.AsyncClient]:
    app = create_app(settings)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://gecko") as c,
    ):
        yield c


@pytest.fixture
def in_process_worker(monkeypatch: pytest.MonkeyPatch, settings: Settings) -> Iterator[None]:
    """This process serves as a planning worker (its own registry and settings)."""
    monkeypatch.setattr(workers, "_WORKER_SETTINGS", settings)
    monkeypatch.setattr(workers, "_WORKER_REGISTRY", workers.registry_for(settings))
    yield
