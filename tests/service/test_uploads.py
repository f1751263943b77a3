"""Scene uploads in the uploads lane's process: refused by their counts before they cost,
bounded by a quota, listed from stored metadata, held in memory by a bounded LRU.

Real servers (uvicorn on a local port, or the app in process with its lifespan) and real mesh
files. No speed is asserted: that /health is not held up by a parse is shown by its answers
arriving while an upload is in flight, not by a latency figure a busy machine would miss.
"""

from __future__ import annotations

import asyncio
import io
import json
import os
import threading
import time
from collections.abc import AsyncIterator, Iterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import trimesh
from asgi_lifespan import LifespanManager
from fastapi import FastAPI
from prometheus_client.parser import text_string_to_metric_families

from planner.scene import content_hash, load_mesh
from planner.scene.collision import bvh_cache_path
from planner.scene.io import validate_arrays
from service.app import create_app
from service.quota import QuotaExceeded
from service.registry import Registry
from service.settings import Settings
from tests.live_process import server_process
from tests.mesh_files import grid_mesh, grid_ply, instanced_dae, instanced_glb
from tests.paths import gecko_cache_dir
from tests.prometheus_text import metric_samples, sample_value

HEALTH_EVERY_S = 0.02
PROVING_UPLOAD_S = 10 * HEALTH_EVERY_S  # an upload this long must see /health answered inside it
MiB = 1024 * 1024
HOUR_S = 3600.0
QUOTA_BYTES = 48 * MiB  # the test servers' quota of uploaded scenes (a 60k-triangle one: 34)
SCENE_SUFFIXES = (".npz", ".json", ".detail.json")  # an uploaded scene's files


def _settings(home: Path, **overrides: object) -> Settings:
    values: dict[str, object] = {
        "home": home,
        "cache_dir": gecko_cache_dir(),
        "scenes_dir": home / "scenes",
        "characters": "humanoid",
        "max_upload_bytes": 20 * MiB,
        "max_triangles": 100_000,
        "scenes_quota_bytes": QUOTA_BYTES,
        "log_level": "warning",
        **overrides,
    }
    return Settings.model_validate(values)


def _box_stl(size: float) -> bytes:
    return bytes(trimesh.creation.box(extents=(size, size, 0.2)).export(file_type="stl"))


def _grid_stl(triangles: int) -> bytes:
    return bytes(grid_mesh(triangles).export(file_type="stl"))


def _error(response: httpx.Response, status: int, code: str) -> str:
    assert response.status_code == status, response.text
    error = response.json()["error"]
    assert error["code"] == code
    assert error["field"] == "body"
    return str(error["message"])


class HealthProbe:
    """Polls /health from a thread every HEALTH_EVERY_S and records when each asking started
    and its answer arrived (perf_counter seconds)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.answers: list[tuple[float, float]] = []
        self.failures: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="health-probe", daemon=True)

    def _run(self) -> None:
        with httpx.Client(base_url=self.url, timeout=10) as http:
            while not self._stop.is_set():
                started = time.perf_counter()
                response = http.get("/health")
                self.answers.append((started, time.perf_counter()))
                if response.status_code != 200:
                    self.failures.append(response.text)
                self._stop.wait(HEALTH_EVERY_S)

    def answered_within(self, start: float, end: float) -> int:
        """How many /health requests were both asked and answered between start and end."""
        return sum(1 for asked, answered in self.answers if asked >= start and answered <= end)

    def slowest(self) -> float:
        return max(answered - asked for asked, answered in self.answers)

    def __enter__(self) -> HealthProbe:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=30)


def _timed_post(
    http: httpx.Client, windows: list[tuple[float, float]], **kwargs: Any
) -> httpx.Response:
    """POST /v1/scenes, appending the request's (start, end) perf_counter seconds to windows."""
    started = time.perf_counter()
    response = http.post("/v1/scenes", **kwargs)
    windows.append((started, time.perf_counter()))
    return response


def _assert_health_answered_during_uploads(
    probe: HealthProbe, windows: list[tuple[float, float]]
) -> None:
    """Every upload in flight for PROVING_UPLOAD_S or longer saw /health answered inside it,
    and no /health answer waited half as long as the longest: a parse that held the server's
    event loop would leave none inside and one waiting out the whole parse."""
    assert not probe.failures
    slowest = probe.slowest()
    for start, end in windows:
        if end - start >= PROVING_UPLOAD_S:
            assert probe.answered_within(start, end) >= 1, (
                f"no /health answer during a {end - start:.2f} s upload; slowest {slowest:.2f} s"
            )
    longest = max(end - start for start, end in windows)
    if longest >= PROVING_UPLOAD_S:
        assert slowest < 0.5 * longest, f"/health waited {slowest:.2f} s, uploads {longest:.2f} s"


@pytest.fixture(scope="module")
def upload_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """The uvicorn command in its own process, as an operator runs it, with small limits:
    100,000 triangles, a 48 MiB quota of scenes. Its own process, so that /health's latency
    is the server's and not this test process's (whose uploading client and probe share one
    interpreter lock)."""
    home = tmp_path_factory.mktemp("gecko-uploads")
    limits = {
        "GECKO_CHARACTERS": "humanoid",
        "GECKO_MAX_UPLOAD_BYTES": str(20 * MiB),
        "GECKO_MAX_TRIANGLES": "100000",
        "GECKO_SCENES_QUOTA_BYTES": str(QUOTA_BYTES),
    }
    with server_process(home, env=limits) as server:
        yield server.url, home / "scenes"


def test_oversized_files_are_refused_before_parsing_while_health_answers(
    upload_server: tuple[str, Path],
) -> None:
    url, scenes = upload_server
    glb = instanced_glb(95, subdivisions=5)  # 20,480 triangles instanced 95 times: 1.9 M
    ply = grid_ply(500_000)
    accepted = _grid_stl(60_000)  # within the limit: parsed and built in the uploads lane
    assert len(glb) < 500_000 and len(ply) > 9_000_000
    windows: list[tuple[float, float]] = []
    with HealthProbe(url) as probe, httpx.Client(base_url=url, timeout=120) as http:
        time.sleep(5 * HEALTH_EVERY_S)
        refused_glb = _timed_post(http, windows, params={"format": "glb"}, content=glb)
        refused_ply = _timed_post(http, windows, params={"format": "ply"}, content=ply)
        built = _timed_post(
            http, windows, params={"format": "stl", "name": "grid"}, content=accepted
        )
        time.sleep(5 * HEALTH_EVERY_S)
    assert built.status_code == 201, built.text
    scene_id = built.json()["id"]
    names = sorted(path.name for path in scenes.iterdir() if not path.name.startswith("."))
    assert httpx.delete(f"{url}/v1/scenes/{scene_id}", timeout=30).status_code == 204
    assert names == [f"{scene_id}.detail.json", f"{scene_id}.json", f"{scene_id}.npz"]
    assert built.json()["triangle_count"] == len(grid_mesh(60_000).faces)
    message = _error(refused_glb, 413, "too_large")
    assert "1945600 triangles (after instancing)" in message, message
    assert "limit 100000" in message
    assert "GECKO_MAX_TRIANGLES" in _error(refused_ply, 413, "too_large")
    spans = ", ".join(f"{end - start:.3f}" for start, end in windows)
    print(f"uploads took {spans} s; /health slowest {probe.slowest():.3f} s")
    assert len(probe.answers) >= 10
    _assert_health_answered_during_uploads(probe, windows)


def test_the_quota_refuses_an_upload_and_delete_frees_it(
    upload_server: tuple[str, Path],
) -> None:
    url, scenes = upload_server
    # About 2.1 MiB of scene files each, and 32 MiB of cached BVH: one fits, not both.
    first, second = _grid_stl(60_000), _grid_stl(64_000)
    with httpx.Client(base_url=url, timeout=120) as http:
        kept = http.post("/v1/scenes", params={"format": "stl", "name": "a"}, content=first)
        assert kept.status_code == 201, kept.text
        listing = {scene["id"]: scene for scene in http.get("/v1/scenes").json()}
        assert listing[kept.json()["id"]]["triangle_count"] == kept.json()["triangle_count"]
        assert listing[kept.json()["id"]]["name"] == "a"
        refused = http.post("/v1/scenes", params={"format": "stl"}, content=second)
        message = _error(refused, 507, "quota_exceeded")
        assert "GECKO_SCENES_QUOTA_BYTES" in message and str(QUOTA_BYTES) in message, message
        assert not any(path.name.startswith(".tmp-") for path in scenes.iterdir())
        stored = metric_samples(url)
        assert sample_value(stored, "gecko_scenes_quota_bytes") == QUOTA_BYTES
        files = [scenes / f"{kept.json()['id']}{suffix}" for suffix in SCENE_SUFFIXES]
        files.append(bvh_cache_path(gecko_cache_dir(), kept.json()["id"]))
        kept_bytes = sum(path.stat().st_size for path in files)
        assert http.delete(f"/v1/scenes/{kept.json()['id']}").status_code == 204
        freed = sample_value(stored, "gecko_scenes_stored_bytes") - sample_value(
            metric_samples(url), "gecko_scenes_stored_bytes"
        )
        assert freed == kept_bytes > 30 * MiB
        assert not any(path.exists() for path in files)
        again = http.post("/v1/scenes", params={"format": "stl"}, content=second)
        assert again.status_code == 201, again.text
        assert http.delete(f"/v1/scenes/{again.json()['id']}").status_code == 204


def test_a_ply_padded_with_vertices_is_refused_by_its_header(
    upload_server: tuple[str, Path],
) -> None:
    url, _ = upload_server
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 400000\n"
    header += b"property float x\nproperty float y\nproperty float z\n"
    header += b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    body = header + bytes(12 * 400_000) + bytes([3]) + bytes(12)
    response = httpx.post(f"{url}/v1/scenes", params={"format": "ply"}, content=body, timeout=60)
    message = _error(response, 413, "too_large")
    assert "400000 vertices" in message and "limit 300000" in message, message


def _quads_obj(side: int) -> bytes:
    """An OBJ grid of ``side`` x ``side`` quads: its ``f`` lines count one triangle each, and
    it parses into two per quad."""
    lines = [f"v {0.1 * i} {0.1 * j} 0" for i in range(side + 1) for j in range(side + 1)]
    for i in range(side):
        for j in range(side):
            a = i * (side + 1) + j + 1  # OBJ indices start at 1
            lines.append(f"f {a} {a + side + 1} {a + side + 2} {a + 1}")
    return "\n".join(lines).encode()


def test_a_mesh_over_the_limit_its_header_undercounts_is_refused_after_parsing(
    upload_server: tuple[str, Path],
) -> None:
    url, _ = upload_server
    body = _quads_obj(240)  # 57,600 faces on its lines, 115,200 triangles parsed
    response = httpx.post(f"{url}/v1/scenes", params={"format": "obj"}, content=body, timeout=120)
    message = _error(response, 413, "too_large")
    assert "mesh has 115200 triangles; limit 100000" in message, message
    assert "GECKO_MAX_TRIANGLES" in message


def test_an_instanced_dae_is_refused_by_its_scene_graph_and_one_within_the_limit_is_built(
    upload_server: tuple[str, Path],
) -> None:
    url, scenes = upload_server
    refused_body = instanced_dae(20, subdivisions=2, doublings=10)  # 6.5 M triangles in 13 KB
    accepted_body = instanced_dae(3, subdivisions=2, doublings=2)  # 3,840 triangles
    windows: list[tuple[float, float]] = []
    with HealthProbe(url) as probe, httpx.Client(base_url=url, timeout=120) as http:
        time.sleep(5 * HEALTH_EVERY_S)
        refused = _timed_post(http, windows, params={"format": "dae"}, content=refused_body)
        accepted = _timed_post(http, windows, params={"format": "dae"}, content=accepted_body)
        time.sleep(5 * HEALTH_EVERY_S)
    message = _error(refused, 413, "too_large")
    assert "the DAE file holds 6553600 triangles (after instancing)" in message, message
    assert "limit 100000 (GECKO_MAX_TRIANGLES)" in message, message
    assert not [path for path in scenes.iterdir() if path.name.startswith(".tmp-")]
    assert accepted.status_code == 201, accepted.text
    assert accepted.json()["triangle_count"] == 3 * 4 * 320
    assert httpx.delete(f"{url}/v1/scenes/{accepted.json()['id']}", timeout=30).status_code == 204
    _assert_health_answered_during_uploads(probe, windows)


@asynccontextmanager
async def _serve(settings: Settings) -> AsyncIterator[tuple[FastAPI, httpx.AsyncClient]]:
    app = create_app(settings)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as http,
    ):
        yield app, http


def _age(path: Path, seconds: float) -> None:
    then = time.time() - seconds
    os.utime(path, (then, then))


@pytest.mark.anyio
async def test_after_a_restart_the_listing_loads_no_uploaded_scene(tmp_path: Path) -> None:
    settings = _settings(tmp_path)
    async with _serve(settings) as (_, http):
        created = await http.post("/v1/scenes?format=stl&name=slab", content=_box_stl(2.0))
        assert created.status_code == 201, created.text
    scene_id = created.json()["id"]
    bvh = bvh_cache_path(settings.cache_path, scene_id)
    assert bvh.is_file()
    bvh.unlink()  # built again only if something loads the scene
    leftover = settings.scenes_path / ".tmp-upload-crashed.tmp"
    leftover.write_bytes(b"half an upload")
    _age(leftover, HOUR_S)
    young = settings.scenes_path / ".tmp-upload-running.tmp"
    young.write_bytes(b"an upload in progress")
    async with _serve(settings) as (app, http):
        assert not leftover.exists() and young.exists()
        listing = (await http.get("/v1/scenes")).json()
        uploaded = [scene for scene in listing if not scene["builtin"]]
        assert uploaded == [
            {
                "id": scene_id,
                "name": "slab",
                "builtin": False,
                "triangle_count": 12,
                "surface_count": len(created.json()["surfaces"]),
            }
        ]
        detail = await http.get(f"/v1/scenes/{scene_id}")
        assert detail.status_code == 200, detail.text
        assert detail.json() == created.json()
        for fmt in ("stl", "glb"):
            mesh = await http.get(f"/v1/scenes/{scene_id}/mesh", params={"format": fmt})
            assert mesh.status_code == 200, mesh.text
            loaded = trimesh.load(io.BytesIO(mesh.content), file_type=fmt, force="mesh")
            assert len(loaded.faces) == 12
        registry: Registry = app.state.registry
        assert registry.loaded_scene_ids() == []
        assert app.state.lanes.uploads.pids() == {"idle": [], "busy": []}
        assert not bvh.exists()
        assert (await http.get("/health")).json()["scenes"] == len(listing)


@pytest.mark.anyio
async def test_metadata_stored_before_summaries_is_upgraded_once(tmp_path: Path) -> None:
    settings = _settings(tmp_path)
    async with _serve(settings) as (_, http):
        created = (await http.post("/v1/scenes?format=stl&name=old", content=_box_stl(3.0))).json()
    meta = settings.scenes_path / f"{created['id']}.json"
    meta.write_text(json.dumps({"name": "old"}))  # what uploads stored before summaries
    (settings.scenes_path / f"{created['id']}.detail.json").unlink()  # and before details
    async with _serve(settings) as (app, http):
        listing = (await http.get("/v1/scenes")).json()
        assert {"id": created["id"], "name": "old", "triangle_count": 12} == {
            key: value
            for scene in listing
            if scene["id"] == created["id"]
            for key, value in scene.items()
            if key in ("id", "name", "triangle_count")
        }
        detail = await http.get(f"/v1/scenes/{created['id']}")
        assert detail.status_code == 200, detail.text
        assert detail.json() == created
        assert app.state.registry.loaded_scene_ids() == []  # loaded in the uploads lane
    stored = json.loads(meta.read_text())
    assert stored["version"] == 2 and stored["triangle_count"] == 12
    assert stored["surface_count"] == len(created["surfaces"])
    detail_file = settings.scenes_path / f"{created['id']}.detail.json"
    assert json.loads(detail_file.read_text()) == created


def _terrain_stl(triangles: int, seed: int) -> tuple[bytes, str]:
    """A gently rolling grid of its own (no other test uploads it, so no other test shares
    its cached BVH) as a binary STL, and the scene id the service will give it."""
    mesh = grid_mesh(triangles)
    heights = 0.02 * np.random.default_rng(seed).random(len(mesh.vertices))
    mesh = trimesh.Trimesh(mesh.vertices + np.outer(heights, [0.0, 0.0, 1.0]), mesh.faces)
    data = bytes(mesh.export(file_type="stl"))
    return data, content_hash(*validate_arrays(*_parsed(data)))


def _parsed(stl: bytes) -> tuple[np.ndarray, np.ndarray]:
    mesh = load_mesh(stl, "stl")
    return mesh.vertices, mesh.faces


@pytest.mark.anyio
async def test_the_quota_counts_each_scenes_cached_bvh_and_delete_frees_it(
    tmp_path: Path,
) -> None:
    quota = MiB  # the smallest quota allowed
    settings = _settings(tmp_path, scenes_quota_bytes=quota)
    first, first_id = _terrain_stl(1000, seed=151)
    second, second_id = _terrain_stl(1000, seed=152)
    bvhs = [bvh_cache_path(settings.cache_path, scene_id) for scene_id in (first_id, second_id)]
    async with _serve(settings) as (app, http):
        registry: Registry = app.state.registry
        kept = await http.post("/v1/scenes?format=stl&name=first", content=first)
        assert kept.status_code == 201, kept.text
        assert kept.json()["id"] == first_id
        files = [settings.scenes_path / f"{first_id}{suffix}" for suffix in SCENE_SUFFIXES]
        scene_files = sum(path.stat().st_size for path in files)
        bvh_bytes = bvhs[0].stat().st_size
        assert bvh_bytes > 10 * scene_files  # the BVH is most of what a scene stores
        assert registry.uploaded_bytes() == scene_files + bvh_bytes
        stored = sample_value(await _metrics(http), "gecko_scenes_stored_bytes")
        assert stored == scene_files + bvh_bytes
        # The second scene's files alone would fit (about as large as the first's); with
        # its BVH they do not: refused before its BVH is built, nothing of it left.
        assert 2 * scene_files + bvh_bytes < quota < 2 * (scene_files + bvh_bytes)
        refused = await http.post("/v1/scenes?format=stl&name=second", content=second)
        message = _error(refused, 507, "quota_exceeded")
        assert "GECKO_SCENES_QUOTA_BYTES" in message and str(quota) in message, message
        assert not bvhs[1].exists()
        leftovers = sorted(path.name for path in settings.scenes_path.iterdir())
        assert leftovers == sorted([".lock", *(path.name for path in files)])
        assert (await http.delete(f"/v1/scenes/{first_id}")).status_code == 204
        assert not any(path.exists() for path in (*files, bvhs[0]))
        assert registry.uploaded_bytes() == 0
        again = await http.post("/v1/scenes?format=stl&name=second", content=second)
        assert again.status_code == 201, again.text
        assert bvhs[1].is_file()
        assert registry.uploaded_bytes() > bvhs[1].stat().st_size
        assert (await http.delete(f"/v1/scenes/{second_id}")).status_code == 204
        assert not bvhs[1].exists() and registry.uploaded_bytes() == 0


async def _metrics(http: httpx.AsyncClient) -> dict[Any, float]:
    """Every sample of the in-process app's /metrics, as :func:`metric_samples` gives them."""
    response = await http.get("/metrics")
    assert response.status_code == 200
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    }


def test_loaded_uploaded_scenes_are_bounded_and_reload_on_use(tmp_path: Path) -> None:
    registry = Registry(
        cache_dir=tmp_path / "cache", scenes_dir=tmp_path / "scenes", max_loaded_scenes=2
    )
    meshes = [load_mesh(_box_stl(size), "stl") for size in (1.0, 2.0, 3.0)]
    ids = [registry.add_uploaded_scene(mesh, f"box{i}").id for i, mesh in enumerate(meshes)]
    assert registry.loaded_scene_ids() == ids[1:]
    loads = registry.scene_loads
    reloaded = registry.get_scene(ids[0])  # evicted: loaded again from disk
    assert reloaded is not None and reloaded.name == "box0"
    assert registry.scene_loads == loads + 1
    assert registry.loaded_scene_ids() == [ids[2], ids[0]]
    assert registry.get_scene(ids[2]) is not None  # held: no load
    assert registry.scene_loads == loads + 1
    assert registry.loaded_scene_ids() == [ids[0], ids[2]]
    stored_only = registry.add_uploaded_scene(load_mesh(_box_stl(4.0), "stl"), "b", keep=False)
    assert registry.loaded_scene_ids() == [ids[0], ids[2]]
    assert registry.get_scene(stored_only.id) is not None  # on disk all the same


def test_delete_frees_quota_memory_and_the_cached_bvh(tmp_path: Path) -> None:
    cache, scenes = tmp_path / "cache", tmp_path / "scenes"
    registry = Registry(cache_dir=cache, scenes_dir=scenes, max_loaded_scenes=4)
    first = registry.add_uploaded_scene(load_mesh(_box_stl(1.0), "stl"), "a", quota_bytes=MiB)
    used = registry.uploaded_bytes()
    assert 0 < used < MiB
    with pytest.raises(QuotaExceeded) as refused:
        registry.add_uploaded_scene(load_mesh(_box_stl(2.0), "stl"), "b", quota_bytes=used + 10)
    assert refused.value.quota == used + 10 and refused.value.used == used
    assert registry.uploaded_bytes() == used  # nothing of the refused scene stayed
    assert not [path for path in scenes.iterdir() if path.name.startswith(".tmp-")]
    assert registry.delete_uploaded_scene(first.id)
    assert registry.uploaded_bytes() == 0
    assert registry.loaded_scene_ids() == []
    assert not bvh_cache_path(cache, first.content_hash).exists()
    second = registry.add_uploaded_scene(load_mesh(_box_stl(2.0), "stl"), "b", quota_bytes=MiB)
    assert registry.scene_summary(second.id) is not None


@pytest.mark.anyio
async def test_deleting_a_scene_removes_the_roadmaps_built_on_it(tmp_path: Path) -> None:
    settings = _settings(tmp_path)
    terrain, scene_id = _terrain_stl(1000, seed=153)
    async with _serve(settings) as (_, http):
        uploaded = await http.post("/v1/scenes?format=stl&name=ground", content=terrain)
        assert uploaded.status_code == 201, uploaded.text
        request = {"character": "humanoid", "scene": scene_id, "nodes": 20, "seed": 3}
        built = await http.post("/v1/roadmaps", json=request)
        assert built.status_code in (200, 202), built.text
        rid = built.json()["id"]
        for _ in range(600):
            status = (await http.get(f"/v1/roadmaps/{rid}")).json()
            if status["status"] != "queued" and status["status"] != "running":
                break
            await asyncio.sleep(0.2)
        assert status["status"] == "done", status
        files = [settings.roadmaps_path / f"{rid}{suffix}" for suffix in (".npz", ".json")]
        assert all(path.is_file() for path in files)
        assert (await http.delete(f"/v1/scenes/{scene_id}")).status_code == 204
        assert not any(path.exists() for path in files)
        gone = await http.get(f"/v1/roadmaps/{rid}")
        assert gone.status_code == 404, gone.text
