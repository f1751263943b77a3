"""Crash isolation against the real ``uvicorn`` command (see tests/live_process.py): a compute
process killed with ``kill -9`` fails only the request it ran and is replaced; a killed
uvicorn worker takes its compute processes with it and is replaced; with ``--workers 2`` a job
is visible from both workers and survives a restart; SIGTERM stops the whole process tree.

Nothing is timed: every wait is for a state the server or the process table reports, bounded
only so that a broken server fails instead of hanging.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import threading
from pathlib import Path
from typing import Any

import httpx
import psutil
import pytest

from tests.live_fixtures import LIVE_JUMP, LIVE_PLAN, LIVE_STEP
from tests.live_process import ServerProcess, server_process
from tests.live_server import wait_until
from tests.prometheus_text import metric_samples, sample_value

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="POSIX signals")

LONG_JUMP = {**LIVE_JUMP, "nodes": 10_000, "time_budget_s": 60}  # builds for ~30 s
BIG_ROADMAP = {"character": "quadruped", "scene": "gaps", "nodes": 10_000, "seed": 100}
SMALL_ROADMAP = {"character": "quadruped", "scene": "gaps", "nodes": 60, "seed": 7}
WAIT_S = 180.0


class Call:
    """An HTTP request made in a thread; ``result()`` waits for its answer."""

    def __init__(self, method: str, url: str, body: dict[str, Any] | None = None) -> None:
        self.response: httpx.Response | None = None
        self.error: BaseException | None = None

        def go() -> None:
            try:
                self.response = httpx.request(method, url, json=body, timeout=WAIT_S)
            except BaseException as exc:
                self.error = exc

        self._thread = threading.Thread(target=go, daemon=True)
        self._thread.start()

    def result(self) -> httpx.Response:
        self._thread.join(WAIT_S)
        assert not self._thread.is_alive(), "the request hung"
        if self.error is not None:
            raise self.error
        assert self.response is not None
        return self.response


def _lane(url: str, metric: str, lane: str = "interactive") -> float:
    return sample_value(metric_samples(url), metric, lane=lane)


def _job(url: str, job_id: str) -> dict[str, Any]:
    response = httpx.get(f"{url}/v1/jobs/{job_id}", timeout=30)
    assert response.status_code == 200, response.text
    return dict(response.json())


def _owner_pid(home: Path, job_id: str) -> int:
    """The pid of the uvicorn worker running a job (read from the job store itself)."""
    with sqlite3.connect(home / "jobs.sqlite3") as db:
        row = db.execute(
            "SELECT owners.pid FROM jobs JOIN owners ON jobs.owner = owners.id WHERE jobs.id = ?",
            (job_id,),
        ).fetchone()
    assert row is not None, f"job {job_id} has no owner"
    return int(row[0])


def _gone(pids: list[int]) -> bool:
    for pid in pids:
        try:
            if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                return False
        except psutil.NoSuchProcess:
            continue
    return True


def _stop_and_check_tree(server: ServerProcess) -> None:
    """SIGTERM the uvicorn command: it stops cleanly (exit 0, or uvicorn re-raising the
    SIGTERM it handled) and no process of its tree survives."""
    tree = [p.pid for p in server.tree()]
    assert tree, "the server has no child processes to check"
    assert server.terminate() in (0, -signal.SIGTERM), server.log()
    assert "Application shutdown complete" in server.log()
    wait_until(lambda: _gone(tree), f"every process of the tree gone ({tree})", 30)


def test_a_killed_compute_process_fails_only_its_request(tmp_path: Path) -> None:
    settings = {"GECKO_WORKER_PROCESSES": "2"}
    with server_process(tmp_path / "home", env=settings) as server:
        url = server.url
        # One long jump runs alone: the lane's only process is its.
        doomed = Call("POST", f"{url}/v1/jumps", LONG_JUMP)
        victims = wait_until(lambda: server.compute_processes()[server.pid], "a compute process")
        assert len(victims) == 1
        wait_until(lambda: _lane(url, "gecko_lane_running") == 1, "the jump runs")
        # A plan takes the other process.
        survivor = Call("POST", f"{url}/v1/plans", LIVE_PLAN)
        wait_until(lambda: _lane(url, "gecko_lane_running") == 2, "the plan runs too")
        os.kill(victims[0], signal.SIGKILL)

        lost = doomed.result()
        assert lost.status_code == 503, lost.text
        assert lost.json()["error"]["code"] == "worker_lost"
        assert "retry" in lost.json()["error"]["message"]
        assert int(lost.headers["retry-after"]) >= 1
        planned = survivor.result()
        assert planned.status_code == 200, planned.text
        assert planned.json()["status"] in {"SOLVED", "APPROXIMATE"}

        # A fresh process replaced the dead one without waiting for the next request.
        def replaced() -> bool:
            pids = server.compute_processes()[server.pid]
            return len(pids) == 2 and victims[0] not in pids

        wait_until(replaced, "a replacement process")
        samples = metric_samples(url)
        assert sample_value(samples, "gecko_worker_pool_restarts_total") == 1
        assert sample_value(samples, "gecko_lane_processes", lane="interactive") == 2
        assert sample_value(samples, "gecko_resident_memory_bytes", process="interactive") > 0

        # An idle process killed: the next requests never see it.
        idle = server.compute_processes()[server.pid]
        os.kill(idle[0], signal.SIGKILL)
        wait_until(lambda: _gone(idle[:1]), "the idle process dead")
        later = [Call("POST", f"{url}/v1/twister/step", LIVE_STEP) for _ in range(2)]
        for call in later:
            step = call.result()
            assert step.status_code == 200, step.text
            assert step.json()["status"] == "SOLVED"

        # A job's process killed: that job fails, saying why; the next one is built.
        before = set(server.compute_processes()[server.pid])
        posted = httpx.post(f"{url}/v1/roadmaps", json=BIG_ROADMAP, timeout=60)
        assert posted.status_code == 202, posted.text
        build = posted.json()["id"]
        wait_until(lambda: _job(url, build)["status"] == "running", "the build runs")
        (builder,) = set(server.compute_processes()[server.pid]) - before
        os.kill(builder, signal.SIGKILL)
        failed = wait_until(lambda: (j := _job(url, build))["status"] == "failed" and j, "failed")
        assert failed["message"].startswith("worker_lost: the jobs process running this")
        small = httpx.post(f"{url}/v1/roadmaps", json=SMALL_ROADMAP, timeout=60)
        assert small.status_code in (200, 202), small.text
        wait_until(lambda: _job(url, small.json()["id"])["status"] == "done", "the next build done")
        _stop_and_check_tree(server)
        assert "died under its task" in server.log()


def _answers_alone(server: ServerProcess, worker: int, path: str) -> httpx.Response:
    """GET ``path`` while every other uvicorn worker is stopped (SIGSTOP): only ``worker``
    can accept the connection, so it is the one answering."""
    others = [pid for pid in server.uvicorn_workers() if pid != worker]
    for pid in others:
        os.kill(pid, signal.SIGSTOP)
    try:
        return httpx.get(f"{server.url}{path}", timeout=20)
    finally:
        for pid in others:
            os.kill(pid, signal.SIGCONT)


def test_two_uvicorn_workers_share_jobs_across_crashes_and_restarts(tmp_path: Path) -> None:
    home = tmp_path / "home"
    with server_process(home, workers=2) as server:
        url = server.url
        posted = httpx.post(f"{url}/v1/plans", json={**LIVE_PLAN, "async": True}, timeout=60)
        assert posted.status_code == 202, posted.text
        plan_job = posted.json()["id"]
        done = wait_until(lambda: (j := _job(url, plan_job))["status"] == "done" and j, "plan done")

        # kill -9 of the uvicorn worker serving a long jump: its compute process dies with it
        # (long before the jump would have ended), and uvicorn starts another worker.
        before = {pid for pids in server.compute_processes().values() for pid in pids}
        jump = Call("POST", f"{url}/v1/jumps", LONG_JUMP)

        def jump_process() -> tuple[int, int] | None:
            for worker, pids in server.compute_processes().items():
                for pid in set(pids) - before:
                    return worker, pid
            return None

        worker, process = wait_until(jump_process, "the jump's compute process")
        wait_until(lambda: psutil.Process(process).cpu_times().user > 0.5, "the jump computes")
        os.kill(worker, signal.SIGKILL)
        wait_until(lambda: _gone([worker, process]), "the jump's process gone with its worker", 10)
        with contextlib.suppress(httpx.HTTPError):  # or the connection closed under it
            assert jump.result().status_code >= 500  # an error, not a hang
        wait_until(lambda: len(server.uvicorn_workers()) == 2, "a replacement uvicorn worker")

        build = httpx.post(f"{url}/v1/roadmaps", json=BIG_ROADMAP, timeout=60)
        assert build.status_code == 202, build.text
        roadmap = build.json()["id"]
        wait_until(lambda: _job(url, roadmap)["status"] == "running", "the roadmap builds")

        workers = server.uvicorn_workers()
        assert len(workers) == 2
        for worker in workers:  # each worker answers for both jobs
            for job_id, state in ((plan_job, "done"), (roadmap, "running")):
                seen = _answers_alone(server, worker, f"/v1/jobs/{job_id}")
                assert seen.status_code == 200, seen.text
                assert seen.json()["status"] == state

        # kill -9 of the uvicorn worker building the roadmap: the job is reported
        # interrupted, its compute processes die, the rest works.
        compute = server.compute_processes()
        owner = _owner_pid(home, roadmap)
        assert compute[owner], compute
        os.kill(owner, signal.SIGKILL)
        wait_until(lambda: _gone([owner, *compute[owner]]), "the worker and its processes gone")
        wait_until(lambda: len(server.uvicorn_workers()) == 2, "a replacement uvicorn worker")
        wait_until(lambda: _job(url, roadmap)["status"] == "interrupted", "the build interrupted")
        assert _job(url, plan_job)["result"] == done["result"]
        step = httpx.post(f"{url}/v1/twister/step", json=LIVE_STEP, timeout=WAIT_S)
        assert step.status_code == 200, step.text

        # SIGTERM while another build runs: the whole tree stops.
        again = httpx.post(f"{url}/v1/roadmaps", json={**BIG_ROADMAP, "seed": 5}, timeout=60)
        assert again.status_code == 202, again.text
        second = again.json()["id"]
        wait_until(lambda: _job(url, second)["status"] == "running", "the second build runs")
        _stop_and_check_tree(server)

    with server_process(home, workers=2) as restarted:  # the same home: the jobs are there
        for worker in restarted.uvicorn_workers():
            plan = _answers_alone(restarted, worker, f"/v1/jobs/{plan_job}")
            assert plan.status_code == 200, plan.text
            assert plan.json()["status"] == "done"
            assert plan.json()["result"] == done["result"]
            for job_id in (roadmap, second):
                build_job = _answers_alone(restarted, worker, f"/v1/jobs/{job_id}")
                assert build_job.status_code == 200, build_job.text
                assert build_job.json()["status"] == "interrupted", build_job.text
        stored = httpx.get(f"{restarted.url}{done['result']['url']}", timeout=60)
        assert stored.status_code == 200
        _stop_and_check_tree(restarted)


def test_sigterm_during_a_request_stops_the_tree(tmp_path: Path) -> None:
    with server_process(tmp_path / "home", grace_s=2) as server:
        running = Call("POST", f"{server.url}/v1/jumps", LONG_JUMP)
        wait_until(lambda: _lane(server.url, "gecko_lane_running") == 1, "the jump runs")
        # the lane's process starts off the event loop: the jump runs once it is there
        wait_until(lambda: server.compute_processes()[server.pid], "the jump's process")
        _stop_and_check_tree(server)
        # The client is not left hanging: an error answer or a closed connection.
        with contextlib.suppress(httpx.HTTPError):  # or a closed connection
            answer = running.result()
            assert answer.status_code >= 500, answer.text
