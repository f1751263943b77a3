"""The operator's basics against a real server (uvicorn on a port): /metrics, gzip of plan
answers and GLB downloads."""

from __future__ import annotations

import gzip
from pathlib import Path
from typing import Any

import httpx

from tests.live_process import server_process
from tests.prometheus_text import metric_samples as _samples
from tests.prometheus_text import sample_value as _value


def test_metrics_parse_and_count_a_request(
    gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    before = _samples(gecko_url)
    labels = {"method": "GET", "route": "/v1/scenes/{scene_id}", "status": "404"}
    for _ in range(3):
        assert httpx.get(f"{gecko_url}/v1/scenes/no-such-scene", timeout=30).status_code == 404
    after = _samples(gecko_url)
    counted = _value(after, "gecko_http_requests_total", **labels)
    assert counted - _value(before, "gecko_http_requests_total", **labels) == 3
    # The latency histogram of the same requests: counts, and a +Inf bucket holding them all.
    assert _value(after, "gecko_http_request_duration_seconds_count", **labels) == counted
    assert _value(after, "gecko_http_request_duration_seconds_bucket", **labels, le="+Inf") == (
        counted
    )
    # Paths no route serves share one label (metric labels stay bounded).
    httpx.get(f"{gecko_url}/no/such/path/at/all", timeout=30)
    unmatched = {"method": "GET", "route": "<unmatched>", "status": "404"}
    assert _value(_samples(gecko_url), "gecko_http_requests_total", **unmatched) >= 1
    # Answers by kind and status: the live plan, step and jump were counted.
    for kind, answer in live_results.items():
        status = answer["status"]
        assert _value(after, "gecko_answers_total", kind=kind, status=status) >= 1, kind
    assert _value(after, "gecko_worker_processes") == 1
    assert _value(after, "gecko_worker_tasks") == 0
    assert ("gecko_worker_pool_restarts_total", ()) in after
    for state in ("queued", "running", "done", "failed", "cancelled", "interrupted"):
        assert ("gecko_jobs", (("kind", "roadmap"), ("state", state))) in after
    for lane in ("interactive", "jobs", "uploads"):
        assert _value(after, "gecko_queue_depth", lane=lane) == 0
        assert _value(after, "gecko_lane_running", lane=lane) == 0
    assert _value(after, "gecko_queue_limit", lane="interactive") == 16
    assert _value(after, "gecko_http_requests_in_progress") == 1  # the scrape itself


def test_plan_answers_come_gzipped_and_identical(
    gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    plan_id = live_results["plan"]["id"]
    with httpx.Client(base_url=gecko_url, timeout=60) as http:
        with http.stream(
            "GET", f"/v1/plans/{plan_id}", headers={"Accept-Encoding": "gzip"}
        ) as response:
            assert response.status_code == 200
            assert response.headers["content-encoding"] == "gzip"
            raw = b"".join(response.iter_raw())
        plain = http.get(f"/v1/plans/{plan_id}", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers
    assert gzip.decompress(raw) == plain.content
    assert len(raw) < len(plain.content) / 3
    print(f"plan answer: {len(plain.content)} bytes, gzipped {len(raw)}")


def test_glb_downloads_still_work_gzipped_or_not(
    gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    step_id = live_results["step"]["id"]
    path = f"/v1/twister/steps/{step_id}.glb?scene=true"
    with httpx.Client(base_url=gecko_url, timeout=60) as http:
        zipped = http.get(path, headers={"Accept-Encoding": "gzip"})
        plain = http.get(path, headers={"Accept-Encoding": "identity"})
    for response in (zipped, plain):
        assert response.status_code == 200
        assert response.headers["content-type"] == "model/gltf-binary"
        assert "filename=" in response.headers["content-disposition"]
    assert zipped.content == plain.content  # httpx undid the gzip
    assert plain.content[:4] == b"glTF"
    assert int.from_bytes(plain.content[8:12], "little") == len(plain.content)


def test_metrics_with_two_uvicorn_workers_count_every_worker(tmp_path: Path) -> None:
    """With ``--workers 2`` any scrape (whichever worker answers it) gives the whole service's
    figures: prometheus-client's multiprocess mode, its directory made by the service."""
    home = tmp_path / "home"
    env = {"GECKO_WORKER_PROCESSES": "1", "GECKO_CHARACTERS": "humanoid"}
    with server_process(home, workers=2, env=env) as server:
        assert (home / "metrics" / str(server.pid)).is_dir()
        labels = {"method": "GET", "route": "/v1/scenes/{scene_id}", "status": "404"}
        for _ in range(12):  # a new connection each: spread over both workers
            assert httpx.get(f"{server.url}/v1/scenes/no-such-scene", timeout=30).status_code == 404
        for _ in range(6):  # a new connection each: whichever worker answers the scrape
            samples = _samples(server.url)
            assert _value(samples, "gecko_http_requests_total", **labels) == 12
            assert _value(samples, "gecko_worker_processes") == 2  # 1 per worker, summed
            assert _value(samples, "gecko_lane_slots", lane="interactive") == 2
            assert _value(samples, "gecko_resident_memory_bytes", process="service") > 0
