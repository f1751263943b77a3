"""glTF export over HTTP: stored results by id, GLB validity (Khronos validator), the
animation against Pinocchio's forward kinematics, the y-up scene, determinism, bad input.

The GLB is read back with pygltflib and evaluated here, by code that shares nothing with
the exporter: accessors decoded from the binary chunk, node transforms composed down the
tree, animation samplers interpolated (linear, slerp) at the keyframe times.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pinocchio as pin
import pygltflib
import pytest

from planner.character import get_character
from service.results import ResultStore, StoredResult
from service.settings import Settings
from tests.gltf_reader import TO_Y_UP, accessor, world_transforms
from tests.gltf_validator import errors_of, validate
from tests.live_fixtures import LIVE_PLAN

GLB_PATHS = {"plan": "/v1/plans", "step": "/v1/twister/steps", "jump": "/v1/jumps"}


def _get(url: str, **params: Any) -> httpx.Response:
    return httpx.get(url, params=params, timeout=120)


def _glb(gecko_url: str, kind: str, rid: str, **params: Any) -> bytes:
    response = _get(f"{gecko_url}{GLB_PATHS[kind]}/{rid}.glb", **params)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "model/gltf-binary"
    return response.content


def _q(character: Any, keyframe: dict[str, Any]) -> np.ndarray:
    q = np.array(character.q_ref, dtype=np.float64)
    q[:3] = keyframe["root"]["position"]
    q[3:7] = keyframe["root"]["orientation"]
    for k, name in enumerate(character.joint_names):
        q[7 + k] = keyframe["joints"][name]
    return q


# -- tests ----------------------------------------------------------------------------------


def test_every_glb_passes_the_khronos_validator(
    gecko_url: str, live_results: dict[str, dict[str, Any]], tmp_path: Path
) -> None:
    files = []
    for kind, body in live_results.items():
        for params in ({}, {"scene": "true", "overlays": "true"}):
            path = tmp_path / f"{kind}-{len(params)}.glb"
            path.write_bytes(_glb(gecko_url, kind, body["id"], **params))
            files.append(path)
    for scene in ("flat", "stairs"):
        path = tmp_path / f"scene-{scene}.glb"
        response = _get(f"{gecko_url}/v1/scenes/{scene}/mesh", format="glb")
        assert response.status_code == 200
        path.write_bytes(response.content)
        files.append(path)
    reports = validate(files)
    assert len(reports) == len(files)
    for path, report in zip(files, reports, strict=True):
        assert report["issues"]["numErrors"] == 0, (path.name, errors_of(report))
        assert report["info"]["version"] == "2.0"


@pytest.mark.parametrize("kind", ["plan", "step", "jump"])
def test_animation_matches_forward_kinematics(
    gecko_url: str, live_results: dict[str, dict[str, Any]], kind: str
) -> None:
    body = live_results[kind]
    character = get_character(LIVE_PLAN["character"] if kind == "plan" else "quadruped")
    glb = _glb(gecko_url, kind, body["id"])
    model = character.model
    data = model.createData()
    keyframes = body["keyframes"]
    picks = sorted({0, len(keyframes) // 3, len(keyframes) // 2, len(keyframes) - 1})
    links = [f for f in model.frames if f.type == pin.FrameType.BODY]
    for index in picks:
        keyframe = keyframes[index]
        world = world_transforms(glb, float(np.float32(keyframe["t"])))
        pin.framesForwardKinematics(model, data, _q(character, keyframe))
        for frame in links:
            placement = data.oMf[model.getFrameId(frame.name)]
            expected_p = TO_Y_UP @ np.asarray(placement.translation)
            expected_r = TO_Y_UP @ np.asarray(placement.rotation)
            got = world[frame.name]
            assert np.abs(got[:3, 3] - expected_p).max() < 1e-5, (kind, index, frame.name)
            assert np.abs(got[:3, :3] - expected_r).max() < 1e-5, (kind, index, frame.name)


def test_glb_has_one_node_per_link_and_the_phases(
    gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    body = live_results["plan"]
    glb = _glb(gecko_url, "plan", body["id"], scene="true", overlays="true")
    gltf = pygltflib.GLTF2.load_from_bytes(glb)
    names = [node.name for node in gltf.nodes]
    character = get_character("humanoid")
    for frame in character.model.frames:
        if frame.type == pin.FrameType.BODY:
            assert names.count(frame.name) == 1
    assert {"scene", "com", "contacts"} <= set(names)
    extras = gltf.scenes[0].extras["gecko"]
    assert extras["id"] == body["id"] and extras["kind"] == "plan"
    assert [p["limbs"] for p in extras["phases"]] == [
        [c["limb"] for c in phase["contacts"]] for phase in body["phases"]
    ]
    assert len(gltf.animations) == 1
    assert len(gltf.animations[0].channels) == len(character.joint_names) + 2
    # Each standing phase carries its equilibrium outline: a horizontal loop (constant
    # glTF y) around the phase's contact points seen from above.
    outlines = [k for k, name in enumerate(names) if name.startswith("equilibrium_")]
    assert len(outlines) >= len(body["phases"]) // 2
    for index in outlines:
        primitive = gltf.meshes[gltf.nodes[index].mesh].primitives[0]
        assert primitive.mode == pygltflib.LINE_LOOP
        loop = accessor(gltf, gltf.binary_blob(), primitive.attributes.POSITION)
        assert len(loop) >= 3 and np.ptp(loop[:, 1]) < 1e-6


def test_scene_glb_is_y_up(gecko_url: str) -> None:
    response = _get(f"{gecko_url}/v1/scenes/stairs/mesh", format="glb")
    assert response.status_code == 200
    gltf = pygltflib.GLTF2.load_from_bytes(response.content)
    positions = accessor(gltf, gltf.binary_blob(), gltf.meshes[0].primitives[0].attributes.POSITION)
    bounds = np.array(httpx.get(f"{gecko_url}/v1/scenes/stairs", timeout=30).json()["bounds"])
    assert np.allclose(
        positions.min(axis=0), [bounds[0][0], bounds[0][2], -bounds[1][1]], atol=1e-5
    )
    assert np.allclose(
        positions.max(axis=0), [bounds[1][0], bounds[1][2], -bounds[0][1]], atol=1e-5
    )
    assert positions[:, 1].max() > 0.5, "the stairs rise along +y"
    stl = _get(f"{gecko_url}/v1/scenes/stairs/mesh", format="stl")
    assert stl.status_code == 200 and stl.headers["content-type"] == "model/stl"


def test_same_request_same_id_and_bytes(
    gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    first = live_results["plan"]
    again = httpx.post(f"{gecko_url}/v1/plans", json=LIVE_PLAN, timeout=180).json()
    assert again["id"] == first["id"]
    glb = _glb(gecko_url, "plan", first["id"])
    assert _glb(gecko_url, "plan", again["id"]) == glb
    assert _glb(gecko_url, "plan", first["id"], format="glb") == glb
    other = httpx.post(f"{gecko_url}/v1/plans", json={**LIVE_PLAN, "seed": 2}, timeout=180)
    assert other.json()["id"] != first["id"]
    stored = _get(f"{gecko_url}/v1/plans/{first['id']}")
    assert stored.status_code == 200
    assert stored.json()["keyframes"] == first["keyframes"]
    listed = _get(f"{gecko_url}/v1/results", kind="plan").json()
    assert first["id"] in {entry["id"] for entry in listed}


@pytest.mark.parametrize(
    ("path", "params", "status", "field"),
    [
        ("/v1/plans/0123456789abcdef0123456789abcdef", {}, 404, "id"),
        ("/v1/plans/not-an-id.glb", {}, 404, "id"),
        ("/v1/jumps/0123456789abcdef0123456789abcdef.glb", {}, 404, "id"),
        ("{plan}", {"format": "obj"}, 422, "format"),
        ("{plan}.glb", {"format": "json"}, 400, "format"),
        ("{plan}.png", {}, 400, "format"),
        ("/v1/twister/steps/{plan_id}", {}, 404, "id"),
        ("/v1/results", {"limit": 0}, 422, "limit"),
        ("/v1/results", {"kind": "dance"}, 422, "kind"),
        ("/v1/scenes/stairs/mesh", {"format": "fbx"}, 422, "format"),
    ],
)
def test_bad_requests_name_the_field(
    gecko_url: str,
    live_results: dict[str, dict[str, Any]],
    path: str,
    params: dict[str, str],
    status: int,
    field: str,
) -> None:
    rid = live_results["plan"]["id"]
    path = path.replace("{plan}", f"/v1/plans/{rid}").replace("{plan_id}", rid)
    response = _get(f"{gecko_url}{path}", **params)
    assert response.status_code == status, response.text
    error = response.json()["error"]
    assert error["field"] == field
    if status == 404:
        assert "unknown" in error["message"]


def _stored(rid: str, stamp: int) -> StoredResult:
    return StoredResult("plan", rid, {"seed": stamp}, {"status": "SOLVED", "keyframes": []})


def test_store_evicts_least_recently_used(tmp_path: Path) -> None:
    store = ResultStore(tmp_path, max_count=3, max_bytes=10**6)
    ids = [f"{k:032x}" for k in range(5)]
    for k, rid in enumerate(ids[:3]):
        assert store.put(_stored(rid, k), {"status": "SOLVED"})
    base = time.time() - 100
    for k, rid in enumerate(ids[:3]):  # 0 oldest
        for suffix in (".json", ".meta.json"):
            os.utime(tmp_path / f"{rid}{suffix}", (base + k, base + k))
    assert store.get(ids[0]) is not None  # used: now the most recent
    store.put(_stored(ids[3], 3), {})
    assert store.get(ids[1]) is None, "the least recently used went first"
    assert all(store.get(rid) is not None for rid in (ids[0], ids[2], ids[3]))
    assert len(store.summaries(10)) == 3
    small = ResultStore(tmp_path / "small", max_count=100, max_bytes=2 * 1024 * 1024)
    big = StoredResult("plan", ids[4], {}, {"blob": "x" * 3 * 1024 * 1024})
    assert not small.put(big, {}), "a result larger than the byte bound is not kept"
    for k in range(40):
        small.put(StoredResult("plan", f"{k:032x}", {}, {"blob": "y" * 100_000}), {})
    total = sum(p.stat().st_size for p in (tmp_path / "small").glob("*.json"))
    assert total <= 2 * 1024 * 1024


def test_a_result_stored_with_its_response_already_serialised_reads_back_the_same(
    tmp_path: Path,
) -> None:
    """The response written as the route's JSON body (``put(response_json=)``) reads back as
    the same result as one the store serialises itself, numbers to the bit."""
    response = {"status": "SOLVED", "keyframes": [{"t": 1 / 3, "q": [1e-05, -0.0, 2.5e300]}]}
    request = {"character": "humanoid", "seed": 7}
    own, given = (ResultStore(tmp_path / name, max_count=3, max_bytes=10**6) for name in "ab")
    stored = StoredResult("step", "cd" * 16, request, response)
    assert own.put(stored, {})
    assert given.put(stored, {}, response_json=json.dumps(response).encode())
    assert own.get(stored.id) == given.get(stored.id) == stored


@pytest.mark.anyio
async def test_result_stored_by_an_older_version_answers_410(
    client: httpx.AsyncClient, settings: Settings
) -> None:
    """A stored answer this code cannot read (another version's shape) is 410, never 500."""
    store = ResultStore(settings.results_path, max_count=10, max_bytes=10**6)
    rid = "ab" * 16
    request = {"character": "humanoid", "scene": "flat", "seed": 1}
    old = StoredResult("plan", rid, request, {"status": "SOLVED", "keyframes": [{"t": 0.0}]})
    assert store.put(old, {})
    for suffix in ("", ".glb"):
        response = await client.get(f"/v1/plans/{rid}{suffix}")
        assert response.status_code == 410, response.text
        assert response.json()["error"]["field"] == "id"
    assert (await client.get(f"/v1/plans/{'cd' * 16}")).status_code == 404


def test_result_without_keyframes_has_no_glb(gecko_url: str) -> None:
    failed = {**LIVE_PLAN, "goal": {"stand_at": [0.5, 0.0, 5.0]}, "time_budget_s": 2}
    body = httpx.post(f"{gecko_url}/v1/plans", json=failed, timeout=180).json()
    if body["keyframes"]:
        pytest.skip("that goal was reachable after all")
    response = _get(f"{gecko_url}/v1/plans/{body['id']}.glb")
    assert response.status_code == 409
    assert response.json()["error"]["field"] == "id"
