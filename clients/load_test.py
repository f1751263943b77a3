"""Load-test client: bounded concurrent requests against a Gecko server, with latency figures.

Usage::

    python -m clients.load_test --url http://127.0.0.1:8000 --concurrency 8 --requests 200

Every run is bounded in request count and in time (``--duration``), and stops by itself.
Requests cycle through a mix of read endpoints; the summary gives, per endpoint, the count,
errors and the median, p95 and maximum latency in milliseconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import httpx

MAX_REQUESTS = 100_000
MAX_CONCURRENCY = 256
MAX_DURATION_S = 3600.0


@dataclass(slots=True)
class EndpointStats:
    """Latencies (seconds) and error count of one endpoint."""

    latencies: list[float] = field(default_factory=list)
    errors: int = 0

    def summary(self) -> dict[str, float | int]:
        ordered = sorted(self.latencies)
        if not ordered:
            return {"count": 0, "errors": self.errors}
        p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
        return {
            "count": len(ordered),
            "errors": self.errors,
            "median_ms": round(statistics.median(ordered) * 1e3, 3),
            "p95_ms": round(p95 * 1e3, 3),
            "max_ms": round(ordered[-1] * 1e3, 3),
        }


async def default_paths(http: httpx.AsyncClient) -> list[str]:
    """A read mix built from what the server serves: health, characters and scenes."""
    paths = ["/health", "/v1/characters", "/v1/scenes"]
    characters = (await http.get("/v1/characters")).json()
    paths += [f"/v1/characters/{c['id']}" for c in characters[:3]]
    scenes = (await http.get("/v1/scenes")).json()
    paths += [f"/v1/scenes/{s['id']}" for s in scenes[:3]]
    return paths


async def run_load(
    http: httpx.AsyncClient,
    *,
    requests: int,
    concurrency: int,
    duration_s: float,
    paths: Sequence[str] | None = None,
) -> dict[str, dict[str, float | int]]:
    """Send up to ``requests`` GETs with ``concurrency`` workers for at most ``duration_s``."""
    if not 1 <= requests <= MAX_REQUESTS:
        raise ValueError(f"requests must be in [1, {MAX_REQUESTS}]")
    if not 1 <= concurrency <= MAX_CONCURRENCY:
        raise ValueError(f"concurrency must be in [1, {MAX_CONCURRENCY}]")
    if not 0 < duration_s <= MAX_DURATION_S:
        raise ValueError(f"duration must be in (0, {MAX_DURATION_S}] seconds")
    mix = list(paths) if paths else await default_paths(http)
    stats: dict[str, EndpointStats] = {path: EndpointStats() for path in mix}
    deadline = time.monotonic() + duration_s
    counter = iter(range(requests))

    async def worker() -> None:
        for index in counter:
            if time.monotonic() >= deadline:
                return
            path = mix[index % len(mix)]
            start = time.perf_counter()
            try:
                response = await http.get(path)
                ok = response.status_code < 400
            except httpx.HTTPError:
                ok = False
            elapsed = time.perf_counter() - start
            if ok:
                stats[path].latencies.append(elapsed)
            else:
                stats[path].errors += 1

    await asyncio.gather(*(worker() for _ in range(concurrency)))
    return {path: s.summary() for path, s in stats.items()}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    parser.add_argument("--requests", type=int, default=200)
    parser.add_argument("--concurrency", type=int, default=8)
    parser.add_argument("--duration", type=float, default=60.0, help="seconds, at most 3600")
    parser.add_argument("--timeout", type=float, default=30.0, help="per request, seconds")
    args = parser.parse_args(argv)

    async def go() -> dict[str, dict[str, float | int]]:
        async with httpx.AsyncClient(base_url=args.url, timeout=args.timeout) as http:
            return await run_load(
                http,
                requests=args.requests,
                concurrency=args.concurrency,
                duration_s=args.duration,
            )

    try:
        summary = asyncio.run(go())
    except (ValueError, httpx.HTTPError) as exc:
        print(f"load test failed: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(summary, indent=2))
    return 0 if all(s["errors"] == 0 for s in summary.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
