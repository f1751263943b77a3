"""Session fixtures: one live Gecko server (uvicorn on a local port) and one stored plan,
Twister step and jump on it, shared by the export, viewer and client tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from service.settings import Settings
from tests.live_server import live_server
from tests.paths import gecko_cache_dir

# The cheapest answer of each kind: a 0.5 m humanoid walk on flat ground (about 10 contact
# changes, 9 s of motion), one Twister move of the quadruped, a short jump roadmap query.
LIVE_PLAN = {
    "character": "humanoid",
    "scene": "flat",
    "start": {"stand_at": [0.0, 0.0, 0.0]},
    "goal": {"stand_at": [0.5, 0.0, 0.0]},
    "seed": 1,
    "time_budget_s": 10,
}
LIVE_STEP = {
    "character": "quadruped",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "break", "limb": "lf_foot"},
    "seed": 3,
}
LIVE_JUMP = {
    "character": "quadruped",
    "scene": "gaps",
    "start": {"stand_at": [0.75, 0.0, 0.6]},
    "goal": {"stand_at": [8.25, 0.0, 1.0]},
    "nodes": 150,
    "seed": 2,
    "time_budget_s": 30,
}
LIVE_PATHS = {"plan": "/v1/plans", "step": "/v1/twister/step", "jump": "/v1/jumps"}
LIVE_REQUESTS = {"plan": LIVE_PLAN, "step": LIVE_STEP, "jump": LIVE_JUMP}


@pytest.fixture(scope="session")
def gecko_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Base URL of a real Gecko server (humanoid and quadruped, one planning worker)."""
    home: Path = tmp_path_factory.mktemp("gecko-live")
    settings = Settings(
        home=home,
        cache_dir=gecko_cache_dir(),
        scenes_dir=home / "scenes",
        characters="humanoid,quadruped",
        worker_processes=1,
        log_level="warning",  # request lines from the server's thread would land between tests
    )
    with live_server(settings) as url:
        yield url


@pytest.fixture(scope="session")
def live_results(gecko_url: str) -> dict[str, dict[str, Any]]:
    """One stored answer of each kind (plan, step, jump), posted once: kind -> response."""
    out = {}
    for kind, path in LIVE_PATHS.items():
        response = httpx.post(f"{gecko_url}{path}", json=LIVE_REQUESTS[kind], timeout=180)
        assert response.status_code == 200, response.text
        body = response.json()
        assert body["keyframes"], f"the live {kind} has no keyframes: {body.get('status')}"
        out[kind] = body
    return out
