"""Stored files under real use: leftovers of interrupted writes, and deleting uploaded scenes."""

from __future__ import annotations

import os
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import httpx
import pytest
import trimesh
from asgi_lifespan import LifespanManager

from planner.scene.collision import bvh_cache_path
from service.app import create_app
from service.files import is_temporary, remove_leftovers
from service.settings import Settings

pytestmark = pytest.mark.anyio
HOUR_S = 3600.0


def _box_stl(size: float = 1.0) -> bytes:
    return bytes(trimesh.creation.box(extents=(size, size, 0.2)).export(file_type="stl"))


def _age(path: Path, seconds: float) -> None:
    then = time.time() - seconds
    os.utime(path, (then, then))


@asynccontextmanager
async def _serve(settings: Settings) -> AsyncIterator[httpx.AsyncClient]:
    app = create_app(settings)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as http,
    ):
        yield http


def test_temporary_names() -> None:
    assert is_temporary(".tmp-a1b2.json")
    assert is_temporary("abc.npz.tmp")
    assert is_temporary(".bvh-xyz")
    assert not is_temporary("0123abcd.json")
    assert not is_temporary("0123abcd.meta.json")


def test_remove_leftovers_spares_young_files_and_others(tmp_path: Path) -> None:
    old, young, kept = tmp_path / ".tmp-old.json", tmp_path / "x.npz.tmp", tmp_path / "a.json"
    for path in (old, young, kept):
        path.write_text("{")
    _age(old, HOUR_S)
    _age(kept, HOUR_S)
    assert remove_leftovers(tmp_path, older_than_s=60) == [old]
    assert not old.exists() and young.exists() and kept.exists()
    assert remove_leftovers(tmp_path / "absent", older_than_s=0) == []


async def test_leftovers_are_removed_at_start_and_never_listed(settings: Settings) -> None:
    scenes, results, roadmaps = settings.scenes_path, settings.results_path, settings.roadmaps_path
    for directory in (scenes, results, roadmaps):
        directory.mkdir(parents=True, exist_ok=True)
    stale = [scenes / ".tmp-stale.json", results / ".tmp-stale.json", roadmaps / "r.npz.tmp"]
    for path in stale:
        path.write_text("{half a fi")
        _age(path, HOUR_S)
    # Young ones may be another service worker's write in progress: kept, but never listed.
    young = [scenes / ".tmp-young.json", scenes / ".tmp-young2.npz", results / "x.meta.json.tmp"]
    for path in young:
        path.write_text("{half a fi")
    async with _serve(settings) as http:
        assert not any(path.exists() for path in stale)
        assert all(path.exists() for path in young)
        listing = await http.get("/v1/scenes")
        assert listing.status_code == 200, listing.text
        assert all(scene["builtin"] for scene in listing.json())
        assert (await http.get("/v1/results")).json() == []
        health = (await http.get("/health")).json()
        assert health["scenes"] == len(listing.json())


async def test_leftovers_of_cache_writes_are_removed_at_start(
    settings: Settings, tmp_path: Path
) -> None:
    """A process killed while writing offline data or a BVH cache leaves ``*.npz.tmp`` or
    ``.bvh-*`` in the cache directory: removed at the next start, the real files kept."""
    cache = tmp_path / "cache"
    cache.mkdir()
    for real in settings.cache_path.iterdir():  # the built data, linked rather than rebuilt
        if real.is_file() and not is_temporary(real.name):
            (cache / real.name).symlink_to(real)
    kept = sorted(path.name for path in cache.iterdir())
    stale = [cache / "humanoid-0123.npz.tmp", cache / ".bvh-k2x9"]
    for path in stale:
        path.write_bytes(b"half a file")
        _age(path, HOUR_S)
    async with _serve(settings.model_copy(update={"cache_dir": cache})) as http:
        assert (await http.get("/health")).status_code == 200
        assert not any(path.exists() for path in stale)
    assert kept and all((cache / name).exists() for name in kept)


async def test_a_broken_stored_scene_does_not_fail_the_listing(settings: Settings) -> None:
    async with _serve(settings) as http:
        good = (await http.post("/v1/scenes?format=stl", content=_box_stl())).json()["id"]
    broken = "f" * 32
    (settings.scenes_path / f"{broken}.json").write_text('{"name": "broken"}')
    (settings.scenes_path / f"{broken}.npz").write_bytes(b"not a zip file")
    async with _serve(settings) as http:
        listing = await http.get("/v1/scenes")
        assert listing.status_code == 200, listing.text
        ids = {scene["id"] for scene in listing.json()}
        assert good in ids and broken not in ids


async def test_delete_an_uploaded_scene(client: httpx.AsyncClient, settings: Settings) -> None:
    created = await client.post("/v1/scenes?format=stl&name=gone", content=_box_stl(1.5))
    assert created.status_code == 201
    scene_id = created.json()["id"]
    files = [settings.scenes_path / f"{scene_id}.{ext}" for ext in ("json", "npz", "detail.json")]
    bvh = bvh_cache_path(settings.cache_path, scene_id)
    assert all(path.exists() for path in files) and bvh.exists()

    response = await client.delete(f"/v1/scenes/{scene_id}")
    assert response.status_code == 204, response.text
    assert not response.content
    assert not any(path.exists() for path in files) and not bvh.exists()
    assert (await client.get(f"/v1/scenes/{scene_id}")).status_code == 404
    assert scene_id not in {s["id"] for s in (await client.get("/v1/scenes")).json()}
    plan = {
        "character": "humanoid",
        "scene": scene_id,
        "start": {"stand_at": [0, 0, 0.1]},
        "goal": {"stand_at": [0.3, 0, 0.1]},
    }
    refused = await client.post("/v1/plans", json=plan)
    assert refused.status_code == 404
    assert refused.json()["error"]["field"] == "scene"

    again = await client.delete(f"/v1/scenes/{scene_id}")
    assert again.status_code == 404
    assert again.json()["error"]["field"] == "scene_id"
    # The same mesh can be uploaded again and gets the same id back.
    created = await client.post("/v1/scenes?format=stl&name=back", content=_box_stl(1.5))
    assert created.json()["id"] == scene_id


@pytest.mark.parametrize("scene_id", ["flat", "nosuchscene", "a.b-c", "x" * 300])
async def test_delete_refuses_builtin_and_unknown_scenes(
    client: httpx.AsyncClient, scene_id: str
) -> None:
    response = await client.delete(f"/v1/scenes/{scene_id}")
    error = response.json()["error"]
    assert error["field"] == "scene_id"
    if scene_id == "flat":
        assert response.status_code == 403
        assert error["code"] == "builtin_scene"
        assert "built in" in error["message"]
        assert (await client.get("/v1/scenes/flat")).status_code == 200
    else:
        assert response.status_code == 404
