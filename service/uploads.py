"""Scene uploads, run in the uploads lane's worker process: counts, parse, quota, build, store.

The service streams an upload's body to a temporary file in the scenes directory and hands its
path to :func:`ingest_upload` in a worker process, so neither parsing nor building surfaces and
the BVH ever holds the event loop (or /health). The work is ordered cheapest refusal first:

1. the file's triangle and vertex counts, read from its header or its glTF or COLLADA scene
   graph (after instancing): over ``GECKO_MAX_TRIANGLES`` is a 413 before any array is built;
2. the parse and validation (``load_mesh``: 422 for corrupt, empty or non-finite meshes) and
   the triangle limit again on what was parsed (formats without a header count, polygons);
3. the mesh file written and measured, with the BVH the scene will cache foreseen from its
   counts, against ``GECKO_SCENES_QUOTA_BYTES`` (507), then surfaces and BVH built, then the
   quota checked again with the real sizes (BVH included) under a lock and the files renamed
   into place. The quota counts everything an uploaded scene stores, its BVH in the cache
   directory too, and a DELETE removes all of it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from planner.scene import Scene, SceneError, content_hash, load_mesh
from planner.scene.counts import count_mesh
from planner.scene.io import validate_arrays
from service import convert
from service.errors import INSUFFICIENT_STORAGE, ApiError
from service.quota import QuotaExceeded
from service.settings import Settings
from service.workers import worker_registry, worker_settings


def too_large(message: str) -> ApiError:
    """A 413 about the upload's body."""
    return ApiError(413, "too_large", message, "body")


def quota_exceeded(message: str) -> ApiError:
    """A 507 naming the uploaded scenes' quota."""
    return ApiError(
        INSUFFICIENT_STORAGE,
        "quota_exceeded",
        f"{message} (GECKO_SCENES_QUOTA_BYTES); delete uploaded scenes to make room",
        "body",
    )


def check_counts(data: bytes, fmt: str, settings: Settings) -> None:
    """Refuse (413) a mesh file whose header or scene graph promises more triangles or
    vertices than the settings allow; 422 when that header is unreadable."""
    try:
        counts = count_mesh(data, fmt)
    except SceneError as exc:
        raise ApiError(422, "invalid_mesh", exc.message, "body") from exc
    if counts is None:
        return
    if counts.triangles > settings.max_triangles:
        raise too_large(
            f"the {fmt.upper()} file holds {counts.triangles} triangles{_instanced(fmt)}; "
            f"limit {settings.max_triangles} (GECKO_MAX_TRIANGLES)"
        )
    if counts.vertices > settings.max_vertices:
        raise too_large(
            f"the {fmt.upper()} file holds {counts.vertices} vertices{_instanced(fmt)}; "
            f"limit {settings.max_vertices} (3 x GECKO_MAX_TRIANGLES)"
        )


def _instanced(fmt: str) -> str:
    return " (after instancing)" if fmt in ("glb", "gltf", "dae") else ""


def ingest_upload(body_path: str, fmt: str, name: str, y_up: bool) -> str:
    """Check, parse, build and store the mesh file at ``body_path`` (the caller removes it);
    the new scene's details as JSON text (answered as is: the service process neither
    validates nor serialises it again). Errors are :class:`ApiError` (413, 422,
    507). Runs in a worker process (it uses that process's registry and settings)."""
    settings = worker_settings()
    registry = worker_registry()
    data = Path(body_path).read_bytes()
    check_counts(data, fmt, settings)
    try:
        mesh = load_mesh(data, fmt, y_up=y_up)
    except SceneError as exc:
        raise ApiError(422, "invalid_mesh", str(exc), "body") from exc
    del data
    if len(mesh.faces) > settings.max_triangles:
        raise too_large(
            f"mesh has {len(mesh.faces)} triangles; limit {settings.max_triangles} "
            "(GECKO_MAX_TRIANGLES)"
        )
    scene_id = content_hash(*validate_arrays(mesh.vertices, mesh.faces))
    stored = registry.stored_detail(scene_id)
    if stored is not None:  # uploaded before: nothing to build
        return stored
    described: list[str] = []

    def describe(scene: Scene) -> str:
        described.append(_detail_text(scene))
        return described[-1]

    try:
        scene = registry.add_uploaded_scene(
            mesh, name, quota_bytes=settings.scenes_quota_bytes, describe=describe, keep=False
        )
    except QuotaExceeded as exc:
        raise quota_exceeded(str(exc)) from exc
    return described[-1] if described else _detail_text(scene)  # else: stored meanwhile


def _detail_text(scene: Scene) -> str:
    return convert.scene_detail(scene, builtin=False).model_dump_json()


def scene_detail_json(scene_id: str) -> str | None:
    """An uploaded scene's details (JSON text), built and stored for a scene stored without
    them; None if unknown. Runs in a worker process."""
    registry = worker_registry()
    stored = registry.stored_detail(scene_id)
    if stored is not None:
        return stored
    scene = registry.get_scene(scene_id)
    if scene is None or registry.is_builtin(scene_id):
        return None
    text = _detail_text(scene)
    registry.store_detail(scene_id, text)
    return text


def scene_summary_json(scene_id: str) -> dict[str, Any] | None:
    """An uploaded scene's stored summary, upgrading metadata stored before summaries were
    (which loads the scene once, in a worker); None if unknown."""
    registry = worker_registry()
    summary = registry.scene_summary(scene_id) or registry.upgrade_metadata(scene_id)
    return None if summary is None else convert.stored_summary(scene_id, summary).model_dump()
