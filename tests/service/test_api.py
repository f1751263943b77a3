"""HTTP API of the foundation: health, characters, scenes, uploads and error envelopes."""

from __future__ import annotations

import io
import math
from pathlib import Path

import httpx
import numpy as np
import pytest
import trimesh

from service.app import create_app
from service.settings import Settings

pytestmark = pytest.mark.anyio


def _error(response: httpx.Response) -> dict[str, object]:
    body = response.json()
    assert set(body) == {"error"}
    assert set(body["error"]) == {"code", "message", "field"}
    assert body["error"]["message"]
    return dict(body["error"])


async def test_health(client: httpx.AsyncClient) -> None:
    response = await client.get("/health")
    assert response.status_code == 200
    body = response.json()
    assert body["status"] == "ok"
    assert body["characters"] == 3


async def test_characters_list_and_detail(client: httpx.AsyncClient) -> None:
    listing = (await client.get("/v1/characters")).json()
    assert {c["id"] for c in listing} == {"humanoid", "quadruped", "hexapod"}
    detail = (await client.get("/v1/characters/humanoid")).json()
    assert detail["mass"] > 30
    assert len(detail["joints"]) >= 28
    reference = detail["reference_configuration"]
    assert set(reference["joints"]) == set(detail["joints"])
    assert math.isclose(np.linalg.norm(reference["root"]["orientation"]), 1.0, rel_tol=1e-9)
    limbs = {limb["name"]: limb for limb in detail["limbs"]}
    assert len(limbs) == 6
    assert {name for name, limb in limbs.items() if limb["on_request"]} == {
        "left_seat",
        "right_seat",
    }
    assert all(
        limb["contact"] == ("point" if limb["on_request"] else "patch") for limb in limbs.values()
    )
    quadruped = (await client.get("/v1/characters/quadruped")).json()
    assert all(limb["contact"] == "point" for limb in quadruped["limbs"])
    assert len(quadruped["joints"]) == 12
    hexapod = (await client.get("/v1/characters/hexapod")).json()
    assert len(hexapod["limbs"]) == 6


async def test_character_urdf(client: httpx.AsyncClient) -> None:
    response = await client.get("/v1/characters/quadruped/urdf")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("application/xml")
    assert "<robot" in response.text


async def test_unknown_ids_give_404_envelopes(client: httpx.AsyncClient) -> None:
    for path, field in [
        ("/v1/characters/nobody", "character_id"),
        ("/v1/characters/nobody/urdf", "character_id"),
        ("/v1/scenes/nowhere", "scene_id"),
        ("/v1/scenes/nowhere/mesh", "scene_id"),
    ]:
        response = await client.get(path)
        assert response.status_code == 404, path
        error = _error(response)
        assert error["code"] == "not_found"
        assert error["field"] == field


async def test_builtin_scenes(client: httpx.AsyncClient) -> None:
    listing = (await client.get("/v1/scenes")).json()
    ids = [s["id"] for s in listing]
    for expected in ["flat", "stairs", "chair", "climbing_wall", "twister", "rubble", "gaps"]:
        assert expected in ids
    stairs = (await client.get("/v1/scenes/stairs")).json()
    assert stairs["triangle_count"] > 0
    low, high = np.array(stairs["bounds"])
    assert np.all(high > low)
    kinds = {s["kind"] for s in stairs["surfaces"]}
    assert "support" in kinds
    for surface in stairs["surfaces"]:
        assert math.isclose(np.linalg.norm(surface["normal"]), 1.0, rel_tol=1e-6)
        assert surface["area"] > 0
        assert surface["polygons"] and len(surface["polygons"][0]) >= 3


@pytest.mark.parametrize("fmt", ["stl", "glb"])
async def test_scene_mesh_download(client: httpx.AsyncClient, fmt: str) -> None:
    response = await client.get(f"/v1/scenes/chair/mesh?format={fmt}")
    assert response.status_code == 200
    mesh = trimesh.load(io.BytesIO(response.content), file_type=fmt, force="mesh")
    detail = (await client.get("/v1/scenes/chair")).json()
    assert len(mesh.faces) == detail["triangle_count"]


def _box_stl(size: float = 1.0) -> bytes:
    box = trimesh.creation.box(extents=[size, size, 0.2])
    return bytes(box.export(file_type="stl"))


async def test_upload_same_mesh_twice_gives_one_id(
    client: httpx.AsyncClient, settings: Settings
) -> None:
    first = await client.post("/v1/scenes?format=stl&name=block", content=_box_stl())
    assert first.status_code == 201, first.text
    second = await client.post("/v1/scenes?format=stl&name=block", content=_box_stl())
    assert second.status_code == 201
    assert first.json()["id"] == second.json()["id"]
    body = first.json()
    assert any(s["kind"] == "support" for s in body["surfaces"])
    listing = (await client.get("/v1/scenes")).json()
    assert sum(s["id"] == body["id"] for s in listing) == 1
    assert len(list(Path(settings.scenes_path).glob("*.npz"))) == 1


async def test_upload_survives_restart(client: httpx.AsyncClient, settings: Settings) -> None:
    scene_id = (await client.post("/v1/scenes?format=stl", content=_box_stl(2.0))).json()["id"]
    from asgi_lifespan import LifespanManager

    app = create_app(settings)
    async with (
        LifespanManager(app),
        httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://g") as again,
    ):
        response = await again.get(f"/v1/scenes/{scene_id}")
        assert response.status_code == 200
        assert response.json()["triangle_count"] == 12


def _obj_with_nan() -> bytes:
    return b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n"


@pytest.mark.parametrize(
    ("query", "body", "status"),
    [
        ("format=stl", b"this is not a mesh at all", 422),
        ("format=stl", b"", 422),
        ("format=obj", b"# nothing here\n", 422),
        ("format=obj", _obj_with_nan(), 422),
        ("format=xyz", b"solid x\nendsolid x\n", 422),
        ("", b"solid x\nendsolid x\n", 422),
    ],
)
async def test_bad_uploads_get_clear_errors_and_leave_nothing(
    client: httpx.AsyncClient, settings: Settings, query: str, body: bytes, status: int
) -> None:
    response = await client.post(f"/v1/scenes?{query}", content=body)
    assert response.status_code == status, response.text
    error = _error(response)
    assert error["field"] in {"body", "format"}
    assert not any(settings.scenes_path.iterdir()) if settings.scenes_path.exists() else True


async def test_oversized_body_is_413(client: httpx.AsyncClient, settings: Settings) -> None:
    big = b"\0" * (settings.max_upload_bytes + 1)
    response = await client.post("/v1/scenes?format=stl", content=big)
    assert response.status_code == 413
    assert _error(response)["code"] == "too_large"
    assert not list(settings.scenes_path.glob("*"))


async def test_too_many_triangles_is_413(client: httpx.AsyncClient, settings: Settings) -> None:
    grid = trimesh.creation.icosphere(subdivisions=5)  # 20,480 triangles > 10,000 limit
    body = bytes(grid.export(file_type="stl"))
    assert len(body) < settings.max_upload_bytes
    response = await client.post("/v1/scenes?format=stl", content=body)
    assert response.status_code == 413
    assert "triangles" in _error(response)["message"]


async def test_openapi_is_served(client: httpx.AsyncClient) -> None:
    spec = (await client.get("/openapi.json")).json()
    for path in ["/health", "/v1/characters/{character_id}", "/v1/scenes"]:
        assert path in spec["paths"]
    assert (await client.get("/docs")).status_code == 200
