"""Scenes: list, details with affordance surfaces, mesh download, upload."""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import Annotated, Any, Literal

import trimesh
from anyio import to_thread
from fastapi import APIRouter, Query, Request
from fastapi.responses import Response
from starlette.status import HTTP_204_NO_CONTENT

from planner.ballistic.planner import RoadmapStore
from planner.export import SceneMesh
from planner.scene import Scene
from service import convert
from service.deps import RegistryDep, SettingsDep
from service.errors import ApiError, not_found
from service.export import scene_glb_bytes, scene_mesh
from service.interactive import RETRY_HEADER
from service.lanes import Lane
from service.registry import Registry
from service.schemas import ErrorBody, SceneDetail, SceneSummary
from service.uploads import (
    ingest_upload,
    quota_exceeded,
    scene_detail_json,
    scene_summary_json,
)

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
async def list_scenes(
    request: Request, registry: RegistryDep, settings: SettingsDep
) -> list[SceneSummary]:
    """Built-in scenes first, then uploaded ones, from their stored metadata (no uploaded
    scene is loaded; one stored before summaries were is loaded once, in the uploads lane,
    and its summary stored). A stored scene that cannot be read is left out and logged: one
    broken file must not fail the listing for everyone."""
    # One trip to a thread for the built-in scenes, one for the uploaded ones: each trip
    # waits for a free thread and the GIL, which under load costs ms (one per scene did).
    out = await to_thread.run_sync(_builtin_summaries, registry)
    stored = await to_thread.run_sync(_stored_summaries, registry)
    lane: Lane = request.app.state.lanes.uploads
    for scene_id, summary in stored:
        if summary is not None:
            out.append(summary)
            continue
        try:  # metadata older than summaries: upgraded once, off the event loop's process
            upgraded = await lane.run(
                scene_summary_json, scene_id, run_for_s=settings.upload_timeout_s
            )
        except Exception as exc:
            log.error("scene %s cannot be loaded: %s: %s", scene_id, type(exc).__name__, exc)
            continue
        if upgraded is not None:  # None: deleted since the ids were read
            out.append(SceneSummary.model_validate(upgraded))
    return out


def _builtin_summaries(registry: Registry) -> list[SceneSummary]:
    """The built-in scenes' summaries, in their order (each loaded on first use)."""
    out = []
    for scene_id in registry.builtin_scene_ids():
        scene = registry.get_scene(scene_id)
        if scene is not None:
            out.append(convert.scene_summary(scene, builtin=True))
    return out


def _stored_summaries(registry: Registry) -> list[tuple[str, SceneSummary | None]]:
    """Each uploaded scene's id and stored summary (None where the metadata has none)."""
    out: list[tuple[str, SceneSummary | None]] = []
    for scene_id in registry.uploaded_scene_ids():
        summary = registry.scene_summary(scene_id)
        out.append(
            (scene_id, None if summary is None else convert.stored_summary(scene_id, summary))
        )
    return out


@router.get("/{scene_id}", responses=_404, response_model=SceneDetail)
async def get_scene(
    scene_id: str, request: Request, registry: RegistryDep, settings: SettingsDep
) -> Response:
    """Bounds, triangle count and affordance surfaces (polygons, normals, kinds, areas).

    An uploaded scene's details were stored at upload: they are answered as stored, without
    loading the scene (one stored before is built once in the uploads lane)."""
    if registry.is_builtin(scene_id):
        scene = await _scene(registry, scene_id)
        detail = convert.scene_detail(scene, builtin=True)
        return Response(detail.model_dump_json(), media_type="application/json")
    stored = await to_thread.run_sync(registry.stored_detail, scene_id)
    if stored is not None:
        return Response(stored, media_type="application/json")
    lane: Lane = request.app.state.lanes.uploads
    built = await lane.run(scene_detail_json, scene_id, run_for_s=settings.upload_timeout_s)
    if built is None:
        raise not_found("scene", scene_id, "scene_id")
    return Response(built, media_type="application/json")


@router.delete(
    "/{scene_id}",
    status_code=HTTP_204_NO_CONTENT,
    response_class=Response,
    responses={
        **_404,
        403: {"model": ErrorBody, "description": "built-in scenes cannot be deleted"},
    },
)
async def delete_scene(scene_id: str, registry: RegistryDep, settings: SettingsDep) -> Response:
    """Delete an uploaded scene: its mesh, metadata and collision cache, and the jump
    roadmaps built on it. Requests naming it then get 404; stored results that used it stay
    readable (their GLB without the scene)."""
    if registry.is_builtin(scene_id):
        message = f"scene '{scene_id}' is built in; only uploaded scenes can be deleted"
        raise ApiError(403, "builtin_scene", message, "scene_id")
    if not await to_thread.run_sync(registry.delete_uploaded_scene, scene_id):
        raise not_found("scene", scene_id, "scene_id")
    store = RoadmapStore(settings.roadmaps_path)
    await to_thread.run_sync(store.delete_of_scene, scene_id)
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
    (y up; Gecko's (x, y, z) is glTF's (x, z, -y)). An uploaded scene is read from its mesh
    file, not loaded."""
    mesh = await to_thread.run_sync(scene_mesh, registry, scene_id)
    if mesh is None:
        raise not_found("scene", scene_id, "scene_id")
    if format == "glb":
        data = await to_thread.run_sync(scene_glb_bytes, mesh)
        return Response(data, media_type="model/gltf-binary")
    data = await to_thread.run_sync(_stl_bytes, mesh)
    return Response(data, media_type="model/stl")


def _stl_bytes(mesh: SceneMesh) -> bytes:
    stl = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(file_type="stl")
    assert isinstance(stl, bytes)
    return stl


async def _receive_body(request: Request, limit: int, directory: Path) -> Path:
    """Stream the request body into a temporary file in ``directory`` (removed again on any
    error); a 413 past ``limit`` bytes (declared or received), a 422 when it is empty."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        message = f"mesh body is {declared} bytes; limit {limit} (GECKO_MAX_UPLOAD_BYTES)"
        raise ApiError(413, "too_large", message, "body")
    directory.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(dir=directory, prefix=".tmp-upload-", suffix=".tmp")
    path = Path(name)
    try:
        size = 0
        with os.fdopen(fd, "wb") as handle:
            async for chunk in request.stream():
                size += len(chunk)
                if size > limit:
                    message = (
                        f"mesh body exceeds the limit of {limit} bytes (GECKO_MAX_UPLOAD_BYTES)"
                    )
                    raise ApiError(413, "too_large", message, "body")
                handle.write(chunk)  # a page-cache write of one chunk (~64 KB): microseconds
        if size == 0:
            raise ApiError(422, "invalid_mesh", "the request body is empty", "body")
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    return path


@router.post(
    "",
    status_code=201,
    response_model=SceneDetail,
    responses={
        413: {
            "model": ErrorBody,
            "description": "body, triangle or vertex count (after instancing) over the limit",
        },
        422: {"model": ErrorBody, "description": "corrupt, empty or non-finite mesh"},
        507: {"model": ErrorBody, "description": "the uploaded scenes' quota is full"},
        504: {"model": ErrorBody, "description": "parsing and building took too long"},
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
) -> Response:
    """Upload a mesh as the raw request body; its id is a content hash of the mesh.

    The body goes to a temporary file; a process of the uploads lane reads its triangle count
    (after instancing, for glTF) before parsing, then parses it and builds the scene, one
    upload at a time per service worker. A few wait in line (a 503 with Retry-After past
    ``GECKO_UPLOAD_QUEUE``, before the body is read)."""
    lane: Lane = request.app.state.lanes.uploads
    ticket = lane.admit()
    try:
        used = await to_thread.run_sync(registry.uploaded_bytes)
        if used >= settings.scenes_quota_bytes:
            raise quota_exceeded(
                f"uploaded scenes take {used} bytes, the quota of {settings.scenes_quota_bytes}"
            )
        body = await _receive_body(request, settings.max_upload_bytes, settings.scenes_path)
        try:
            detail = await lane.run(
                ingest_upload,
                str(body),
                format,
                name,
                y_up,
                ticket=ticket,
                run_for_s=settings.upload_timeout_s,
            )
        finally:
            body.unlink(missing_ok=True)
    finally:
        ticket.release()
    return Response(detail, status_code=201, media_type="application/json")
