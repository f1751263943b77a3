"""The load-test client against a real server (uvicorn on a port), with tiny settings."""

from __future__ import annotations

import asyncio
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import httpx
import pytest

from clients.http import GeckoClient, GeckoError
from clients.load_test import (
    LoadTestError,
    Settings,
    describe,
    format_table,
    main,
    parse_levels,
    parse_mix,
    percentile,
    retry_after_s,
    run_ramp,
)
from tests.live_server import free_port


def test_a_short_ramp_exercises_every_kind(gecko_url: str) -> None:
    settings = Settings(
        mix=parse_mix("step=4,list=2,plan=1,jump=1,upload=1"),
        step_budget_s=2.0,
        plan_budget_s=3.0,
        jump_budget_s=3.0,
        roadmap_nodes=60,
        game_length=3,
        timeout_s=120.0,
    )

    async def go() -> list[dict[str, object]]:
        async with httpx.AsyncClient(base_url=gecko_url, timeout=120) as http:
            return await run_ramp(
                http, levels=[1, 2], duration_s=6.0, max_requests=40, settings=settings, seed=5
            )

    levels = asyncio.run(go())
    assert [level["concurrency"] for level in levels] == [1, 2]
    total: dict[str, int] = {}
    for level in levels:
        for kind, stats in level["kinds"].items():  # type: ignore[attr-defined]
            # One planning process: a step may wait out its budget behind a plan, a refusal
            # the service documents (503 queue_timeout); nothing else may fail.
            assert set(stats["errors"]) <= {"503"}, (kind, stats["error_examples"])
            assert "queue_" in stats["error_examples"].get("503", "queue_"), stats
            total[kind] = total.get(kind, 0) + stats["ok"]
            if stats["ok"]:
                assert 0 < stats["p50_ms"] <= stats["p99_ms"]
                assert stats["per_second"] > 0
    assert set(total) == {"step", "list", "plan", "jump", "upload"}
    assert total["step"] > 0 and total["list"] > 0
    for level in levels:
        health: Any = level["health"]
        assert health["errors"] == {} and health["ok"] > 0
        assert 0 < health["p50_ms"] <= health["p99_ms"]
        memory: Any = level["memory_bytes"]
        assert memory["before"]["service"] > 0  # the compute processes start on demand
        assert memory["after"]["service"] > 0 and memory["after"]["interactive"] > 0
    table = format_table(levels)  # type: ignore[arg-type]
    assert "concurrency 2" in table and "p99 ms" in table
    assert re.search(r"^  /health +\d+ +\d+ ", table, re.MULTILINE), table
    assert re.search(r"^  upload +\d+ +\d+ ", table, re.MULTILINE), table
    assert re.search(r"^  memory after: +\d+ MiB \(interactive \d+, ", table, re.MULTILINE)
    # The uploads were deleted again: no load-test scene is left behind.
    scenes = httpx.get(f"{gecko_url}/v1/scenes", timeout=60).json()
    assert not [scene for scene in scenes if scene["name"] == "load-test"]
    print(table)


class _WrongServer(BaseHTTPRequestHandler):
    """A server that says it is healthy, then answers what the API never does: a 500 that
    is not the error envelope, and 200s and 201s whose bodies are not JSON."""

    def _answer(self, status: int, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:  # http.server's naming
        self._answer(200, b'{"status": "ok"}' if self.path == "/health" else b"[]")

    def do_POST(self) -> None:
        self.rfile.read(int(self.headers.get("Content-Length", 0)))
        if self.path.startswith("/v1/plans"):
            self._answer(500, b"")
        elif self.path.startswith("/v1/scenes"):
            self._answer(201, b"<html>not json</html>")
        else:
            self._answer(200, b"{truncated")

    def log_message(self, *args: Any) -> None:
        pass


def test_wrong_answers_are_counted_with_their_type_and_text(
    capsys: pytest.CaptureFixture[str],
) -> None:
    server = ThreadingHTTPServer(("127.0.0.1", 0), _WrongServer)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}"
        args = ["--url", url, "--concurrency", "1,2", "--duration", "1", "--timeout", "10"]
        code = main([*args, "--mix", "step,plan,upload,list", "--seed", "3"])
    finally:
        server.shutdown()
    out = capsys.readouterr().out
    assert code == 1, out  # some requests failed; the run itself did not
    assert re.search(r"^  step +\d+ +0 .*exception: \d+", out, re.MULTILINE), out
    assert "exception: JSONDecodeError: Expecting property name" in out
    assert re.search(r"^  plan +\d+ +0 .*500: \d+", out, re.MULTILINE), out
    assert "500: Internal Server Error" in out  # an empty 500 still says something
    assert re.search(r"^  upload +\d+ +0 .*exception: \d+", out, re.MULTILINE), out
    assert "memory before: not reported" in out
    assert re.search(r"^  /health +\d+ +\d+ ", out, re.MULTILINE), out


def test_a_timeout_says_so(gecko_url: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["--url", gecko_url, "--timeout", "0.0001", "--duration", "1", "--mix", "list"])
    assert code == 2
    message = capsys.readouterr().err
    assert "timed out after 0.0001 s" in message
    assert "GET /health" in message


def test_an_unreachable_server_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    assert main(["--url", url, "--duration", "1", "--mix", "list", "--timeout", "5"]) == 2
    message = capsys.readouterr().err.strip()
    assert message.startswith("load test failed: GET /health: ConnectError")


def test_arguments_are_checked_with_clear_messages() -> None:
    with pytest.raises(LoadTestError, match="unknown kind 'walk'"):
        parse_mix("walk=1")
    with pytest.raises(LoadTestError, match="zero weight"):
        parse_mix("step=0")
    with pytest.raises(LoadTestError, match="concurrency level"):
        parse_levels("1,4,10000")
    with pytest.raises(LoadTestError, match="integers"):
        parse_levels("one")
    assert parse_levels("1,4,16") == [1, 4, 16]
    assert parse_mix("step=3,list") == {"step": 3.0, "list": 1.0}


def test_messages_are_never_empty() -> None:
    assert describe(httpx.ReadTimeout("")) == "timed out (ReadTimeout)"
    assert describe(httpx.ReadTimeout(""), 2.5) == "timed out after 2.5 s (ReadTimeout)"
    assert describe(RuntimeError()) == "RuntimeError"
    assert describe(ValueError("bad")) == "ValueError: bad"


def test_a_refused_user_waits_as_told() -> None:
    def answer(headers: dict[str, str]) -> httpx.Response:
        return httpx.Response(503, headers=headers)

    assert retry_after_s(answer({"Retry-After": "1"})) == 1.0
    assert retry_after_s(answer({"Retry-After": "3600"})) == 10.0  # capped
    assert retry_after_s(answer({"Retry-After": "soon"})) == 0.0
    assert retry_after_s(answer({})) == 0.0


def test_percentiles_are_nearest_rank() -> None:
    values = [float(v) for v in range(1, 101)]
    assert percentile(values, 0.5) == 50.0
    assert percentile(values, 0.99) == 99.0
    assert percentile([3.0], 0.99) == 3.0


async def _typed_client_errors(url: str) -> None:
    async with httpx.AsyncClient(base_url=url) as http:
        gecko = GeckoClient(http)
        assert (await gecko.health())["status"] == "ok"
        with pytest.raises(GeckoError) as info:
            await gecko.character("nobody")
    assert info.value.status == 404
    assert info.value.field == "character_id"


def test_typed_client_raises_envelope_errors(gecko_url: str) -> None:
    asyncio.run(_typed_client_errors(gecko_url))
