"""The load-test client against a real server (uvicorn on a port), with tiny settings."""

from __future__ import annotations

import asyncio
import contextlib
import re
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import httpx
import pytest

from clients.http import GeckoClient, GeckoError
from clients.load_test import (
    MEMORY_GROWTH_BYTES,
    SOAK_CONCURRENCY,
    LoadTestError,
    Settings,
    describe,
    format_table,
    main,
    memory_trend,
    parse_levels,
    parse_mix,
    parse_soak,
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


@contextlib.contextmanager
def _wrong_server() -> Iterator[str]:
    """The URL of a ``_WrongServer`` serving in a thread, shut down on exit."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), _WrongServer)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()


def test_wrong_answers_are_counted_with_their_type_and_text(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with _wrong_server() as url:
        args = ["--url", url, "--concurrency", "1,2", "--duration", "1", "--timeout", "10"]
        code = main([*args, "--mix", "step,plan,upload,list", "--seed", "3"])
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


MiB = 2**20


def test_a_soak_runs_one_level_and_checks_its_arguments() -> None:
    assert parse_soak(60, None) == (SOAK_CONCURRENCY, 5.0)
    assert parse_soak(60, "64", sample_every_s=2) == (64, 2.0)
    assert parse_soak(2, "4") == (4, 2.0)  # a short soak: sampled at its end at least
    assert parse_soak(0.2, "4") == (4, 0.5)
    with pytest.raises(LoadTestError, match="one concurrency level, not 2"):
        parse_soak(60, "16,64")
    with pytest.raises(LoadTestError, match=r"--soak must be in \(0, 3600\]"):
        parse_soak(0, None)
    with pytest.raises(LoadTestError, match="--soak must be"):
        parse_soak(float("nan"), None)
    with pytest.raises(LoadTestError, match=r"--sample-every must be in \[0.5, 10\]"):
        parse_soak(10, None, sample_every_s=20)
    with pytest.raises(LoadTestError, match="--sample-every"):
        parse_soak(10, None, sample_every_s=0.1)


def test_a_soak_summary_says_whether_memory_grew() -> None:
    idle = {"service": 100 * MiB}
    flat = [
        (0.0, idle),  # before the load: the compute processes start on demand
        (5.0, {"service": 110 * MiB, "interactive": 600 * MiB}),
        (10.0, {"service": 112 * MiB, "interactive": 640 * MiB}),
        (15.0, {"service": 111 * MiB, "interactive": 605 * MiB}),
    ]
    trend = memory_trend(flat)
    assert trend["reported"] and trend["samples"] == 4
    assert trend["idle"] == 100 * MiB
    assert trend["start"] == 710 * MiB and trend["end"] == 716 * MiB
    assert trend["max"] == 752 * MiB and trend["growth"] == 6 * MiB
    assert trend["grew"] is False
    assert trend["by_process"]["interactive"] == {
        "start": 600 * MiB,
        "end": 605 * MiB,
        "max": 640 * MiB,
    }
    assert trend["settled_growth"] == -36 * MiB  # from t = 10 s, the soak's second half
    leaking = [(t, {"service": 100 * MiB + t * 8 * MiB}) for t in (0.0, 5.0, 10.0, 15.0)]
    trend = memory_trend(leaking)
    assert trend["growth"] == 80 * MiB and trend["settled_growth"] == 40 * MiB
    assert trend["grew"] is True
    assert trend["slope_per_min"] == pytest.approx(8 * 60 * MiB)
    assert trend["settled_slope_per_min"] == pytest.approx(8 * 60 * MiB)
    # A process started on demand early on (the first upload's) is warm-up, not a leak.
    warming = [
        (0.0, idle),
        (5.0, {"service": 110 * MiB, "uploads": 0.0}),
        (10.0, {"service": 110 * MiB, "uploads": 180 * MiB}),
        (15.0, {"service": 111 * MiB, "uploads": 181 * MiB}),
        (20.0, {"service": 111 * MiB, "uploads": 182 * MiB}),
    ]
    trend = memory_trend(warming)
    assert trend["growth"] == 183 * MiB
    assert trend["settled_growth"] == 3 * MiB < MEMORY_GROWTH_BYTES  # from t = 10 s
    assert trend["grew"] is False
    # Small growth is within the tolerance even on a small server.
    assert (
        memory_trend([(0, {"s": MiB}), (1, {"s": 2 * MiB}), (2, {"s": 3 * MiB})])["grew"] is False
    )
    unreported = memory_trend([(0.0, {}), (5.0, {}), (10.0, {})])
    assert unreported == {"samples": 3, "reported": False, "grew": None}


def test_a_soak_is_printed_with_its_memory_and_its_latencies() -> None:
    samples = [
        (0.0, {"service": 100 * MiB}),
        (5.0, {"service": 120 * MiB}),
        (9.0, {"service": 121 * MiB}),
    ]
    level = {
        "concurrency": 16,
        "seconds": 9.0,
        "kinds": {
            "step": {
                "count": 90,
                "ok": 88,
                "per_second": 9.78,
                "p50_ms": 800.0,
                "p99_ms": 1900.0,
                "errors": {"503": 2},
                "error_examples": {"503": "queue_full: ..."},
            }
        },
        "memory_bytes": {"before": samples[0][1], "after": samples[-1][1]},
        "soak": memory_trend(samples),
    }
    table = format_table([level])
    assert re.search(r"^  step +90 +88 +9.78 +800.0 +1900.0  503: 2$", table, re.MULTILINE), table
    assert "soak memory (3 samples): flat: start 120 MiB, end 121 MiB, max 121 MiB" in table
    assert "growth +1.0 MiB" in table and "(idle before the load: 100 MiB)" in table
    assert "second half +1.0 MiB" in table
    assert re.search(r"^    service +start +120  end +121  max +121 MiB$", table, re.MULTILINE)
    unreported = {**level, "soak": memory_trend([(0.0, {}), (5.0, {})])}
    assert "soak memory: not reported (2 samples)" in format_table([unreported])


def test_the_soak_option_runs_one_level_with_memory_samples(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with _wrong_server() as url:
        args = ["--url", url, "--soak", "1.5", "--sample-every", "0.5", "--mix", "list"]
        code = main([*args, "--concurrency", "2", "--timeout", "10"])
        assert main(["--url", url, "--soak", "1", "--concurrency", "1,2"]) == 2
    captured = capsys.readouterr()
    assert code == 0, captured.out
    assert re.search(r"^concurrency 2 \(", captured.out, re.MULTILINE), captured.out
    assert "concurrency 1" not in captured.out
    assert re.search(r"soak memory: not reported \(\d+ samples\)", captured.out), captured.out
    assert "a soak runs one concurrency level, not 2 ('1,2')" in captured.err
