"""Prometheus metrics of one service process, served as text at ``GET /metrics``.

Each app has its own :class:`prometheus_client.CollectorRegistry` (tests build many apps in
one process). With several uvicorn workers (``--workers N``) each worker counts only the
requests it served: a scrape reaches one of them. Prometheus' multiprocess mode is not used.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Protocol

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector

from service.settings import LATENCY_BUCKETS_S

JOB_KINDS = ("roadmap", "plan")
JOB_STATES = ("queued", "running", "done", "failed", "cancelled", "interrupted")

_PAGE_BYTES = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
UNMATCHED_ROUTE = "<unmatched>"  # one label for every path no route serves (bounded labels)


class GateLike(Protocol):
    """What the metrics read of a lane (service.lanes.Gate)."""

    name: str
    slots: int
    queue: int

    @property
    def running(self) -> int: ...

    @property
    def waiting(self) -> int: ...

    @property
    def live_processes(self) -> int: ...

    def process_ids(self) -> list[int]: ...


class Gates(Collector):
    """Each lane's depth, running work and bounds, read at each scrape."""

    def __init__(self, gates: Callable[[], Iterable[GateLike]]) -> None:
        self._gates = gates

    def collect(self) -> Iterable[GaugeMetricFamily]:
        gates = list(self._gates())
        families = {
            "gecko_queue_depth": ("Work admitted and waiting for a slot, by lane.", "waiting"),
            "gecko_queue_limit": ("Most work that may wait for a slot, by lane.", "queue"),
            "gecko_lane_running": ("Work holding a slot (running), by lane.", "running"),
            "gecko_lane_slots": ("Slots (processes, or uploads at once), by lane.", "slots"),
            "gecko_lane_processes": (
                "Processes alive now, by lane (started on demand; a dead one is replaced).",
                "live_processes",
            ),
        }
        for name, (text, attribute) in families.items():
            family = GaugeMetricFamily(name, text, labels=["lane"])
            for gate in gates:
                family.add_metric([gate.name], float(getattr(gate, attribute)))
            yield family
        tasks = GaugeMetricFamily(
            "gecko_worker_tasks",
            "Plans, steps and jumps admitted and not answered yet (waiting or running).",
        )
        tasks.add_metric(
            [], float(sum(g.running + g.waiting for g in gates if g.name == "interactive"))
        )
        yield tasks
        memory = GaugeMetricFamily(
            "gecko_resident_memory_bytes",
            "Resident memory of this service worker's process (process=service) and of each "
            "lane's processes together (process=<lane>), from /proc (Linux only).",
            labels=["process"],
        )
        own = resident_bytes(os.getpid())
        if own is not None:
            memory.add_metric(["service"], float(own))
            for gate in gates:
                sizes = [resident_bytes(pid) for pid in gate.process_ids()]
                memory.add_metric([gate.name], float(sum(size or 0 for size in sizes)))
        yield memory


def resident_bytes(pid: int) -> int | None:
    """Resident set size of process ``pid`` in bytes (from ``/proc``), None if unknown."""
    try:
        fields = Path(f"/proc/{pid}/statm").read_text().split()
        return int(fields[1]) * _PAGE_BYTES
    except (OSError, IndexError, ValueError):
        return None


class JobCounts(Collector):
    """Jobs in the shared job store by kind and state (every service worker's), at each
    scrape."""

    def __init__(self, counts: Callable[[], Mapping[tuple[str, str], int]]) -> None:
        self._counts = counts

    def collect(self) -> Iterable[GaugeMetricFamily]:
        family = GaugeMetricFamily(
            "gecko_jobs",
            "Jobs (roadmap builds, asynchronous plans) in the job store, by kind and state.",
            labels=["kind", "state"],
        )
        counts = dict(self._counts())
        for kind in JOB_KINDS:
            for state in JOB_STATES:
                family.add_metric([kind, state], float(counts.get((kind, state), 0)))
        yield family


class SceneStorage(Collector):
    """Bytes the uploaded scenes take and their quota, read at each scrape."""

    def __init__(self, used: Callable[[], int], quota: int) -> None:
        self._used = used
        self._quota = quota

    def collect(self) -> Iterable[GaugeMetricFamily]:
        yield GaugeMetricFamily(
            "gecko_scenes_stored_bytes",
            "Bytes the uploaded scenes take in the scenes directory (shared by every worker).",
            value=float(self._used()),
        )
        yield GaugeMetricFamily(
            "gecko_scenes_quota_bytes",
            "Most bytes the uploaded scenes may take (GECKO_SCENES_QUOTA_BYTES).",
            value=float(self._quota),
        )


class Metrics:
    """The service's metrics: requests, answers, lanes, worker restarts, jobs."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry(auto_describe=True)
        self.requests = Counter(
            "gecko_http_requests",
            "HTTP requests answered, by method, route template and status code.",
            ["method", "route", "status"],
            registry=self.registry,
        )
        self.latency = Histogram(
            "gecko_http_request_duration_seconds",
            "Seconds from a request's arrival to the end of its answer.",
            ["method", "route", "status"],
            buckets=LATENCY_BUCKETS_S,
            registry=self.registry,
        )
        self.in_progress = Gauge(
            "gecko_http_requests_in_progress",
            "HTTP requests being served now.",
            registry=self.registry,
        )
        self.answers = Counter(
            "gecko_answers",
            "Plan, Twister step and jump answers, by kind and status (SOLVED, ...).",
            ["kind", "status"],
            registry=self.registry,
        )
        self.refused = Counter(
            "gecko_refused",
            "Work refused with a 503, by lane and reason (queue_full, queue_timeout).",
            ["lane", "reason"],
            registry=self.registry,
        )
        self.cancelled = Counter(
            "gecko_worker_tasks_stopped",
            "Tasks whose process was killed before they answered, by lane and reason "
            "(timeout; cancelled: the client went away or the job was deleted).",
            ["lane", "reason"],
            registry=self.registry,
        )
        self.worker_processes = Gauge(
            "gecko_worker_processes",
            "Planning processes of this service worker (configured).",
            registry=self.registry,
        )
        self.worker_restarts = Counter(
            "gecko_worker_pool_restarts",
            "Planning or job processes replaced after dying on their own.",
            registry=self.registry,
        )

    def watch_gates(self, gates: Callable[[], Iterable[GateLike]]) -> None:
        """Report the lanes ``gates()`` returns at each scrape."""
        self.registry.register(Gates(gates))

    def watch_jobs(self, counts: Callable[[], Mapping[tuple[str, str], int]]) -> None:
        """Report the job counts ``counts()`` returns ((kind, state) -> n) at each scrape."""
        self.registry.register(JobCounts(counts))

    def watch_scenes(self, used: Callable[[], int], quota: int) -> None:
        """Report the uploaded scenes' bytes ``used()`` and their ``quota`` at each scrape."""
        self.registry.register(SceneStorage(used, quota))

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Count one answered request and its latency (s)."""
        labels = (method, route, str(status))
        self.requests.labels(*labels).inc()
        self.latency.labels(*labels).observe(seconds)

    def observe_answer(self, kind: str, status: str) -> None:
        """Count one plan, step or jump answer by its domain status."""
        self.answers.labels(kind, status).inc()

    def exposition(self) -> bytes:
        """The Prometheus text format of every metric."""
        return generate_latest(self.registry)
