"""The load-test client against the real app (in process, lifespan run)."""

from __future__ import annotations

import httpx
import pytest

from clients.http import GeckoClient, GeckoError
from clients.load_test import run_load

pytestmark = pytest.mark.anyio


async def test_load_test_reports_every_endpoint(client: httpx.AsyncClient) -> None:
    summary = await run_load(client, requests=30, concurrency=4, duration_s=60)
    assert "/health" in summary
    assert sum(int(s["count"]) for s in summary.values()) == 30
    assert all(s["errors"] == 0 for s in summary.values())
    assert all(s["median_ms"] <= s["p95_ms"] <= s["max_ms"] for s in summary.values())


async def test_load_test_bounds_are_enforced(client: httpx.AsyncClient) -> None:
    with pytest.raises(ValueError, match="requests"):
        await run_load(client, requests=0, concurrency=1, duration_s=1)
    with pytest.raises(ValueError, match="concurrency"):
        await run_load(client, requests=1, concurrency=10_000, duration_s=1)


async def test_typed_client_raises_envelope_errors(client: httpx.AsyncClient) -> None:
    gecko = GeckoClient(client)
    assert (await gecko.health())["status"] == "ok"
    with pytest.raises(GeckoError) as info:
        await gecko.character("nobody")
    assert info.value.status == 404
    assert info.value.field == "character_id"
