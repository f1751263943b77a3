"""Jobs: long work (roadmap builds, asynchronous plans) with an id and a state every service
worker can read, that survives restarts.

A job is ``queued``, ``running``, then ``done`` (with a ``result``), ``failed`` (with a
message), ``cancelled`` (a DELETE) or ``interrupted`` (the service worker running it
stopped). The service worker that accepted a job runs it (its *owner*); any other answers GET
and DELETE for it from the store. An owner renews a heartbeat; the jobs of an owner that
stopped without saying so (killed) are reported interrupted, never left running forever.

:class:`JobStore` is the interface the service uses; :class:`SqliteJobStore` keeps it in one
SQLite file (WAL mode, so readers never wait for the writer) under the service's home,
shared by every service worker on the machine. A distributed queue could stand behind the
same interface for workers on other machines.
"""

from __future__ import annotations

import json
import os
import socket
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol

from service.settings import JOB_OWNER_STALE_S, JOBS_KEPT

JobKind = Literal["roadmap", "plan"]
JobState = Literal["queued", "running", "done", "failed", "cancelled", "interrupted"]
ACTIVE: tuple[JobState, ...] = ("queued", "running")
BUSY_TIMEOUT_S = 10.0  # s a store call waits for another process's write to finish
STOPPED = "the service worker running it stopped (restart or crash); submit it again"


@dataclass(frozen=True, slots=True)
class Job:
    """A job as stored: times are Unix seconds, ``progress`` a fraction in [0, 1]."""

    id: str
    kind: JobKind
    state: JobState
    progress: float
    message: str
    request: dict[str, Any]
    result: dict[str, Any] | None
    owner: str | None
    created_at: float
    started_at: float | None
    finished_at: float | None

    @property
    def active(self) -> bool:
        """Queued or running."""
        return self.state in ACTIVE


class JobStore(Protocol):
    """Where jobs live. Every method is safe to call from any thread or process."""

    def submit(
        self, job_id: str, kind: JobKind, request: dict[str, Any], owner: str
    ) -> tuple[Job, bool]:
        """Queue a job owned by ``owner``; ``(job, True)``, or ``(the active job, False)``
        when one with this id is already queued or running (a finished one is replaced)."""
        ...

    def get(self, job_id: str) -> Job | None:
        """The job (an active one whose owner is gone is reported interrupted), or None."""
        ...

    def start(self, job_id: str) -> bool:
        """Queued -> running; False when it is no longer queued (cancelled meanwhile)."""
        ...

    def progress(self, job_id: str, fraction: float) -> None:
        """Record the progress of a running job."""
        ...

    def finish(self, job_id: str, result: dict[str, Any]) -> None:
        """Running -> done with ``result`` (unless cancelled or interrupted meanwhile)."""
        ...

    def fail(self, job_id: str, message: str) -> None:
        """Queued or running -> failed with ``message``."""
        ...

    def cancel(self, job_id: str) -> Job | None:
        """Queued or running -> cancelled (its owner stops it); the job after, or None."""
        ...

    def states(self, job_ids: list[str]) -> dict[str, JobState]:
        """The state of each of these jobs (an owner polls those it runs for DELETEs)."""
        ...

    def heartbeat(self, owner: str) -> None:
        """``owner`` is alive (called every few tenths of a second while it runs jobs)."""
        ...

    def release(self, owner: str, message: str) -> None:
        """``owner`` stops: its active jobs become interrupted with ``message``."""
        ...

    def counts(self) -> dict[tuple[str, str], int]:
        """Number of jobs by (kind, state)."""
        ...


_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    state TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    message TEXT NOT NULL DEFAULT '',
    request TEXT NOT NULL,
    result TEXT,
    owner TEXT,
    created_at REAL NOT NULL,
    started_at REAL,
    finished_at REAL
);
CREATE INDEX IF NOT EXISTS jobs_by_state ON jobs (state);
CREATE TABLE IF NOT EXISTS owners (
    id TEXT PRIMARY KEY,
    host TEXT NOT NULL,
    pid INTEGER NOT NULL,
    heartbeat_at REAL NOT NULL
);
"""
_COLUMNS = (
    "id, kind, state, progress, message, request, result, owner, created_at, started_at, "
    "finished_at"
)


def owner_id() -> str:
    """A new owner id for this service worker: host, process id and a random part."""
    return f"{socket.gethostname()}:{os.getpid()}:{os.urandom(4).hex()}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


class SqliteJobStore:
    """:class:`JobStore` in one SQLite file (WAL), shared by the processes of one machine."""

    def __init__(self, path: Path) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        db = sqlite3.connect(path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        try:
            db.execute("PRAGMA journal_mode=WAL")  # kept by the file: readers never wait
            db.executescript(_SCHEMA)
        finally:
            db.close()
        # Held open (after one read, which maps the WAL index and takes its shared lock): the
        # per-call connections below are then never the last one to close, whose close
        # checkpoints and removes the WAL under an exclusive lock that readers would wait on
        # (for long, if that process was stopped or stuck meanwhile).
        self._anchor = sqlite3.connect(path, check_same_thread=False)
        self._anchor.execute("SELECT COUNT(*) FROM owners").fetchone()

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        """A connection in one transaction (committed on success), closed after."""
        db = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        try:
            db.execute("PRAGMA synchronous=NORMAL")  # WAL: durable at checkpoints, never torn
            db.execute("BEGIN IMMEDIATE")
            try:
                yield db
            except BaseException:
                db.execute("ROLLBACK")
                raise
            db.execute("COMMIT")
        finally:
            db.close()

    @contextmanager
    def _read(self) -> Iterator[sqlite3.Connection]:
        """A connection in one read transaction: a snapshot that, in WAL mode, never waits
        for a writer (not even one stopped while it holds the write lock)."""
        db = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        try:
            db.execute("BEGIN DEFERRED")
            try:
                yield db
            finally:
                db.execute("ROLLBACK")
        finally:
            db.close()

    @staticmethod
    def _job(row: tuple[Any, ...]) -> Job:
        return Job(
            id=row[0],
            kind=row[1],
            state=row[2],
            progress=float(row[3]),
            message=row[4],
            request=json.loads(row[5]),
            result=None if row[6] is None else json.loads(row[6]),
            owner=row[7],
            created_at=float(row[8]),
            started_at=row[9],
            finished_at=row[10],
        )

    def _select(self, db: sqlite3.Connection, job_id: str) -> Job | None:
        row = db.execute(f"SELECT {_COLUMNS} FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else self._job(row)

    def _owner_gone(self, db: sqlite3.Connection, owner: str | None) -> bool:
        if owner is None:
            return True
        row = db.execute("SELECT host, pid, heartbeat_at FROM owners WHERE id = ?", (owner,))
        found = row.fetchone()
        if found is None:
            return True
        host, pid, heartbeat_at = found
        if time.time() - float(heartbeat_at) > JOB_OWNER_STALE_S:
            return True
        return bool(host == socket.gethostname() and not _pid_alive(int(pid)))

    def _reap(self, db: sqlite3.Connection, job: Job | None) -> Job | None:
        """An active job whose owner is gone becomes interrupted (written, then returned)."""
        if job is None or not job.active or not self._owner_gone(db, job.owner):
            return job
        db.execute(
            "UPDATE jobs SET state = 'interrupted', message = ?, finished_at = ? WHERE id = ?",
            (STOPPED, time.time(), job.id),
        )
        return self._select(db, job.id)

    def submit(
        self, job_id: str, kind: JobKind, request: dict[str, Any], owner: str
    ) -> tuple[Job, bool]:
        with self._connect() as db:
            existing = self._reap(db, self._select(db, job_id))
            if existing is not None and existing.active:
                return existing, False
            db.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
            db.execute(
                "INSERT INTO jobs (id, kind, state, request, owner, created_at) "
                "VALUES (?, ?, 'queued', ?, ?, ?)",
                (job_id, kind, json.dumps(request), owner, time.time()),
            )
            self._prune(db)
            job = self._select(db, job_id)
        assert job is not None
        return job, True

    @staticmethod
    def _prune(db: sqlite3.Connection) -> None:
        db.execute(
            "DELETE FROM jobs WHERE state NOT IN ('queued', 'running') AND id NOT IN ("
            "SELECT id FROM jobs WHERE state NOT IN ('queued', 'running') "
            "ORDER BY created_at DESC LIMIT ?)",
            (JOBS_KEPT,),
        )

    def get(self, job_id: str) -> Job | None:
        with self._read() as db:  # the usual case: a read that waits for nobody
            job = self._select(db, job_id)
            if job is None or not job.active or not self._owner_gone(db, job.owner):
                return job
        with self._connect() as db:  # its owner is gone: say so, once
            return self._reap(db, self._select(db, job_id))

    def start(self, job_id: str) -> bool:
        with self._connect() as db:
            cursor = db.execute(
                "UPDATE jobs SET state = 'running', started_at = ? "
                "WHERE id = ? AND state = 'queued'",
                (time.time(), job_id),
            )
            return cursor.rowcount == 1

    def progress(self, job_id: str, fraction: float) -> None:
        with self._connect() as db:
            db.execute(
                "UPDATE jobs SET progress = ? WHERE id = ? AND state = 'running'",
                (min(1.0, max(0.0, fraction)), job_id),
            )

    def finish(self, job_id: str, result: dict[str, Any]) -> None:
        with self._connect() as db:
            db.execute(
                "UPDATE jobs SET state = 'done', progress = 1, result = ?, finished_at = ? "
                "WHERE id = ? AND state = 'running'",
                (json.dumps(result), time.time(), job_id),
            )

    def fail(self, job_id: str, message: str) -> None:
        with self._connect() as db:
            db.execute(
                "UPDATE jobs SET state = 'failed', message = ?, finished_at = ? "
                "WHERE id = ? AND state IN ('queued', 'running')",
                (message, time.time(), job_id),
            )

    def cancel(self, job_id: str) -> Job | None:
        with self._connect() as db:
            job = self._reap(db, self._select(db, job_id))
            if job is not None and job.active:
                db.execute(
                    "UPDATE jobs SET state = 'cancelled', message = ?, finished_at = ? "
                    "WHERE id = ?",
                    ("cancelled by a DELETE", time.time(), job_id),
                )
                job = self._select(db, job_id)
            return job

    def states(self, job_ids: list[str]) -> dict[str, JobState]:
        if not job_ids:
            return {}
        marks = ",".join("?" * len(job_ids))
        with self._read() as db:
            rows = db.execute(f"SELECT id, state FROM jobs WHERE id IN ({marks})", job_ids)
            return {row[0]: row[1] for row in rows.fetchall()}

    def heartbeat(self, owner: str) -> None:
        with self._connect() as db:
            db.execute(
                "INSERT INTO owners (id, host, pid, heartbeat_at) VALUES (?, ?, ?, ?) "
                "ON CONFLICT (id) DO UPDATE SET heartbeat_at = excluded.heartbeat_at",
                (owner, socket.gethostname(), os.getpid(), time.time()),
            )

    def release(self, owner: str, message: str) -> None:
        with self._connect() as db:
            db.execute(
                "UPDATE jobs SET state = 'interrupted', message = ?, finished_at = ? "
                "WHERE owner = ? AND state IN ('queued', 'running')",
                (message, time.time(), owner),
            )
            db.execute("DELETE FROM owners WHERE id = ?", (owner,))

    def counts(self) -> dict[tuple[str, str], int]:
        with self._read() as db:
            active = db.execute(
                f"SELECT {_COLUMNS} FROM jobs WHERE state IN ('queued', 'running')"
            ).fetchall()
            orphans = [row[0] for row in active if self._owner_gone(db, row[7])]
            if not orphans:
                rows = db.execute("SELECT kind, state, COUNT(*) FROM jobs GROUP BY kind, state")
                return {(kind, state): int(n) for kind, state, n in rows.fetchall()}
        with self._connect() as db:  # some owner is gone: its jobs are interrupted first
            for job_id in orphans:
                self._reap(db, self._select(db, job_id))
            rows = db.execute("SELECT kind, state, COUNT(*) FROM jobs GROUP BY kind, state")
            return {(kind, state): int(n) for kind, state, n in rows.fetchall()}
