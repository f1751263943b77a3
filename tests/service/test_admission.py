"""Admission control, deadlines, cancellation and shared jobs against real servers (uvicorn on
local ports). Two servers share one GECKO_HOME, as two uvicorn workers do.

Nothing here times anything: every wait is for a state the server reports (its /metrics, a
job's status), bounded only so that a broken server fails instead of hanging.
"""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from service import lanes
from service.settings import Settings
from tests.live_fixtures import LIVE_JUMP, LIVE_PLAN, LIVE_STEP
from tests.live_server import live_server, wait_until
from tests.paths import gecko_cache_dir
from tests.prometheus_text import metric_samples, sample_value

# A roadmap far too big to finish while a test looks at it (tens of seconds of CPU); cancelled
# at the end of each test that starts one.
BIG_ROADMAP = {"character": "quadruped", "scene": "gaps", "nodes": 10_000, "seed": 100}
SMALL_ROADMAP = {"character": "quadruped", "scene": "gaps", "nodes": 60, "seed": 7}
# A jump without a roadmap builds one of ``nodes`` nodes within its budget: a long request.
LONG_JUMP = {**LIVE_JUMP, "nodes": 10_000, "time_budget_s": 60}
WAIT_S = 180.0  # the longest any wait below may take before the test fails


def _settings(home: Path) -> Settings:
    return Settings(
        home=home,
        cache_dir=gecko_cache_dir(),
        scenes_dir=home / "scenes",
        characters="humanoid,quadruped",
        worker_processes=1,
        interactive_queue=1,
        step_queue=1,
        job_processes=1,
        job_queue=1,
        log_level="warning",
    )


@pytest.fixture(scope="module")
def shared_home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("gecko-shared")


@pytest.fixture(scope="module")
def server_a(shared_home: Path) -> Iterator[str]:
    """One of two servers sharing a home: one planning process, one waiting place for plans
    and jumps and one for Twister steps."""
    with live_server(_settings(shared_home)) as url:
        yield url


@pytest.fixture(scope="module")
def server_b(shared_home: Path) -> Iterator[str]:
    """The other server on the same home (another uvicorn worker, as far as jobs go)."""
    with live_server(_settings(shared_home)) as url:
        yield url


def _lane(url: str, metric: str, lane: str) -> float:
    return sample_value(metric_samples(url), metric, lane=lane)


def _job(url: str, path: str) -> dict[str, Any]:
    response = httpx.get(f"{url}{path}", timeout=30)
    assert response.status_code == 200, response.text
    return dict(response.json())


def _refused(response: httpx.Response, code: str, limit: str | None = None) -> None:
    assert response.status_code == 503, response.text
    assert int(response.headers["retry-after"]) >= 1
    error = response.json()["error"]
    assert error["code"] == code
    if limit is not None:
        assert limit in error["message"]


def _raw_post(url: str, path: str, body: dict[str, Any]) -> socket.socket:
    """Send a POST on a bare socket (closing it later is a client going away)."""
    host, port = url.removeprefix("http://").split(":")
    sock = socket.create_connection((host, int(port)))
    data = json.dumps(body).encode()
    head = f"POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
    sock.sendall(f"{head}Content-Length: {len(data)}\r\n\r\n".encode() + data)
    return sock


def test_a_flood_of_roadmap_builds_leaves_twister_steps_answering(server_a: str) -> None:
    answers = [
        httpx.post(f"{server_a}/v1/roadmaps", json={**BIG_ROADMAP, "seed": seed}, timeout=60)
        for seed in (101, 102, 103, 104)
    ]
    # One build runs in the job process, one waits (GECKO_JOB_QUEUE=1), the rest are refused
    # at once, with Retry-After and the limit named.
    assert [a.status_code for a in answers[:2]] == [202, 202], answers[1].text
    for answer in answers[:2]:
        assert answer.headers["location"] == f"/v1/roadmaps/{answer.json()['id']}"
    for answer in answers[2:]:
        _refused(answer, "queue_full", "GECKO_JOB_QUEUE=1")
    step = httpx.post(f"{server_a}/v1/twister/step", json=LIVE_STEP, timeout=120)
    assert step.status_code == 200, step.text
    assert step.json()["status"] == "SOLVED"
    samples = metric_samples(server_a)
    assert sample_value(samples, "gecko_lane_running", lane="jobs") == 1
    assert sample_value(samples, "gecko_queue_depth", lane="jobs") == 1
    assert sample_value(samples, "gecko_refused_total", lane="jobs", reason="queue_full") == 2
    for answer in answers[:2]:
        rid = answer.json()["id"]
        deleted = httpx.delete(f"{server_a}/v1/roadmaps/{rid}", timeout=30)
        assert deleted.status_code == 200, deleted.text
        assert deleted.json()["status"] == "cancelled"
        assert _job(server_a, f"/v1/roadmaps/{rid}")["status"] == "cancelled"
    # The DELETE stopped the build's process there and then: the lane is empty again.
    samples = metric_samples(server_a)
    assert sample_value(samples, "gecko_lane_running", lane="jobs") == 0
    assert sample_value(samples, "gecko_queue_depth", lane="jobs") == 0
    assert sample_value(samples, "gecko_jobs", kind="roadmap", state="cancelled") >= 2


def test_full_queue_deadline_from_arrival_and_client_disconnect(server_a: str) -> None:
    def stopped() -> float:
        samples = metric_samples(server_a)
        name = "gecko_worker_tasks_stopped_total"
        return sample_value(samples, name, lane="interactive", reason="cancelled")

    before = stopped()
    long_jump = _raw_post(server_a, "/v1/jumps", LONG_JUMP)
    try:
        wait_until(lambda: _lane(server_a, "gecko_lane_running", "interactive") == 1, "jump runs")
        # The one waiting place: a step whose budget runs out while it waits is refused,
        # having cost nothing (its budget counts from its arrival, not from its start).
        waiting: dict[str, httpx.Response] = {}
        slow = {**LIVE_STEP, "time_budget_s": 2}
        thread = threading.Thread(
            target=lambda: waiting.update(
                r=httpx.post(f"{server_a}/v1/twister/step", json=slow, timeout=120)
            )
        )
        thread.start()
        wait_until(lambda: _lane(server_a, "gecko_queue_depth", "interactive") == 1, "step waits")
        # No waiting place left for steps (GECKO_STEP_QUEUE=1): refused at once.
        full = httpx.post(f"{server_a}/v1/twister/step", json=LIVE_STEP, timeout=120)
        _refused(full, "queue_full", "GECKO_STEP_QUEUE=1")
        thread.join(timeout=WAIT_S)
        _refused(waiting["r"], "queue_timeout")
    finally:
        long_jump.close()  # the client goes away: the jump's process is killed
    wait_until(lambda: _lane(server_a, "gecko_lane_running", "interactive") == 0, "jump stopped")
    assert stopped() == before + 1
    step = httpx.post(f"{server_a}/v1/twister/step", json=LIVE_STEP, timeout=120)
    assert step.status_code == 200, step.text


def test_an_async_plan_is_a_job_any_worker_answers(server_a: str, server_b: str) -> None:
    posted = httpx.post(f"{server_a}/v1/plans", json={**LIVE_PLAN, "async": True}, timeout=60)
    assert posted.status_code == 202, posted.text
    location = posted.headers["location"]
    job = posted.json()
    assert location == f"/v1/jobs/{job['id']}"
    assert (job["kind"], job["status"]) == ("plan", "queued")
    seen = _job(server_b, location)  # the other worker reads the same job
    assert seen["id"] == job["id"] and seen["status"] in {"queued", "running", "done"}
    done = wait_until(lambda: (j := _job(server_b, location))["status"] == "done" and j, "done")
    result = done["result"]
    assert (result["kind"], result["url"]) == ("plan", f"/v1/plans/{result['id']}")
    # The plan is the synchronous answer: same id, stored where every worker finds it.
    stored = httpx.get(f"{server_b}{result['url']}", timeout=60)
    assert stored.status_code == 200
    assert stored.json()["status"] == result["status"]
    sync = httpx.post(f"{server_b}/v1/plans", json=LIVE_PLAN, timeout=120)
    assert sync.status_code == 200, sync.text
    assert sync.json()["id"] == result["id"]
    again = httpx.delete(f"{server_a}{location}", timeout=30)
    assert again.status_code == 409  # finished: nothing to cancel
    assert httpx.get(f"{server_a}/v1/jobs/nosuchjob", timeout=30).status_code == 404


def test_a_delete_on_one_worker_stops_the_job_on_the_other(server_a: str, server_b: str) -> None:
    def stopped() -> float:
        samples = metric_samples(server_a)
        name = "gecko_worker_tasks_stopped_total"
        return sample_value(samples, name, lane="jobs", reason="cancelled")

    before = stopped()
    posted = httpx.post(f"{server_a}/v1/roadmaps", json=BIG_ROADMAP, timeout=60)
    assert posted.status_code == 202, posted.text
    rid = posted.json()["id"]
    wait_until(lambda: _job(server_b, f"/v1/jobs/{rid}")["status"] == "running", "build runs")
    deleted = httpx.delete(f"{server_b}/v1/jobs/{rid}", timeout=30)
    assert deleted.status_code == 200, deleted.text
    assert deleted.json()["status"] == "cancelled"
    # Server A sees the DELETE in the store and kills the build's process.
    wait_until(lambda: _lane(server_a, "gecko_lane_running", "jobs") == 0, "A's job process freed")
    assert stopped() == before + 1
    assert _job(server_a, f"/v1/roadmaps/{rid}")["status"] == "cancelled"
    # The freed process builds the next roadmap.
    small = httpx.post(f"{server_a}/v1/roadmaps", json=SMALL_ROADMAP, timeout=60)
    assert small.status_code in (200, 202), small.text
    path = f"/v1/roadmaps/{small.json()['id']}"
    wait_until(lambda: _job(server_b, path)["status"] == "done", "the small roadmap is built")


def test_a_job_survives_a_restart_as_interrupted(shared_home: Path, server_b: str) -> None:
    with live_server(_settings(shared_home)) as first:
        posted = httpx.post(f"{first}/v1/roadmaps", json=BIG_ROADMAP, timeout=60)
        assert posted.status_code == 202, posted.text
        rid = posted.json()["id"]
        wait_until(lambda: _job(first, f"/v1/roadmaps/{rid}")["status"] == "running", "build runs")
    # That server stopped mid-build: every worker says so, and why.
    status = _job(server_b, f"/v1/roadmaps/{rid}")
    assert status["status"] == "interrupted", status
    assert "submit it again" in status["message"]
    with live_server(_settings(shared_home)) as restarted:
        assert _job(restarted, f"/v1/jobs/{rid}")["status"] == "interrupted"
        again = httpx.post(f"{restarted}/v1/roadmaps", json=BIG_ROADMAP, timeout=60)
        assert again.status_code == 202, again.text
        assert again.json()["status"] in {"queued", "running"}
        deleted = httpx.delete(f"{restarted}/v1/roadmaps/{rid}", timeout=30)
        assert deleted.json()["status"] == "cancelled"


def test_while_steps_come_a_jump_waits_rather_than_take_the_last_process(
    shared_home: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two planning processes: once a Twister step has come, plans and jumps hold one of
    them (GECKO_STEP_PROCESSES=1) and a step runs at once on the other, never behind
    them."""
    # steps "keep coming" for the whole test however slow the machine (the server runs in
    # this process); the lapse of the window is tested on the gate (tests/service/test_lanes)
    monkeypatch.setattr(lanes, "SHORT_DEMAND_S", 3600.0)
    settings = _settings(shared_home).model_copy(update={"worker_processes": 2})
    with live_server(settings) as url:
        first = httpx.post(f"{url}/v1/twister/step", json=LIVE_STEP, timeout=120)
        assert first.status_code == 200, first.text
        jumps = [_raw_post(url, "/v1/jumps", {**LONG_JUMP, "seed": s}) for s in (1, 2)]
        try:
            wait_until(lambda: _lane(url, "gecko_queue_depth", "interactive") == 1, "jump waits")
            assert _lane(url, "gecko_lane_running", "interactive") == 1
            step = httpx.post(f"{url}/v1/twister/step", json=LIVE_STEP, timeout=120)
            assert step.status_code == 200, step.text
            assert step.json()["status"] == "SOLVED"
            # the second jump still waits: the step did not queue behind it
            assert _lane(url, "gecko_queue_depth", "interactive") == 1
            assert _lane(url, "gecko_lane_running", "interactive") == 1
        finally:
            for jump in jumps:
                jump.close()
        wait_until(lambda: _lane(url, "gecko_lane_running", "interactive") == 0, "jumps stop")
