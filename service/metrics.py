"""Prometheus metrics of the service, served as text at ``GET /metrics``.

Each app has its own :class:`prometheus_client.CollectorRegistry` (tests build many apps in
one process). With several uvicorn workers (``--workers N``: each worker is a process that
uvicorn's supervisor started), a scrape reaches one of them, so the service uses
prometheus-client's multiprocess mode: every worker writes its counters, histograms and
gauges to memory-mapped files in a directory of its own supervisor,
``<GECKO_HOME>/metrics/<supervisor pid>`` (made at start, and the directories of
supervisors that are gone removed; ``PROMETHEUS_MULTIPROC_DIR`` is set to it), and a scrape
sums every worker's: requests and answers counted by any worker, lane gauges and memory
summed over the live workers (each refreshes its own every ``LIVE_REFRESH_S`` and at a
scrape; a dead worker's gauges are dropped, its counts kept). The job counts and the scenes'
storage are read from what every worker shares (the job store, the scenes directory).
"""

from __future__ import annotations

import glob
import multiprocessing
import os
import re
import shutil
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Protocol

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client import values as prometheus_values
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.multiprocess import MultiProcessCollector, mark_process_dead
from prometheus_client.registry import Collector

from service.settings import LATENCY_BUCKETS_S

JOB_KINDS = ("roadmap", "plan")
JOB_STATES = ("queued", "running", "done", "failed", "cancelled", "interrupted")

_PAGE_BYTES = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
UNMATCHED_ROUTE = "<unmatched>"  # one label for every path no route serves (bounded labels)
MULTIPROC_VARIABLE = "PROMETHEUS_MULTIPROC_DIR"
LIVE_REFRESH_S = 1.0  # s between two refreshes of a worker's lane and memory gauges
_LIVE_FILE = re.compile(r"gauge_live[a-z]*_(\d+)\.db$")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def multiprocess_dir(home: Path) -> Path | None:
    """The metrics directory shared by the uvicorn workers of this service, when this
    process is one of them (started by uvicorn's supervisor: ``--workers N``); None for a
    service running in a single process (then its own registry holds every figure).
    ``<home>/metrics/<supervisor pid>``, made here; the directories of supervisors no longer
    running are removed."""
    parent = multiprocessing.parent_process()
    if parent is None or parent.pid is None:
        return None
    root = home / "metrics"
    path = root / str(parent.pid)
    path.mkdir(parents=True, exist_ok=True)
    for other in root.iterdir():
        if other != path and other.name.isdigit() and not _alive(int(other.name)):
            shutil.rmtree(other, ignore_errors=True)
    return path


def use_multiprocess(path: Path) -> None:
    """Switch prometheus-client to multiprocess mode over ``path`` for the metrics made from
    now on in this process (the mode is otherwise chosen when the library is imported)."""
    os.environ[MULTIPROC_VARIABLE] = str(path)
    if not getattr(prometheus_values.ValueClass, "_multiprocess", False):
        prometheus_values.ValueClass = prometheus_values.MultiProcessValue()  # type: ignore[no-untyped-call]


def drop_dead_workers(path: Path) -> None:
    """Remove the live gauges of worker processes that are gone (their counts stay)."""
    for name in glob.glob(str(path / "gauge_live*_*.db")):
        match = _LIVE_FILE.search(name)
        if match and not _alive(int(match.group(1))):
            mark_process_dead(int(match.group(1)), str(path))  # type: ignore[no-untyped-call]


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


GaugeValues = list[tuple[tuple[str, ...], float]]
_GATE_FAMILIES = {
    "gecko_queue_depth": ("Work admitted and waiting for a slot, by lane.", "waiting"),
    "gecko_queue_limit": ("Most work that may wait for a slot, by lane.", "queue"),
    "gecko_lane_running": ("Work holding a slot (running), by lane.", "running"),
    "gecko_lane_slots": ("Slots (processes, or uploads at once), by lane.", "slots"),
    "gecko_lane_processes": (
        "Processes alive now, by lane (started on demand; a dead one is replaced).",
        "live_processes",
    ),
}
_TASKS_HELP = "Plans, steps and jumps admitted and not answered yet (waiting or running)."
_MEMORY_HELP = (
    "Resident memory of this service worker's process (process=service) and of each "
    "lane's processes together (process=<lane>), from /proc (Linux only); with several "
    "uvicorn workers, summed over them."
)


def gate_figures(gates: Iterable[GateLike]) -> dict[str, tuple[str, list[str], GaugeValues]]:
    """Each lane gauge's help text, label names and values (labels, value) now."""
    gates = list(gates)
    out: dict[str, tuple[str, list[str], GaugeValues]] = {}
    for name, (text, attribute) in _GATE_FAMILIES.items():
        values: GaugeValues = [((gate.name,), float(getattr(gate, attribute))) for gate in gates]
        out[name] = (text, ["lane"], values)
    tasks = float(sum(g.running + g.waiting for g in gates if g.name == "interactive"))
    no_labels: tuple[str, ...] = ()
    out["gecko_worker_tasks"] = (_TASKS_HELP, [], [(no_labels, tasks)])
    memory: GaugeValues = []
    own = resident_bytes(os.getpid())
    if own is not None:
        memory.append((("service",), float(own)))
        for gate in gates:
            sizes = [resident_bytes(pid) for pid in gate.process_ids()]
            memory.append(((gate.name,), float(sum(size or 0 for size in sizes))))
    out["gecko_resident_memory_bytes"] = (_MEMORY_HELP, ["process"], memory)
    return out


class Gates(Collector):
    """Each lane's depth, running work and bounds, read at each scrape."""

    def __init__(self, gates: Callable[[], Iterable[GateLike]]) -> None:
        self._gates = gates

    def collect(self) -> Iterable[GaugeMetricFamily]:
        for name, (text, labels, values) in gate_figures(self._gates()).items():
            family = GaugeMetricFamily(name, text, labels=labels)
            for label_values, value in values:
                family.add_metric(list(label_values), value)
            yield family


class LiveGates:
    """The lane gauges in multiprocess mode: one gauge per family, summed over the live
    uvicorn workers (``livesum``), set from this worker's lanes by :meth:`refresh`."""

    def __init__(self, gates: Callable[[], Iterable[GateLike]], registry: CollectorRegistry):
        self._gates = gates
        self._gauges: dict[str, Gauge] = {}
        for name, (text, labels, _) in gate_figures(()).items():
            self._gauges[name] = Gauge(
                name, text, labels, registry=registry, multiprocess_mode="livesum"
            )

    def refresh(self) -> None:
        """Write this worker's figures now."""
        for name, (_, labels, values) in gate_figures(self._gates()).items():
            gauge = self._gauges[name]
            for label_values, value in values:
                (gauge.labels(*label_values) if labels else gauge).set(value)


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


class StoredBytes(Collector):
    """Bytes a store on disk takes and its quota, read at each scrape:
    ``gecko_<store>_stored_bytes`` and ``gecko_<store>_quota_bytes``."""

    def __init__(
        self, store: str, what: str, setting: str, used: Callable[[], int], quota: int
    ) -> None:
        self._store, self._what, self._setting = store, what, setting
        self._used = used
        self._quota = quota

    def collect(self) -> Iterable[GaugeMetricFamily]:
        yield GaugeMetricFamily(
            f"gecko_{self._store}_stored_bytes",
            f"Bytes {self._what} take on disk (shared by every worker).",
            value=float(self._used()),
        )
        yield GaugeMetricFamily(
            f"gecko_{self._store}_quota_bytes",
            f"Most bytes {self._what} may take ({self._setting}).",
            value=float(self._quota),
        )


class Metrics:
    """The service's metrics: requests, answers, lanes, worker restarts, jobs.

    ``multiprocess``: the directory shared by the uvicorn workers (:func:`multiprocess_dir`),
    None for a service in one process."""

    def __init__(self, multiprocess: Path | None = None) -> None:
        self.multiprocess = multiprocess
        if multiprocess is not None:
            use_multiprocess(multiprocess)
        self.registry = CollectorRegistry(auto_describe=True)
        self.exposed = self.registry  # what a scrape reads
        if multiprocess is not None:
            self.exposed = CollectorRegistry()
            MultiProcessCollector(self.exposed, path=str(multiprocess))  # type: ignore[no-untyped-call]
        self._live: LiveGates | None = None
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
            multiprocess_mode="livesum",
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
            "Planning processes of the service's workers (configured).",
            registry=self.registry,
            multiprocess_mode="livesum",
        )
        self.worker_restarts = Counter(
            "gecko_worker_pool_restarts",
            "Planning or job processes replaced after dying on their own.",
            registry=self.registry,
        )

    def watch_gates(self, gates: Callable[[], Iterable[GateLike]]) -> None:
        """Report the lanes ``gates()`` returns at each scrape (in multiprocess mode, as
        gauges each worker refreshes: :meth:`refresh_live`)."""
        if self.multiprocess is None:
            self.registry.register(Gates(gates))
        else:
            self._live = LiveGates(gates, self.registry)
            self._live.refresh()

    def refresh_live(self) -> None:
        """Multiprocess mode: write this worker's lane and memory gauges, and drop those of
        workers that are gone (call it every ``LIVE_REFRESH_S``); nothing otherwise."""
        if self.multiprocess is None:
            return
        if self._live is not None:
            self._live.refresh()
        drop_dead_workers(self.multiprocess)

    def watch_jobs(self, counts: Callable[[], Mapping[tuple[str, str], int]]) -> None:
        """Report the job counts ``counts()`` returns ((kind, state) -> n) at each scrape."""
        self.exposed.register(JobCounts(counts))

    def watch_scenes(self, used: Callable[[], int], quota: int) -> None:
        """Report the uploaded scenes' bytes ``used()`` and their ``quota`` at each scrape."""
        what = "the uploaded scenes, cached BVHs included,"
        self.exposed.register(StoredBytes("scenes", what, "GECKO_SCENES_QUOTA_BYTES", used, quota))

    def watch_roadmaps(self, used: Callable[[], int], quota: int) -> None:
        """Report the stored jump roadmaps' bytes ``used()`` and their ``quota`` at each
        scrape."""
        what = "the stored jump roadmaps"
        self.exposed.register(
            StoredBytes("roadmaps", what, "GECKO_ROADMAPS_QUOTA_BYTES", used, quota)
        )

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Count one answered request and its latency (s)."""
        labels = (method, route, str(status))
        self.requests.labels(*labels).inc()
        self.latency.labels(*labels).observe(seconds)

    def observe_answer(self, kind: str, status: str) -> None:
        """Count one plan, step or jump answer by its domain status."""
        self.answers.labels(kind, status).inc()

    def close(self) -> None:
        """Multiprocess mode: this worker stops; its live gauges leave the sums now."""
        if self.multiprocess is not None:
            mark_process_dead(os.getpid(), str(self.multiprocess))  # type: ignore[no-untyped-call]

    def exposition(self) -> bytes:
        """The Prometheus text format of every metric (every worker's, in multiprocess
        mode)."""
        self.refresh_live()
        return generate_latest(self.exposed)
