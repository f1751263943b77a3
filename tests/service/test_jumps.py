"""Roadmaps and jumps over HTTP: background build with progress, persistence, jump plans."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from asgi_lifespan import LifespanManager
from prometheus_client.parser import text_string_to_metric_families

from planner.ballistic.planner import JumpParams, RoadmapStore
from planner.ballistic.roadmap import Roadmap
from planner.character import get_character
from planner.offline import load_offline_data
from planner.scene import load_builtin_scene
from service.app import create_app
from service.quota import QuotaExceeded
from service.roadmap_storage import ROADMAP_BYTES_PER_NODE, admission
from service.settings import Settings
from tests.motion_audit import audit_from_json
from tests.paths import gecko_cache_dir

pytestmark = pytest.mark.anyio

ROADMAP = {
    "character": "quadruped",
    "scene": "gaps",
    "mu": 1.0,
    "vmax_takeoff": 6.0,
    "vmax_landing": 8.0,
    "nodes": 120,
    "seed": 5,
}
START = {"stand_at": [0.75, 0.0, 0.6]}
GOAL = {"stand_at": [8.25, 0.0, 1.0]}


async def _wait_done(client: httpx.AsyncClient, rid: str) -> dict[str, Any]:
    for _ in range(600):
        status = (await client.get(f"/v1/roadmaps/{rid}")).json()
        assert status["status"] in {"queued", "running", "done"}, status
        assert 0.0 <= status["progress"] <= 1.0
        if status["status"] == "done":
            return dict(status)
        await asyncio.sleep(0.2)
    raise AssertionError("roadmap build did not finish in 120 s")


def _check_jump(jump: dict[str, Any]) -> None:
    p0 = np.array(jump["takeoff"]["position"])
    v0 = np.array(jump["takeoff"]["velocity"])
    p1 = np.array(jump["landing"]["position"])
    t = jump["duration"]
    reached = p0 + v0 * t + 0.5 * np.array([0.0, 0.0, -9.81]) * t * t
    assert np.linalg.norm(reached - p1) < 1e-3
    assert jump["takeoff"]["contacts"] and jump["landing"]["contacts"]


async def test_roadmap_build_persist_and_jump(
    client: httpx.AsyncClient, settings: Settings
) -> None:
    response = await client.post("/v1/roadmaps", json=ROADMAP)
    assert response.status_code in (200, 202), response.text
    rid = response.json()["id"]
    done = await _wait_done(client, rid)
    assert done["nodes"] > 0
    again = await client.post("/v1/roadmaps", json=ROADMAP)
    assert again.status_code == 200
    assert again.json()["id"] == rid

    request = {
        "character": "quadruped",
        "scene": "gaps",
        "start": START,
        "goal": GOAL,
        "roadmap": rid,
        "seed": 1,
        "time_budget_s": 60,  # the most: a busy machine answers the same, only later
    }
    first = await client.post("/v1/jumps", json=request, timeout=120)
    assert first.status_code == 200, first.text
    body = first.json()
    # APPROXIMATE: every jump animated, the builder's report saying what is not clean
    assert body["status"] in {"SOLVED", "APPROXIMATE"}, body["message"]
    assert (body["status"] == "SOLVED") == bool(body["report"]["complete"])
    assert body["jumps"]
    for jump in body["jumps"]:
        _check_jump(jump)
        assert jump["push_start"] < jump["takeoff_time"] < jump["landing_time"] < jump["rest_time"]
    times = np.array([k["t"] for k in body["keyframes"]])
    steps = np.diff(times)
    assert len(times) > 5 and steps.min() > 0 and steps.max() - steps.min() < 1e-6
    assert body["phases"] and body["com"]
    assert body["report"]["phases_animated"] == len(body["phases"])
    assert isinstance(body["report"]["nodes_refused"], int) and body["report"]["nodes_refused"] >= 0
    assert isinstance(body["report"]["jumps_refused"], int) and body["report"]["jumps_refused"] >= 0
    flying = [
        k
        for k in body["keyframes"]
        if body["jumps"][0]["takeoff_time"] < k["t"] < body["jumps"][0]["landing_time"]
    ]
    assert flying and all(not k["contacts"] for k in flying)
    # the independent auditor: the keyframes' COM on each parabola in flight, no root jump
    # outside the jumps (push to rest), no link 1 cm inside the scene
    mesh = (await client.get("/v1/scenes/gaps/mesh", params={"format": "stl"})).content
    spans = [(j["push_start"], j["rest_time"]) for j in body["jumps"]]
    audit = audit_from_json(body, "quadruped", mesh, flights=spans)
    assert audit.root_jumps == 0 and audit.penetrating_frames == 0, audit.summary()
    gravity = np.array([0.0, 0.0, -9.81])
    for jump in body["jumps"]:
        t0, t1 = jump["takeoff_time"], jump["landing_time"]
        for t, com in zip(audit.times, audit.coms, strict=True):
            if t0 <= t <= t1:
                tau = t - t0
                p0, v0 = (
                    np.array(jump["takeoff"]["position"]),
                    np.array(jump["takeoff"]["velocity"]),
                )
                assert np.linalg.norm(com - (p0 + v0 * tau + 0.5 * gravity * tau**2)) < 0.02

    app = create_app(settings)  # a restart: the finished roadmap is still there
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as fresh,
    ):
        status = (await fresh.get(f"/v1/roadmaps/{rid}")).json()
        assert status["status"] == "done"
        replay = (await fresh.post("/v1/jumps", json=request, timeout=120)).json()
    body.pop("timings")
    replay.pop("timings")
    assert replay == body


async def test_jumps_without_roadmap(client: httpx.AsyncClient) -> None:
    request = {
        "character": "quadruped",
        "scene": "gaps",
        "start": START,
        "goal": GOAL,
        "nodes": 150,
        "seed": 2,
        "time_budget_s": 60,  # the most: a busy machine answers the same, only later
    }
    response = await client.post("/v1/jumps", json=request, timeout=120)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["status"] in {"SOLVED", "APPROXIMATE", "INFEASIBLE", "TIMEOUT"}
    for jump in body["jumps"]:
        _check_jump(jump)


@pytest.mark.parametrize(
    ("path", "body", "status", "field"),
    [
        ("/v1/roadmaps", {**ROADMAP, "nodes": 10_001}, 422, "nodes"),
        ("/v1/roadmaps", {**ROADMAP, "vmax_takeoff": 0}, 422, "vmax_takeoff"),
        ("/v1/roadmaps", {**ROADMAP, "scene": "nowhere"}, 404, "scene"),
        (
            "/v1/jumps",
            {
                "character": "quadruped",
                "scene": "gaps",
                "start": START,
                "goal": GOAL,
                "roadmap": "0123abcd",
            },
            404,
            "roadmap",
        ),
        (
            "/v1/jumps",
            {
                "character": "quadruped",
                "scene": "gaps",
                "start": START,
                "goal": GOAL,
                "time_budget_s": 90,
            },
            422,
            "time_budget_s",
        ),
    ],
)
async def test_bad_requests(
    client: httpx.AsyncClient, path: str, body: dict[str, Any], status: int, field: str
) -> None:
    response = await client.post(path, json=body, timeout=60)
    assert response.status_code == status, response.text
    assert response.json()["error"]["field"].startswith(field)


async def test_unknown_roadmap_is_404(client: httpx.AsyncClient) -> None:
    response = await client.get("/v1/roadmaps/deadbeef")
    assert response.status_code == 404
    assert response.json()["error"]["field"] == "roadmap_id"


async def test_roadmaps_quota_refuses_a_build_before_it_starts_and_delete_frees_it(
    settings: Settings,
) -> None:
    """A build whose estimated size would take the stored roadmaps past
    GECKO_ROADMAPS_QUOTA_BYTES is refused (507, naming the setting and the field) before any
    work; a finished roadmap's DELETE removes its files (204), its id then answers 404, and
    the freed room takes the refused build."""
    small = ROADMAP["nodes"] * ROADMAP_BYTES_PER_NODE
    room = settings.model_copy(update={"roadmaps_quota_bytes": max(1024 * 1024, 2 * small)})
    app = create_app(room)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as client,
    ):
        too_big = {**ROADMAP, "nodes": room.roadmaps_quota_bytes // ROADMAP_BYTES_PER_NODE + 1}
        refused = await client.post("/v1/roadmaps", json=too_big)
        assert refused.status_code == 507, refused.text
        error = refused.json()["error"]
        assert error["code"] == "quota_exceeded" and error["field"] == "nodes"
        assert "GECKO_ROADMAPS_QUOTA_BYTES" in error["message"]
        assert not list(room.roadmaps_path.glob("*.npz"))  # nothing was built

        built = await client.post("/v1/roadmaps", json=ROADMAP)
        rid = built.json()["id"]
        await _wait_done(client, rid)
        stored = RoadmapStore(room.roadmaps_path).used_bytes()
        assert 0 < stored <= ROADMAP["nodes"] * ROADMAP_BYTES_PER_NODE  # the estimate bounds it
        scraped = {
            sample.name: sample.value
            for family in text_string_to_metric_families((await client.get("/metrics")).text)
            for sample in family.samples
        }
        assert scraped["gecko_roadmaps_stored_bytes"] == stored
        assert scraped["gecko_roadmaps_quota_bytes"] == room.roadmaps_quota_bytes
        fits = {**too_big, "nodes": (room.roadmaps_quota_bytes - stored) // ROADMAP_BYTES_PER_NODE}
        assert (
            await client.post("/v1/roadmaps", json={**fits, "nodes": fits["nodes"] + 1})
        ).status_code == 507

        deleted = await client.delete(f"/v1/roadmaps/{rid}")
        assert deleted.status_code == 204, deleted.text
        assert RoadmapStore(room.roadmaps_path).used_bytes() == 0
        gone = await client.get(f"/v1/roadmaps/{rid}")
        assert gone.status_code == 404 and gone.json()["error"]["field"] == "roadmap_id"
        jump = await client.post(
            "/v1/jumps",
            json={
                "character": "quadruped",
                "scene": "gaps",
                "start": START,
                "goal": GOAL,
                "roadmap": rid,
            },
        )
        assert jump.status_code == 404 and jump.json()["error"]["field"] == "roadmap"
        assert (await client.delete(f"/v1/roadmaps/{rid}")).status_code == 404  # gone
        again = await client.post("/v1/roadmaps", json={**fits, "nodes": fits["nodes"] + 1})
        assert again.status_code == 202, again.text  # the freed room
        assert (await client.delete(f"/v1/roadmaps/{again.json()['id']}")).json()[
            "status"
        ] == "cancelled"


def test_a_roadmap_past_the_quota_when_stored_leaves_nothing(tmp_path: Path) -> None:
    """The quota is checked again on the real size when the files are stored (builds
    admitted together): a refused roadmap leaves no file, and one that fits is stored."""
    character = get_character("quadruped")
    data = load_offline_data(character, gecko_cache_dir())
    scene = load_builtin_scene("gaps", gecko_cache_dir())
    source = RoadmapStore(tmp_path / "source")
    roadmap = source.load(source.build(scene, character, data, JumpParams(), 8, 0))
    store = RoadmapStore(tmp_path / "store")
    with pytest.raises(QuotaExceeded):
        store.save("abc", roadmap, {"nodes": 3}, admission(store.directory, 100))
    assert sorted(p.name for p in store.directory.iterdir() if p.name != ".lock") == []
    store.save("abc", roadmap, {"nodes": 3}, admission(store.directory, 1024 * 1024))
    assert store.exists("abc") and isinstance(store.load("abc"), Roadmap)
    assert sorted(p.name for p in store.directory.iterdir() if p.name != ".lock") == [
        "abc.json",
        "abc.npz",
    ]
