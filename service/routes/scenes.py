"""Scenes: list, details with affordance surfaces, mesh download, upload."""

from __future__ import annotations

import logging
from typing import Annotated, Any, Literal

import trimesh
from anyio import to_thread
from fastapi import APIRouter, Query, Request
from fastapi.responses import Response
from starlette.status import HTTP_204_NO_CONTENT

from planner.scene import Scene, SceneError, load_mesh
from service import convert
from service.deps import RegistryDep, SettingsDep
from service.errors import ApiError, not_found
from service.export import scene_glb_bytes
from service.interactive import RETRY_HEADER
from service.lanes import Gate
from service.registry import Registry
from service.schemas import ErrorBody, SceneDetail, SceneSummary
from service.settings import Settings

router = APIRouter(prefix="/v1/scenes", tags=["scenes"])
_404: dict[int | str, dict[str, Any]] = {404: {"model": ErrorBody, "description": "unknown scene"}}
UploadFormat = Literal["stl", "obj", "ply", "glb", "gltf", "dae"]
MAX_NAME_LENGTH = 200
log = logging.getLogger("gecko.scenes")


async def _scene(registry: Registry, scene_id: str) -> Scene:
    scene = await to_thread.run_sync(registry.get_scene, scene_id)
    if scene is None:
        raise not_found("scene", scene_id, "scene_id")
    return scene


@router.get("")
async def list_scenes(registry: RegistryDep) -> list[SceneSummary]:
    """Built-in scenes first, then uploaded ones (a stored scene that cannot be read is left
    out and logged: one broken file must not fail the listing for everyone)."""
    out = []
    for scene_id in registry.scene_ids():
        try:
            scene = await to_thread.run_sync(registry.get_scene, scene_id)
        except Exception as exc:
            log.error("scene %s cannot be loaded: %s: %s", scene_id, type(exc).__name__, exc)
            continue
        if scene is not None:  # None: deleted since the ids were read
            out.append(convert.scene_summary(scene, registry.is_builtin(scene_id)))
    return out


@router.get("/{scene_id}", responses=_404)
async def get_scene(scene_id: str, registry: RegistryDep) -> SceneDetail:
    """Bounds, triangle count and affordance surfaces (polygons, normals, kinds, areas)."""
    scene = await _scene(registry, scene_id)
    return convert.scene_detail(scene, registry.is_builtin(scene_id))


@router.delete(
    "/{scene_id}",
    status_code=HTTP_204_NO_CONTENT,
    response_class=Response,
    responses={
        **_404,
        403: {"model": ErrorBody, "description": "built-in scenes cannot be deleted"},
    },
)
async def delete_scene(scene_id: str, registry: RegistryDep) -> Response:
    """Delete an uploaded scene: its mesh, metadata and collision cache. Requests naming it
    then get 404; stored results that used it stay readable (their GLB without the scene)."""
    if registry.is_builtin(scene_id):
        message = f"scene '{scene_id}' is built in; only uploaded scenes can be deleted"
        raise ApiError(403, "builtin_scene", message, "scene_id")
    if not await to_thread.run_sync(registry.delete_uploaded_scene, scene_id):
        raise not_found("scene", scene_id, "scene_id")
    return Response(status_code=HTTP_204_NO_CONTENT)


@router.get(
    "/{scene_id}/mesh",
    responses={
        **_404,
        200: {"content": {"model/stl": {}, "model/gltf-binary": {}}},
    },
)
async def get_scene_mesh(
    scene_id: str,
    registry: RegistryDep,
    format: Literal["stl", "glb"] = Query("stl", description="binary STL or GLB"),
) -> Response:
    """The scene's triangle mesh in metres: STL in Gecko's world (z up), GLB in glTF's
    (y up; Gecko's (x, y, z) is glTF's (x, z, -y))."""
    scene = await _scene(registry, scene_id)
    if format == "glb":
        data = await to_thread.run_sync(scene_glb_bytes, scene)
        return Response(data, media_type="model/gltf-binary")
    mesh = trimesh.Trimesh(scene.vertices, scene.faces, process=False)
    stl = mesh.export(file_type="stl")
    assert isinstance(stl, bytes)
    return Response(stl, media_type="model/stl")


async def _read_body(request: Request, limit: int) -> bytes:
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        message = f"mesh body is {declared} bytes; limit {limit}"
        raise ApiError(413, "too_large", message, "body")
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise ApiError(
                413, "too_large", f"mesh body exceeds the limit of {limit} bytes", "body"
            )
        chunks.append(chunk)
    return b"".join(chunks)


@router.post(
    "",
    status_code=201,
    responses={
        413: {"model": ErrorBody, "description": "body or triangle count over the limit"},
        422: {"model": ErrorBody, "description": "corrupt, empty or non-finite mesh"},
        503: {
            "model": ErrorBody,
            "description": "too many uploads waiting (queue_full), with Retry-After",
            "headers": RETRY_HEADER,
        },
    },
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/octet-stream": {"schema": {"type": "string", "format": "binary"}}
            },
        }
    },
)
async def upload_scene(
    request: Request,
    registry: RegistryDep,
    settings: SettingsDep,
    format: Annotated[UploadFormat, Query(description="mesh file format")],
    name: Annotated[str, Query(max_length=MAX_NAME_LENGTH, description="scene label")] = "",
    y_up: Annotated[bool, Query(description="the file is y-up (converted to z-up)")] = False,
) -> SceneDetail:
    """Upload a mesh as the raw request body; its id is a content hash of the mesh.

    Uploads are parsed one at a time per service worker; a few wait in line (a 503 with
    Retry-After past ``GECKO_UPLOAD_QUEUE``, before the body is read)."""
    gate: Gate = request.app.state.lanes.uploads
    ticket = gate.admit()
    try:
        return await _upload(request, registry, settings, gate, format, name, y_up)
    finally:
        ticket.release()


async def _upload(
    request: Request,
    registry: Registry,
    settings: Settings,
    gate: Gate,
    format: UploadFormat,
    name: str,
    y_up: bool,
) -> SceneDetail:
    body = await _read_body(request, settings.max_upload_bytes)
    if not body:
        raise ApiError(422, "invalid_mesh", "the request body is empty", "body")

    def build() -> Scene:
        try:
            mesh = load_mesh(body, format, y_up=y_up)
        except SceneError as exc:
            raise ApiError(422, "invalid_mesh", str(exc), "body") from exc
        if len(mesh.faces) > settings.max_triangles:
            raise ApiError(
                413,
                "too_large",
                f"mesh has {len(mesh.faces)} triangles; limit {settings.max_triangles}",
                "body",
            )
        return registry.add_uploaded_scene(mesh, name)

    await gate.take_slot()
    try:
        scene = await to_thread.run_sync(build)
    finally:
        gate.give_slot()
    return convert.scene_detail(scene, builtin=False)
