"""Prometheus metrics of one service process, served as text at ``GET /metrics``.

Each app has its own :class:`prometheus_client.CollectorRegistry` (tests build many apps in
one process). With several uvicorn workers (``--workers N``) each worker counts only the
requests it served: a scrape reaches one of them. Prometheus' multiprocess mode is not used.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector

from service.settings import LATENCY_BUCKETS_S

UNMATCHED_ROUTE = "<unmatched>"  # one label for every path no route serves (bounded labels)
JOB_STATES = ("queued", "running", "finished")


class RoadmapJobs(Collector):
    """Roadmap builds of this process by state, read from the live futures at each scrape."""

    def __init__(self, jobs: Callable[[], Mapping[str, Future[None]]]) -> None:
        self._jobs = jobs

    def collect(self) -> Iterable[GaugeMetricFamily]:
        counts = dict.fromkeys(JOB_STATES, 0)
        for job in list(self._jobs().values()):
            state = "finished" if job.done() else "running" if job.running() else "queued"
            counts[state] += 1
        family = GaugeMetricFamily(
            "gecko_roadmap_jobs",
            "Roadmap builds started by this process, by state (finished: done or failed).",
            labels=["state"],
        )
        for state, count in counts.items():
            family.add_metric([state], count)
        yield family


class Metrics:
    """The service's metrics: requests, answers, worker tasks and restarts, roadmap jobs."""

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
        self.worker_tasks = Gauge(
            "gecko_worker_tasks",
            "Plans, steps and jumps submitted to the planning processes and not answered yet "
            "(waiting or running).",
            registry=self.registry,
        )
        self.worker_processes = Gauge(
            "gecko_worker_processes",
            "Planning processes of this service worker (configured).",
            registry=self.registry,
        )
        self.worker_restarts = Counter(
            "gecko_worker_pool_restarts",
            "Times the planning process pool was replaced after a process died.",
            registry=self.registry,
        )

    def watch_roadmap_jobs(self, jobs: Callable[[], Mapping[str, Future[None]]]) -> None:
        """Report the roadmap builds ``jobs()`` returns (id -> future) at each scrape."""
        self.registry.register(RoadmapJobs(jobs))

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
