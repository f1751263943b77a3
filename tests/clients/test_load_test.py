"""The load-test client against a real server (uvicorn on a port), with tiny settings."""

from __future__ import annotations

import asyncio

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
    run_ramp,
)
from tests.live_server import free_port


def test_a_short_ramp_exercises_every_kind(gecko_url: str) -> None:
    settings = Settings(
        mix=parse_mix("step=4,list=2,plan=1,jump=1"),
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
            assert stats["errors"] == {}, (kind, stats["error_examples"])
            total[kind] = total.get(kind, 0) + stats["ok"]
            if stats["ok"]:
                assert 0 < stats["p50_ms"] <= stats["p99_ms"]
                assert stats["per_second"] > 0
    assert set(total) == {"step", "list", "plan", "jump"}
    assert total["step"] > 0 and total["list"] > 0
    table = format_table(levels)  # type: ignore[arg-type]
    assert "concurrency 2" in table and "p99 ms" in table
    print(table)


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
