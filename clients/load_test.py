"""Load-test client: what users do (Twister games, short plans, jumps, a few uploads,
listings) at a ramp of concurrency levels, with throughput, latency percentiles and errors per
kind of request, /health's latency under that load and the server's memory.

Usage::

    python -m clients.load_test --url http://127.0.0.1:8000 --concurrency 1,4,16,64 --duration 20

Each concurrency level runs for ``--duration`` seconds (or ``--requests`` requests, whichever
comes first) with that many simulated users. A user draws the kind of each request from
``--mix``: ``step`` plays a Twister game (each step passes the previous answer's state back, a
new game after ``--game-length`` steps or a refused move), ``plan`` asks a short walk, ``jump``
plans jumps over the ``gaps`` scene on a roadmap built once before the ramp, ``upload`` uploads
a small terrain mesh (an STL of its own each time) and deletes it again, ``list`` reads a
listing (health, characters, scenes, stored results). Meanwhile a probe in a process of its own
asks ``/health`` every ``HEALTH_INTERVAL_S`` (so that its latencies are the server's, not also
the time this client's event loop spends on the users' answers). The summary gives, per level
and kind, the count, throughput (answers per second), p50 and p99 latency (ms, of the answers
with status < 400) and the errors by HTTP status or by failure (``timeout``, ``connection``,
``exception``), with one message of each (a user refused with ``Retry-After`` waits that long
before its next request, as a client should); then /health's p50 and p99 and the server's
resident memory (its ``gecko_resident_memory_bytes`` metric: the service process and its
compute processes) before and after the level. Every failure says what happened: its type and
its text.

A soak holds one level long and watches the server's memory::

    python -m clients.load_test --soak 60 --concurrency 16

runs the mix at one concurrency (16 unless ``--concurrency`` names another) for 60 s, reads
the server's memory every ``--sample-every`` seconds (5) and prints, besides the level's
figures, the memory before the load (idle: compute processes start on demand), at the first
sample under load (start), at the end and at its maximum, the growth from start to end and
its trend (least-squares slope, MiB per minute), the same over the soak's second half, and
whether it grew: by more than MEMORY_GROWTH_FRACTION and MEMORY_GROWTH_BYTES both over the
second half (the first holds the warm-up: compute processes and caches started on demand).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import multiprocessing
import random
import re
import struct
import sys
import time
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any

import httpx

MAX_REQUESTS = 1_000_000
MAX_CONCURRENCY = 256
MAX_DURATION_S = 3600.0
KINDS = ("step", "plan", "jump", "upload", "list")
DEFAULT_MIX = "step=6,list=2,plan=1,jump=1,upload=0.2"
DEFAULT_LEVELS = "1,4,16,64"
LIST_PATHS = ("/health", "/v1/characters", "/v1/scenes", "/v1/results?limit=20")
ROADMAP_POLL_S = 0.5
HEALTH_INTERVAL_S = 0.1  # the /health probe's period during each level
PROBE_START_S = 60.0  # s the /health probe's process may take to start or to stop
UPLOAD_GRID = 12  # an upload is a 12 x 12 height field: 242 triangles
MEMORY_METRIC = "gecko_resident_memory_bytes"
MAX_RETRY_AFTER_S = 10.0  # the longest a refused user waits before its next request
SOAK_CONCURRENCY = 16  # a soak's level unless --concurrency names another
SOAK_SAMPLE_EVERY_S = 5.0  # a soak reads the server's memory this often
MIN_SAMPLE_EVERY_S = 0.5
MEMORY_GROWTH_FRACTION = 0.01  # a soak's memory "grew" past both of these, over its 2nd half
MEMORY_GROWTH_BYTES = 16 * 2**20

# The workloads: small and quick answers of each kind on the built-in characters and scenes.
STEP_START = {
    "character": "quadruped",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "break", "limb": "lf_foot"},
}
PLAN = {
    "character": "humanoid",
    "scene": "flat",
    "start": {"stand_at": [0.0, 0.0, 0.0]},
    "goal": {"stand_at": [0.4, 0.0, 0.0]},
}
ROADMAP = {"character": "quadruped", "scene": "gaps"}
JUMP = {
    "character": "quadruped",
    "scene": "gaps",
    "start": {"stand_at": [0.75, 0.0, 0.6]},
    "goal": {"stand_at": [8.25, 0.0, 1.0]},
}


def terrain_stl(rng: random.Random, cells: int = UPLOAD_GRID, size_m: float = 3.0) -> bytes:
    """A binary STL of a gently rolling height field, different for each draw of ``rng``
    (so each upload is a new scene, parsed and built)."""
    step = size_m / cells
    heights = [[0.05 * rng.random() for _ in range(cells + 1)] for _ in range(cells + 1)]

    def vertex(i: int, j: int) -> tuple[float, float, float]:
        return (i * step, j * step, heights[i][j])

    triangles = []
    for i in range(cells):
        for j in range(cells):
            a, b, c, d = vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1), vertex(i, j + 1)
            triangles += [(a, b, c), (a, c, d)]
    out = [b"gecko load test terrain".ljust(80, b" "), struct.pack("<I", len(triangles))]
    for triangle in triangles:
        out.append(struct.pack("<12fH", 0.0, 0.0, 1.0, *(x for v in triangle for x in v), 0))
    return b"".join(out)


def retry_after_s(response: httpx.Response) -> float:
    """Seconds a refused request is told to wait (``Retry-After``, capped at
    MAX_RETRY_AFTER_S); 0 without one."""
    try:
        return min(MAX_RETRY_AFTER_S, max(0.0, float(response.headers.get("retry-after", 0))))
    except ValueError:
        return 0.0


def parse_memory(metrics_text: str) -> dict[str, float]:
    """``gecko_resident_memory_bytes`` by process (service, interactive, ...) from Prometheus
    text; empty when the server does not report it."""
    pattern = re.compile(rf'^{MEMORY_METRIC}{{process="([^"]+)"}} ([0-9.eE+-]+)$', re.MULTILINE)
    return {name: float(value) for name, value in pattern.findall(metrics_text)}


class LoadTestError(Exception):
    """The load test could not run (bad arguments, a server that does not answer the set-up)."""


def describe(exc: BaseException, timeout_s: float | None = None) -> str:
    """A message that is never empty: what failed, and how."""
    if isinstance(exc, httpx.TimeoutException):
        limit = f" after {timeout_s:g} s" if timeout_s is not None else ""
        return f"timed out{limit} ({type(exc).__name__})"
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _error_message(response: httpx.Response) -> str:
    try:
        error = response.json()["error"]
        field_name = f" (field {error['field']})" if error.get("field") else ""
        return f"{error['code']}: {error['message']}{field_name}"
    except (ValueError, KeyError, TypeError):
        return response.text[:200] or response.reason_phrase or f"HTTP {response.status_code}"


@dataclass(slots=True)
class KindStats:
    """Latencies (s) of the answers with status < 400, and the failures by status or kind."""

    latencies: list[float] = field(default_factory=list)
    errors: dict[str, int] = field(default_factory=dict)
    examples: dict[str, str] = field(default_factory=dict)

    def fail(self, key: str, message: str) -> None:
        self.errors[key] = self.errors.get(key, 0) + 1
        self.examples.setdefault(key, message)

    def summary(self, seconds: float) -> dict[str, Any]:
        """Count, throughput (answers/s over ``seconds``), p50/p99 (ms) and errors."""
        ordered = sorted(self.latencies)
        out: dict[str, Any] = {
            "count": len(ordered) + sum(self.errors.values()),
            "ok": len(ordered),
            "per_second": round(len(ordered) / seconds, 3) if seconds > 0 else 0.0,
            "errors": dict(sorted(self.errors.items())),
            "error_examples": dict(sorted(self.examples.items())),
        }
        if ordered:
            out["p50_ms"] = round(percentile(ordered, 0.50) * 1e3, 1)
            out["p99_ms"] = round(percentile(ordered, 0.99) * 1e3, 1)
        return out


def percentile(ordered: Sequence[float], fraction: float) -> float:
    """Nearest-rank percentile of sorted values (``fraction`` in [0, 1])."""
    rank = max(1, min(len(ordered), math.ceil(fraction * len(ordered))))
    return ordered[rank - 1]


def parse_mix(text: str) -> dict[str, float]:
    """``"step=6,list=2"`` -> weights by kind; unknown kinds and bad weights are refused."""
    mix: dict[str, float] = {}
    for part in text.split(","):
        name, _, weight = part.strip().partition("=")
        if name not in KINDS:
            raise LoadTestError(f"unknown kind '{name}' in --mix; expected some of {KINDS}")
        try:
            mix[name] = float(weight) if weight else 1.0
        except ValueError:
            message = f"weight of '{name}' in --mix is not a number: '{weight}'"
            raise LoadTestError(message) from None
        if not 0 <= mix[name] <= 1000:
            raise LoadTestError(f"weight of '{name}' in --mix must be in [0, 1000]")
    if sum(mix.values()) <= 0:
        raise LoadTestError("--mix gives every kind a zero weight")
    return mix


def parse_soak(
    seconds: float, concurrency: str | None, sample_every_s: float | None = None
) -> tuple[int, float]:
    """A soak's one concurrency level (SOAK_CONCURRENCY unless ``concurrency`` names one) and
    its memory sampling period (SOAK_SAMPLE_EVERY_S unless given, and at most the soak's
    length), after checking them."""
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_DURATION_S):
        raise LoadTestError(f"--soak must be in (0, {MAX_DURATION_S:g}] seconds, not {seconds:g}")
    longest = max(MIN_SAMPLE_EVERY_S, seconds)
    if sample_every_s is None:
        sample_every_s = min(SOAK_SAMPLE_EVERY_S, longest)
    if not (math.isfinite(sample_every_s) and MIN_SAMPLE_EVERY_S <= sample_every_s <= longest):
        raise LoadTestError(
            f"--sample-every must be in [{MIN_SAMPLE_EVERY_S:g}, {longest:g}] seconds (the "
            f"soak's length), not {sample_every_s:g}"
        )
    if concurrency is None:
        return SOAK_CONCURRENCY, sample_every_s
    levels = parse_levels(concurrency)
    if len(levels) != 1:
        raise LoadTestError(
            f"a soak runs one concurrency level, not {len(levels)} ('{concurrency}')"
        )
    return levels[0], sample_every_s


def memory_trend(samples: Sequence[tuple[float, dict[str, float]]]) -> dict[str, Any]:
    """A soak's memory from its samples ``(seconds since the load began, bytes by process)``:
    the first taken before the load (idle), the others under it, the last after it. Gives
    ``idle``, ``start`` (the first sample under load), ``end``, ``max`` (bytes, all
    processes together), ``growth`` (end - start), ``slope_per_min`` (least squares over
    the samples from start on, bytes per minute), the same per process, and the second half's
    ``settled_growth`` (end - the first sample from the soak's middle on) and
    ``settled_slope_per_min``. ``grew`` judges the second half (None when the server reports
    no memory): the first also holds the warm-up, compute processes and their caches
    started on demand (an uploads process at the first upload, say), which is not a leak."""
    reported = [(t, memory) for t, memory in samples if memory]
    loaded = [(t, memory) for t, memory in reported if t > 0]
    if not loaded:
        return {"samples": len(samples), "reported": False, "grew": None}
    idle = next((memory for t, memory in reported if t <= 0), {})
    start, end = loaded[0][1], loaded[-1][1]
    totals = [(t, sum(memory.values())) for t, memory in loaded]
    middle = loaded[-1][0] / 2
    settled = [(t, total) for t, total in totals if t >= middle]
    settled_growth = settled[-1][1] - settled[0][1]
    tolerance = max(MEMORY_GROWTH_FRACTION * settled[0][1], MEMORY_GROWTH_BYTES)
    names = sorted({name for _, memory in loaded for name in memory})
    return {
        "samples": len(samples),
        "reported": True,
        "idle": sum(idle.values()),
        "start": sum(start.values()),
        "end": sum(end.values()),
        "max": max(total for _, total in totals),
        "growth": sum(end.values()) - sum(start.values()),
        "slope_per_min": _slope(totals) * 60.0,
        "settled_growth": settled_growth,
        "settled_slope_per_min": _slope(settled) * 60.0,
        "grew": settled_growth > tolerance,
        "by_process": {
            name: {
                "start": start.get(name, 0.0),
                "end": end.get(name, 0.0),
                "max": max(memory.get(name, 0.0) for _, memory in loaded),
            }
            for name in names
        },
    }


def _slope(points: Sequence[tuple[float, float]]) -> float:
    """Least-squares slope of y over x (0 with fewer than two distinct x)."""
    if len(points) < 2:
        return 0.0
    mean_x = sum(x for x, _ in points) / len(points)
    mean_y = sum(y for _, y in points) / len(points)
    spread = sum((x - mean_x) ** 2 for x, _ in points)
    if spread == 0:
        return 0.0
    return sum((x - mean_x) * (y - mean_y) for x, y in points) / spread


def parse_levels(text: str) -> list[int]:
    """``"1,4,16"`` -> concurrency levels, each in [1, MAX_CONCURRENCY]."""
    try:
        levels = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise LoadTestError(f"--concurrency must be integers like 1,4,16, not '{text}'") from None
    if not levels or not all(1 <= level <= MAX_CONCURRENCY for level in levels):
        raise LoadTestError(f"each concurrency level must be in [1, {MAX_CONCURRENCY}]")
    return levels


@dataclass(slots=True)
class Settings:
    """What one run asks of the server; the defaults are the real workload."""

    mix: dict[str, float]
    step_budget_s: float = 2.0
    plan_budget_s: float = 5.0
    jump_budget_s: float = 5.0
    roadmap_nodes: int = 300
    game_length: int = 8
    timeout_s: float = 60.0


@dataclass(slots=True)
class User:
    """One simulated user: its random stream and its Twister game in progress."""

    rng: random.Random
    state: dict[str, Any] | None = None
    steps: int = 0


def _probe_health(url: str, timeout_s: float, connection: Connection) -> None:
    """In a process of its own: ask ``url``/health every HEALTH_INTERVAL_S on one connection
    until anything arrives on ``connection``, then send back the KindStats."""
    stats = KindStats()
    with httpx.Client(base_url=url, timeout=timeout_s) as probe:
        connection.send("ready")
        while True:
            sent = time.perf_counter()
            try:
                response = probe.get("/health")
            except httpx.HTTPError as exc:
                key = "timeout" if isinstance(exc, httpx.TimeoutException) else "connection"
                stats.fail(key, describe(exc, timeout_s))
            else:
                if response.status_code < 400:
                    stats.latencies.append(time.perf_counter() - sent)
                else:
                    stats.fail(str(response.status_code), _error_message(response))
            if connection.poll(HEALTH_INTERVAL_S):
                break
    connection.send(stats)


class HealthProbe:
    """/health asked every HEALTH_INTERVAL_S from a process of its own, so that its
    latencies are the server's: in the load test's own event loop they would also count the
    time that loop spends on the simulated users' answers (tens of ms at 64 users)."""

    def __init__(self, url: str, timeout_s: float) -> None:
        self.url = url
        self.timeout_s = timeout_s
        self._process: BaseProcess | None = None
        self._connection: Connection | None = None

    def start(self) -> None:
        """Start the probe's process; returns once it asks (blocking: call it off the loop)."""
        context = multiprocessing.get_context("spawn")
        ours, theirs = context.Pipe()
        process = context.Process(
            target=_probe_health, args=(self.url, self.timeout_s, theirs), daemon=True
        )
        process.start()
        theirs.close()
        self._process, self._connection = process, ours
        try:
            if not ours.poll(PROBE_START_S) or ours.recv() != "ready":
                raise LoadTestError(f"the /health probe did not start within {PROBE_START_S:g} s")
        except (EOFError, OSError) as exc:
            self._close()
            raise LoadTestError(f"the /health probe could not start: {describe(exc)}") from exc
        except LoadTestError:
            self._close()
            raise

    def stop(self) -> KindStats:
        """Stop the probe; its statistics (a probe that died is one ``exception``)."""
        connection = self._connection
        if connection is None:
            raise LoadTestError("the /health probe was not started")
        try:
            connection.send("stop")
            if not connection.poll(self.timeout_s + PROBE_START_S):
                raise TimeoutError(f"no answer within {self.timeout_s + PROBE_START_S:g} s")
            stats = connection.recv()
            if not isinstance(stats, KindStats):
                raise TypeError(f"the probe sent a {type(stats).__name__}")
        except (EOFError, OSError, TimeoutError, TypeError) as exc:
            stats = KindStats()
            stats.fail("exception", f"the /health probe failed: {describe(exc)}")
        finally:
            self._close()
        return stats

    def _close(self) -> None:
        if self._connection is not None:
            self._connection.close()
        if self._process is not None:
            self._process.join(PROBE_START_S)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
        self._process = self._connection = None


class LoadTest:
    """Runs the ramp against ``http`` (an ``httpx.AsyncClient`` with the server's base URL)."""

    def __init__(self, http: httpx.AsyncClient, settings: Settings, seed: int = 0) -> None:
        self.http = http
        self.settings = settings
        self.seed = seed
        self.roadmap: str | None = None
        self.requests: dict[str, Callable[[User], Awaitable[httpx.Response]]] = {
            "step": self._step,
            "plan": self._plan,
            "jump": self._jump,
            "upload": self._upload,
            "list": self._list,
        }

    async def memory(self) -> dict[str, float]:
        """The server's resident memory by process (bytes; empty if not reported)."""
        try:
            response = await self.http.get("/metrics", timeout=self.settings.timeout_s)
        except httpx.HTTPError:
            return {}
        return parse_memory(response.text) if response.status_code == 200 else {}

    async def _start_probe(self) -> HealthProbe:
        """The /health probe, started in a process of its own and asking already."""
        probe = HealthProbe(str(self.http.base_url), self.settings.timeout_s)
        await asyncio.to_thread(probe.start)
        return probe

    async def prepare(self, setup_timeout_s: float = 300.0) -> None:
        """Check the server answers, and build the jump roadmap when jumps are in the mix."""
        try:
            health = await self.http.get("/health", timeout=self.settings.timeout_s)
        except httpx.HTTPError as exc:
            raise LoadTestError(f"GET /health: {describe(exc, self.settings.timeout_s)}") from exc
        if health.status_code != 200:
            raise LoadTestError(f"GET /health answered {health.status_code}")
        if self.settings.mix.get("jump", 0) > 0:
            self.roadmap = await self._build_roadmap(setup_timeout_s)

    async def _build_roadmap(self, setup_timeout_s: float) -> str:
        body = {**ROADMAP, "nodes": self.settings.roadmap_nodes, "seed": self.seed}
        deadline = time.monotonic() + setup_timeout_s
        try:
            response = await self.http.post(
                "/v1/roadmaps", json=body, timeout=self.settings.timeout_s
            )
            while True:
                if response.status_code >= 400:
                    raise LoadTestError(f"jump roadmap: {_error_message(response)}")
                status = response.json()
                if status["status"] == "done":
                    return str(status["id"])
                if status["status"] in ("failed", "interrupted"):
                    raise LoadTestError(f"jump roadmap {status['status']}: {status['message']}")
                if time.monotonic() > deadline:
                    raise LoadTestError(f"jump roadmap not built within {setup_timeout_s:g} s")
                await asyncio.sleep(ROADMAP_POLL_S)
                response = await self.http.get(
                    f"/v1/roadmaps/{status['id']}", timeout=self.settings.timeout_s
                )
        except httpx.HTTPError as exc:
            raise LoadTestError(f"jump roadmap: {describe(exc, self.settings.timeout_s)}") from exc

    async def _step(self, user: User) -> httpx.Response:
        if user.state is None or user.steps >= self.settings.game_length:
            body: dict[str, Any] = dict(STEP_START)
            user.state, user.steps = None, 0
        else:
            body = {k: v for k, v in STEP_START.items() if k != "stand_at"}
            body |= {"state": user.state, "action": {"kind": "auto"}}
        body |= {"seed": user.rng.randrange(2**31), "time_budget_s": self.settings.step_budget_s}
        response = await self.http.post("/v1/twister/step", json=body)
        answer = response.json() if response.status_code == 200 else None
        if answer is not None and answer.get("status") == "SOLVED":
            user.state = answer["state"]  # the next move starts where this one ended
            user.steps += 1
        else:
            user.state = None
        return response

    async def _plan(self, user: User) -> httpx.Response:
        budget = self.settings.plan_budget_s
        body = {**PLAN, "seed": user.rng.randrange(2**31), "time_budget_s": budget}
        return await self.http.post("/v1/plans", json=body)

    async def _jump(self, user: User) -> httpx.Response:
        body = {
            **JUMP,
            "roadmap": self.roadmap,
            "seed": user.rng.randrange(2**31),
            "time_budget_s": self.settings.jump_budget_s,
        }
        return await self.http.post("/v1/jumps", json=body)

    async def _upload(self, user: User) -> httpx.Response:
        """Upload a terrain of its own; a stored one is deleted again (not timed)."""
        response = await self.http.post(
            "/v1/scenes",
            params={"format": "stl", "name": "load-test"},
            content=terrain_stl(user.rng),
            headers={"content-type": "application/octet-stream"},
        )
        if response.status_code in (200, 201):
            scene_id = response.json()["id"]
            await self.http.delete(f"/v1/scenes/{scene_id}")
        return response

    async def _list(self, user: User) -> httpx.Response:
        return await self.http.get(user.rng.choice(LIST_PATHS))

    async def level(
        self,
        concurrency: int,
        *,
        duration_s: float,
        max_requests: int,
        memory_every_s: float | None = None,
    ) -> dict[str, Any]:
        """``concurrency`` users for ``duration_s`` (at most ``max_requests`` requests); with
        ``memory_every_s``, the server's memory read that often too (a soak)."""
        kinds = [kind for kind, weight in self.settings.mix.items() if weight > 0]
        weights = [self.settings.mix[kind] for kind in kinds]
        stats = {kind: KindStats() for kind in kinds}
        memory_before = await self.memory()
        probe = await self._start_probe()
        started = time.monotonic()
        deadline = started + duration_s
        budget = iter(range(max_requests))

        async def user_loop(index: int) -> None:
            user = User(random.Random(self.seed * 1_000_003 + concurrency * 1009 + index))
            for _ in budget:
                if time.monotonic() >= deadline:
                    return
                kind = user.rng.choices(kinds, weights)[0]
                sent = time.perf_counter()
                try:
                    response = await self.requests[kind](user)
                except httpx.HTTPError as exc:
                    key = "timeout" if isinstance(exc, httpx.TimeoutException) else "connection"
                    stats[kind].fail(key, describe(exc, self.settings.timeout_s))
                    user.state = None
                    continue
                except Exception as exc:  # an answer that is not what the API says
                    stats[kind].fail("exception", describe(exc))
                    user.state = None
                    continue
                elapsed = time.perf_counter() - sent
                if response.status_code < 400:
                    stats[kind].latencies.append(elapsed)
                else:
                    stats[kind].fail(str(response.status_code), _error_message(response))
                    pause = retry_after_s(response)  # a refused user waits as told
                    if pause > 0:
                        await asyncio.sleep(min(pause, max(0.0, deadline - time.monotonic())))

        samples: list[tuple[float, dict[str, float]]] = [(0.0, memory_before)]

        async def sample_memory(every_s: float) -> None:
            while True:
                await asyncio.sleep(every_s)
                memory = await self.memory()
                samples.append((round(time.monotonic() - started, 3), memory))

        sampler = None
        if memory_every_s is not None:
            sampler = asyncio.create_task(sample_memory(memory_every_s))
        try:
            await asyncio.gather(*(user_loop(i) for i in range(concurrency)))
        finally:
            seconds = time.monotonic() - started
            if sampler is not None:
                sampler.cancel()
                await asyncio.gather(sampler, return_exceptions=True)
            health = await asyncio.to_thread(probe.stop)
        memory_after = await self.memory()
        out = {
            "concurrency": concurrency,
            "seconds": round(seconds, 3),
            "kinds": {kind: s.summary(seconds) for kind, s in stats.items()},
            "health": health.summary(seconds),
            "memory_bytes": {"before": memory_before, "after": memory_after},
        }
        if memory_every_s is not None:
            samples.append((round(time.monotonic() - started, 3), memory_after))
            out["memory_samples"] = [{"t": t, "bytes": memory} for t, memory in samples]
            out["soak"] = memory_trend(samples)
        return out


async def run_ramp(
    http: httpx.AsyncClient,
    *,
    levels: Sequence[int],
    duration_s: float,
    max_requests: int,
    settings: Settings,
    seed: int = 0,
    memory_every_s: float | None = None,
) -> list[dict[str, Any]]:
    """Prepare, then run each concurrency level in turn; one summary per level (with
    ``memory_every_s``, each with its memory samples and :func:`memory_trend`)."""
    if not 0 < duration_s <= MAX_DURATION_S:
        raise LoadTestError(f"duration must be in (0, {MAX_DURATION_S:g}] seconds")
    if not 1 <= max_requests <= MAX_REQUESTS:
        raise LoadTestError(f"requests must be in [1, {MAX_REQUESTS}]")
    if not levels or not all(1 <= level <= MAX_CONCURRENCY for level in levels):
        raise LoadTestError(f"each concurrency level must be in [1, {MAX_CONCURRENCY}]")
    test = LoadTest(http, settings, seed)
    await test.prepare()
    return [
        await test.level(
            level, duration_s=duration_s, max_requests=max_requests, memory_every_s=memory_every_s
        )
        for level in levels
    ]


def _mib(memory: dict[str, float]) -> str:
    if not memory:
        return "not reported"
    parts = ", ".join(f"{name} {value / 2**20:.0f}" for name, value in sorted(memory.items()))
    return f"{sum(memory.values()) / 2**20:.0f} MiB ({parts})"


def format_table(levels: Sequence[dict[str, Any]]) -> str:
    """The summaries as a text table, one block per concurrency level."""
    lines = []
    for level in levels:
        lines.append(f"concurrency {level['concurrency']} ({level['seconds']:.1f} s)")
        lines.append(f"  {'kind':<7} {'count':>6} {'ok':>6} {'per s':>8} {'p50 ms':>9} "
                     f"{'p99 ms':>9}  errors")  # fmt: skip
        rows = list(level["kinds"].items())
        if "health" in level:
            rows.append(("/health", level["health"]))
        for kind, s in rows:
            errors = ", ".join(f"{key}: {count}" for key, count in s["errors"].items()) or "-"
            p50 = f"{s['p50_ms']:.1f}" if "p50_ms" in s else "-"
            p99 = f"{s['p99_ms']:.1f}" if "p99_ms" in s else "-"
            lines.append(
                f"  {kind:<7} {s['count']:>6} {s['ok']:>6} {s['per_second']:>8.2f} "
                f"{p50:>9} {p99:>9}  {errors}"
            )
            for key, message in s["error_examples"].items():
                lines.append(f"          {key}: {message}")
        if "memory_bytes" in level:
            memory = level["memory_bytes"]
            lines.append(f"  memory before: {_mib(memory['before'])}")
            lines.append(f"  memory after:  {_mib(memory['after'])}")
        if "soak" in level:
            lines += format_soak(level["soak"])
    return "\n".join(lines)


def format_soak(trend: dict[str, Any]) -> list[str]:
    """A soak's memory (:func:`memory_trend`) as text lines."""
    if not trend["reported"]:
        return [f"  soak memory: not reported ({trend['samples']} samples)"]
    mib = 2**20
    verdict = "GREW" if trend["grew"] else "flat"
    lines = [
        f"  soak memory ({trend['samples']} samples): {verdict}: start {trend['start'] / mib:.0f}"
        f" MiB, end {trend['end'] / mib:.0f} MiB, max {trend['max'] / mib:.0f} MiB, growth "
        f"{trend['growth'] / mib:+.1f} MiB, trend {trend['slope_per_min'] / mib:+.1f} MiB/min; "
        f"second half {trend['settled_growth'] / mib:+.1f} MiB, trend "
        f"{trend['settled_slope_per_min'] / mib:+.1f} MiB/min "
        f"(idle before the load: {trend['idle'] / mib:.0f} MiB)"
    ]
    for name, memory in trend["by_process"].items():
        lines.append(
            f"    {name:<12} start {memory['start'] / mib:6.0f}  end {memory['end'] / mib:6.0f}"
            f"  max {memory['max'] / mib:6.0f} MiB"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Load-test a Gecko server with what users do, at a ramp of concurrency "
        "levels: throughput, p50/p99 latency and errors per kind, /health p50/p99, memory."
    )
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    parser.add_argument(
        "--concurrency", default=None, help=f"levels, e.g. {DEFAULT_LEVELS} (the default)"
    )
    parser.add_argument("--duration", type=float, default=20.0, help="seconds per level")
    parser.add_argument("--requests", type=int, default=MAX_REQUESTS, help="at most, per level")
    parser.add_argument("--mix", default=DEFAULT_MIX, help=f"kind weights ({DEFAULT_MIX})")
    parser.add_argument("--timeout", type=float, default=60.0, help="per request, seconds")
    parser.add_argument("--game-length", type=int, default=8, help="Twister steps per game")
    parser.add_argument("--roadmap-nodes", type=int, default=300, help="jump roadmap size")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument(
        "--soak",
        type=float,
        default=None,
        metavar="SECONDS",
        help=f"hold one level (--concurrency, else {SOAK_CONCURRENCY}) this long, reading the "
        "server's memory: start, end, max, growth, and whether it grew",
    )
    parser.add_argument(
        "--sample-every",
        type=float,
        default=None,
        metavar="SECONDS",
        help=f"a soak's memory sampling period ({SOAK_SAMPLE_EVERY_S:g}, at most the soak)",
    )
    args = parser.parse_args(argv)

    async def go() -> list[dict[str, Any]]:
        if args.soak is not None:
            level, memory_every_s = parse_soak(args.soak, args.concurrency, args.sample_every)
            levels, duration_s = [level], args.soak
        else:
            levels = parse_levels(args.concurrency or DEFAULT_LEVELS)
            duration_s, memory_every_s = args.duration, None
        settings = Settings(
            mix=parse_mix(args.mix),
            game_length=args.game_length,
            roadmap_nodes=args.roadmap_nodes,
            timeout_s=args.timeout,
        )
        async with httpx.AsyncClient(base_url=args.url, timeout=args.timeout) as http:
            return await run_ramp(
                http,
                levels=levels,
                duration_s=duration_s,
                max_requests=args.requests,
                settings=settings,
                seed=args.seed,
                memory_every_s=memory_every_s,
            )

    try:
        levels = asyncio.run(go())
    except LoadTestError as exc:
        print(f"load test failed: {exc}", file=sys.stderr)
        return 2
    except httpx.HTTPError as exc:
        print(f"load test failed: {describe(exc, args.timeout)}", file=sys.stderr)
        return 2
    except Exception as exc:  # never an empty message: the type and the text
        print(f"load test failed: {describe(exc)}", file=sys.stderr)
        return 2
    print(json.dumps(levels, indent=2) if args.json else format_table(levels))
    failed = any(s["errors"] for level in levels for s in level["kinds"].values())
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
