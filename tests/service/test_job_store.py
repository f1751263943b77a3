"""The SQLite job store: states, conditional transitions, and honest reports about jobs whose
service worker died without saying so (its process is gone)."""

from __future__ import annotations

import asyncio
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from asgi_lifespan import LifespanManager

import service.jobs
from service.app import create_app
from service.jobs import BUSY_TIMEOUT_S, SqliteJobStore, owner_id
from service.settings import Settings
from tests.paths import REPO_ROOT, gecko_cache_dir


def test_a_job_goes_queued_running_done_and_is_never_overwritten(tmp_path: Path) -> None:
    store = SqliteJobStore(tmp_path / "jobs.sqlite3")
    owner = owner_id()
    store.heartbeat(owner)
    job, created = store.submit("a1", "plan", {"seed": 1}, owner)
    assert created and (job.state, job.progress, job.request) == ("queued", 0.0, {"seed": 1})
    same, created = store.submit("a1", "plan", {"seed": 2}, owner)
    assert not created and same.request == {"seed": 1}  # the active job stays
    assert store.start("a1") and not store.start("a1")
    store.progress("a1", 0.25)
    assert store.get("a1").progress == 0.25  # type: ignore[union-attr]
    store.finish("a1", {"kind": "plan", "id": "p", "url": "/v1/plans/p"})
    done = store.get("a1")
    assert (
        done is not None
        and done.state == "done"
        and done.result
        == {
            "kind": "plan",
            "id": "p",
            "url": "/v1/plans/p",
        }
    )
    store.fail("a1", "late")  # a finished job keeps its state
    assert store.get("a1").state == "done"  # type: ignore[union-attr]
    assert store.cancel("a1").state == "done"  # type: ignore[union-attr]
    assert store.counts() == {("plan", "done"): 1}
    # A cancelled job cannot be started nor finished by its owner afterwards.
    store.submit("a2", "roadmap", {}, owner)
    assert store.cancel("a2").state == "cancelled"  # type: ignore[union-attr]
    assert not store.start("a2")
    store.finish("a2", {"kind": "roadmap", "id": "a2", "url": "/v1/roadmaps/a2"})
    assert store.get("a2").state == "cancelled"  # type: ignore[union-attr]
    # A finished job may be submitted again: it is replaced.
    again, created = store.submit("a2", "roadmap", {"nodes": 3}, owner)
    assert created and again.state == "queued"
    assert store.get("nosuch") is None


def test_jobs_of_a_worker_that_died_are_reported_interrupted(tmp_path: Path) -> None:
    path = tmp_path / "jobs.sqlite3"
    # A service worker in another process takes a job and dies (kill -9: no goodbye).
    script = (
        "import sys, os; from pathlib import Path; from service.jobs import *\n"
        "s = SqliteJobStore(Path(sys.argv[1])); o = owner_id(); s.heartbeat(o)\n"
        "s.submit('j1', 'roadmap', {}, o); s.start('j1'); s.submit('j2', 'plan', {}, o)\n"
        "os.kill(os.getpid(), 9)\n"
    )
    command = [sys.executable, "-c", script, str(path)]
    dead = subprocess.run(command, cwd=REPO_ROOT, check=False)
    assert dead.returncode == -9
    store = SqliteJobStore(path)
    for job_id in ("j1", "j2"):
        job = store.get(job_id)
        assert job is not None and job.state == "interrupted", job
        assert "stopped" in job.message
    # A live worker's jobs stay as they are; when it stops, they are interrupted too.
    owner = owner_id()
    store.heartbeat(owner)
    store.submit("j3", "plan", {}, owner)
    assert store.get("j3").state == "queued"  # type: ignore[union-attr]
    store.release(owner, "stopping")
    stopped = store.get("j3")
    assert stopped is not None and (stopped.state, stopped.message) == ("interrupted", "stopping")
    assert store.counts() == {("roadmap", "interrupted"): 1, ("plan", "interrupted"): 2}


def _hold_write_lock(path: Path) -> sqlite3.Connection:
    """Another process's writer stopped mid-transaction (as SIGSTOP leaves one)."""
    writer = sqlite3.connect(path, isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")
    writer.execute("UPDATE owners SET heartbeat_at = heartbeat_at")
    return writer


def test_reads_wait_for_no_writer(tmp_path: Path) -> None:
    store = SqliteJobStore(tmp_path / "jobs.sqlite3")
    owner = owner_id()
    store.heartbeat(owner)
    store.submit("r1", "roadmap", {}, owner)
    writer = _hold_write_lock(tmp_path / "jobs.sqlite3")
    try:
        started = time.monotonic()
        assert store.get("r1").state == "queued"  # type: ignore[union-attr]
        assert store.states(["r1"]) == {"r1": "queued"}
        assert store.counts() == {("roadmap", "queued"): 1}
        assert time.monotonic() - started < BUSY_TIMEOUT_S  # none of them waited it out
    finally:
        writer.close()


def test_a_store_locked_past_its_timeout_is_a_503_to_retry(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(service.jobs, "BUSY_TIMEOUT_S", 0.2)
    settings = Settings(
        home=tmp_path, cache_dir=gecko_cache_dir(), characters="quadruped", log_level="error"
    )
    app = create_app(settings)

    async def go() -> httpx.Response:
        async with (
            LifespanManager(app),
            httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as c,
        ):
            store: SqliteJobStore = app.state.jobs.store
            store.submit("j1", "plan", {}, app.state.jobs.owner)
            writer = _hold_write_lock(settings.jobs_db_path)
            try:
                assert (await c.get("/v1/jobs/j1")).status_code == 200  # a read
                return await c.delete("/v1/jobs/j1")  # a write: waits, then gives up
            finally:
                writer.close()

    answer = asyncio.run(go())
    assert answer.status_code == 503, answer.text
    assert answer.headers["retry-after"] == "1"
    assert answer.json()["error"]["code"] == "store_busy"
