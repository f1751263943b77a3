"""The operator's basics in process: request ids and JSON logs, CORS, gzip."""

from __future__ import annotations

import asyncio
import gzip
import json
import os
import signal
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
from asgi_lifespan import LifespanManager
from prometheus_client.parser import text_string_to_metric_families

from service.app import create_app
from service.settings import Settings

pytestmark = pytest.mark.anyio

STEP = {
    "character": "quadruped",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "break", "limb": "lf_foot"},
    "seed": 3,
}


@asynccontextmanager
async def _serve(settings: Settings) -> AsyncIterator[httpx.AsyncClient]:
    app = create_app(settings)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as http,
    ):
        yield http


def _log_lines(text: str) -> list[dict[str, Any]]:
    """Every line of captured stderr must be one JSON object."""
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def _requests(lines: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [line for line in lines if line["logger"] == "gecko.request"]


async def test_request_ids_and_one_json_line_per_request(
    settings: Settings, capsys: pytest.CaptureFixture[str]
) -> None:
    async with _serve(settings) as http:
        given = await http.get("/health", headers={"X-Request-ID": "game-42.frame:7"})
        fresh = await http.get("/v1/scenes/nowhere")
        for bad in ("has spaces", "x" * 129, "semi;colon", ""):
            refused = await http.get("/health", headers={"X-Request-ID": bad})
            assert refused.headers["x-request-id"] != bad
            assert len(refused.headers["x-request-id"]) == 32
    assert given.headers["x-request-id"] == "game-42.frame:7"
    assert len(fresh.headers["x-request-id"]) == 32
    lines = _log_lines(capsys.readouterr().err)
    # The app's own log lines appear (start-up), as JSON.
    assert any(line["logger"] == "gecko" and "ready" in line["message"] for line in lines)
    requests = _requests(lines)
    assert len(requests) == 6
    health = requests[0]
    assert health["request_id"] == "game-42.frame:7"
    assert health["method"] == "GET"
    assert health["route"] == "/health"
    assert health["status"] == 200
    assert 0 <= health["duration_s"] < 10
    assert health["level"] == "info"
    missing = requests[1]
    assert missing["request_id"] == fresh.headers["x-request-id"]
    assert missing["route"] == "/v1/scenes/{scene_id}"
    assert missing["path"] == "/v1/scenes/nowhere"
    assert (missing["status"], missing["error_code"], missing["error_field"]) == (
        404,
        "not_found",
        "scene_id",
    )


async def test_answer_lines_carry_seed_status_and_timings(
    settings: Settings, capsys: pytest.CaptureFixture[str]
) -> None:
    async with _serve(settings) as http:
        step = await http.post("/v1/twister/step", json=STEP)
        refused = await http.post("/v1/twister/step", json={**STEP, "seed": -1})
    assert step.status_code == 200, step.text
    assert refused.status_code == 422
    lines = _requests(_log_lines(capsys.readouterr().err))
    answered, invalid = lines
    assert answered["route"] == "/v1/twister/step"
    assert answered["request_id"] == step.headers["x-request-id"]
    assert answered["seed"] == 3
    assert answered["kind"] == "step"
    assert answered["answer_status"] == step.json()["status"]
    assert answered["result"] == step.json()["id"]
    assert set(answered["timings"]) == set(step.json()["timings"])
    assert invalid["status"] == 422
    assert invalid["error_field"] == "seed"


async def test_log_level_is_a_setting(
    settings: Settings, capsys: pytest.CaptureFixture[str]
) -> None:
    quiet = settings.model_copy(update={"log_level": "warning"})
    async with _serve(quiet) as http:
        assert (await http.get("/health")).status_code == 200
    assert not _requests(_log_lines(capsys.readouterr().err))
    verbose = settings.model_copy(update={"log_level": "debug"})
    async with _serve(verbose) as http:
        assert (await http.get("/health")).status_code == 200
    assert len(_requests(_log_lines(capsys.readouterr().err))) == 1


async def test_cors_is_off_by_default(client: httpx.AsyncClient) -> None:
    origin = {"Origin": "https://game.example"}
    response = await client.get("/health", headers=origin)
    assert response.status_code == 200
    assert not any(name.startswith("access-control-") for name in response.headers)
    preflight = await client.options(
        "/v1/plans", headers={**origin, "Access-Control-Request-Method": "POST"}
    )
    assert "access-control-allow-origin" not in preflight.headers


async def test_cors_allows_the_configured_origins(settings: Settings) -> None:
    allowed = settings.model_copy(update={"cors_origins": ["https://game.example"]})
    async with _serve(allowed) as http:
        simple = await http.get("/health", headers={"Origin": "https://game.example"})
        assert simple.headers["access-control-allow-origin"] == "https://game.example"
        assert "x-request-id" in simple.headers["access-control-expose-headers"].lower()
        preflight = await http.options(
            "/v1/plans",
            headers={
                "Origin": "https://game.example",
                "Access-Control-Request-Method": "POST",
                "Access-Control-Request-Headers": "content-type",
            },
        )
        assert preflight.status_code == 200
        assert "POST" in preflight.headers["access-control-allow-methods"]
        other = await http.get("/health", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in other.headers
        # Errors carry the headers too, so a browser can read the envelope.
        missing = await http.get("/v1/scenes/nowhere", headers={"Origin": "https://game.example"})
        assert missing.status_code == 404
        assert missing.headers["access-control-allow-origin"] == "https://game.example"


def test_cors_origins_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GECKO_CORS_ORIGINS", "https://a.example, http://localhost:5173/")
    assert Settings().cors_origins == ["https://a.example", "http://localhost:5173"]
    monkeypatch.setenv("GECKO_CORS_ORIGINS", "")
    assert Settings().cors_origins == []
    with pytest.raises(ValueError, match="CORS origin"):
        Settings(cors_origins=["game.example"])


async def test_large_answers_are_gzipped_small_ones_not(client: httpx.AsyncClient) -> None:
    accept = {"Accept-Encoding": "gzip"}
    small = await client.get("/health", headers=accept)
    assert "content-encoding" not in small.headers
    async with client.stream("GET", "/v1/scenes/stairs", headers=accept) as response:
        assert response.headers["content-encoding"] == "gzip"
        raw = b"".join([chunk async for chunk in response.aiter_raw()])
    plain = await client.get("/v1/scenes/stairs", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers
    assert gzip.decompress(raw) == plain.content
    assert len(raw) < len(plain.content)


def test_gzip_threshold_is_a_setting() -> None:
    with pytest.raises(ValueError, match="gzip_minimum_bytes"):
        Settings(gzip_minimum_bytes=-1)


async def _until_dead(pid: int) -> None:
    """Wait until the killed process ``pid`` is a zombie (or gone); Linux's /proc."""
    status = Path(f"/proc/{pid}/status")
    for _ in range(500):
        try:
            if "\tZ" in status.read_text():
                return
        except FileNotFoundError:
            return
        await asyncio.sleep(0.01)
    raise AssertionError(f"process {pid} still alive after SIGKILL")


async def test_a_dead_planning_process_is_replaced_and_counted(settings: Settings) -> None:
    def restarts(text: str) -> float:
        for family in text_string_to_metric_families(text):
            for sample in family.samples:
                if sample.name == "gecko_worker_pool_restarts_total":
                    return sample.value
        raise AssertionError("gecko_worker_pool_restarts_total is missing")

    app = create_app(settings.model_copy(update={"worker_processes": 1}))
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as http,
    ):
        assert (await http.post("/v1/twister/step", json=STEP)).status_code == 200
        assert restarts((await http.get("/metrics")).text) == 0
        lane = app.state.lanes.interactive
        (pid,) = lane.pids()["idle"]
        os.kill(pid, signal.SIGKILL)
        await _until_dead(pid)
        # An idle process that died costs nobody an answer: the next task gets a fresh one.
        again = await http.post("/v1/twister/step", json=STEP)
        assert again.status_code == 200, again.text
        assert restarts((await http.get("/metrics")).text) == 1
        assert lane.pids()["idle"] != [pid]
