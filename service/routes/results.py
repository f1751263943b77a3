"""Stored results: listing, and the shared GET of one plan, Twister step or jump as JSON or
GLB (the routes of each kind call :func:`stored_answer`)."""

from __future__ import annotations

import functools
import secrets
from typing import Annotated, Any, Literal

from anyio import to_thread
from fastapi import APIRouter, Query, Request
from fastapi.responses import Response
from pydantic import BaseModel, TypeAdapter, ValidationError

from service import compute
from service.context import annotate
from service.deps import RegistryDep
from service.errors import ApiError, not_found
from service.export import result_glb
from service.interactive import run_interactive
from service.results import Kind, ResultStore, StoredResult, stored_result
from service.schemas import MAX_SEED, ErrorBody, ResultSummary

router = APIRouter(prefix="/v1", tags=["results"])
Format = Literal["json", "glb"]
KIND_NAMES: dict[Kind, str] = {"plan": "plan", "step": "Twister step", "jump": "jump"}
MAX_LIST = 1000
GLB_MEDIA = "model/gltf-binary"
RESULT_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {"content": {GLB_MEDIA: {}}, "description": "the result as JSON, or as GLB"},
    400: {"model": ErrorBody, "description": "the suffix and ?format= disagree"},
    404: {"model": ErrorBody, "description": "unknown (or evicted) result id"},
    409: {"model": ErrorBody, "description": "GLB of a result without keyframes"},
    410: {"model": ErrorBody, "description": "stored by a Gecko version this one cannot read"},
    422: {"model": ErrorBody, "description": "invalid format"},
}
FormatQuery = Annotated[
    Format | None, Query(description="json or glb (default: the path's suffix, else json)")
]
SceneQuery = Annotated[bool, Query(description="GLB: include the scene mesh (node 'scene')")]
OverlaysQuery = Annotated[
    bool,
    Query(description="GLB: include the COM curve or jump arcs ('com') and contact points"),
]


def draw_seed() -> int:
    """A seed for a request without one, in [0, 2^53 - 1] (exact as a JavaScript number)."""
    return secrets.randbelow(MAX_SEED + 1)


def store_of(request: Request) -> ResultStore:
    """The app's result store."""
    store: ResultStore = request.app.state.results
    return store


async def remember(
    request: Request, kind: Kind, body: BaseModel, seed: int, answer: dict[str, Any]
) -> dict[str, Any]:
    """Give an answer its content id and store it; returns the answer with ``id`` set (and
    its id, seed, status and timings on the request's log line)."""
    answer = await remember_answer(request.app.state, kind, body, seed, answer)
    annotate(
        kind=kind,
        result=answer["id"],
        seed=seed,
        answer_status=str(answer.get("status")),
        timings=answer.get("timings"),
    )
    return answer


async def run_answer(
    request: Request,
    kind: Kind,
    body: BaseModel,
    seed: int,
    *,
    budget_s: float,
    answer_within_s: float,
) -> Response:
    """A plan, Twister step or jump run in the interactive lane and answered as the worker
    made it ready (:func:`service.compute.run_ready`: given its id, stored, serialised and,
    for a client that accepts it, gzipped), so that the event loop only passes bytes on."""
    settings = request.app.state.settings
    accepts_gzip = "gzip" in request.headers.get("accept-encoding", "").lower()
    work = functools.partial(
        compute.run_ready,
        kind,
        gzip_from=settings.gzip_minimum_bytes if accepts_gzip else None,
        gzip_level=settings.gzip_level,
    )
    ready: compute.ReadyAnswer = await run_interactive(
        request,
        work,
        body.model_dump_json(),
        seed,
        budget_s=budget_s,
        answer_within_s=answer_within_s,
        short=kind == "step",
    )
    annotate(
        kind=kind, result=ready.id, seed=seed, answer_status=ready.status, timings=ready.timings
    )
    request.app.state.metrics.observe_answer(kind, ready.status)
    headers = {"content-encoding": "gzip", "vary": "Accept-Encoding"} if ready.gzipped else {}
    return Response(ready.body, media_type="application/json", headers=headers)


async def remember_answer(
    state: Any, kind: Kind, body: BaseModel, seed: int, answer: dict[str, Any]
) -> dict[str, Any]:
    """:func:`remember` outside a request (``state`` is the app's state): for jobs."""
    stored, summary = stored_result(kind, body.model_dump(mode="json"), seed, answer)
    answer = stored.response
    results: ResultStore = state.results
    await to_thread.run_sync(results.put, stored, summary)
    state.metrics.observe_answer(kind, str(answer.get("status")))
    return answer


def _split(reference: str, format: Format | None) -> tuple[str, Format]:
    rid, _, suffix = reference.partition(".")
    if suffix and suffix not in ("json", "glb"):
        raise ApiError(
            400, "invalid_request", f"unknown suffix '.{suffix}'; use .json or .glb", "format"
        )
    if suffix and format is not None and suffix != format:
        raise ApiError(
            400,
            "invalid_request",
            f"the path asks for .{suffix} but ?format={format}",
            "format",
        )
    chosen: Format = format or ("glb" if suffix == "glb" else "json")
    return rid, chosen


def _unreadable(stored: StoredResult) -> ApiError:
    """410 for a stored result whose shape this code no longer reads (an older version's)."""
    message = f"{KIND_NAMES[stored.kind]} {stored.id} was stored by a Gecko version this one "
    message += "cannot read; send the request again to get it from this version"
    return ApiError(410, "stored_by_other_version", message, "id")


def _stored_json(store: ResultStore, rid: str, kind: Kind, model: type[BaseModel]) -> bytes | None:
    """A stored answer as its route's JSON: read, validated as ``model`` (410 for a shape
    this code no longer reads) and serialised by alias, as FastAPI serialises a route's
    ``response_model``; None for an unknown id. Run in a thread: a plan of a few MB takes
    tens of ms to validate and serialise, which the event loop (and /health) must not wait."""
    stored = store.get(rid, kind)
    if stored is None:
        return None
    try:
        answer = model.model_validate(stored.response)
    except ValidationError as exc:
        raise _unreadable(stored) from exc
    return _adapter(model).dump_json(answer, by_alias=True)


@functools.cache
def _adapter(model: type[BaseModel]) -> TypeAdapter[Any]:
    """The serialiser of ``model`` (one per answer model, built once)."""
    return TypeAdapter(model)


async def stored_answer(
    request: Request,
    registry: RegistryDep,
    kind: Kind,
    reference: str,
    format: Format | None,
    scene: bool,
    overlays: bool,
    model: type[BaseModel],
) -> Response:
    """A stored result: its JSON answer validated as ``model``, or its GLB.

    404 for an unknown id, 410 when the stored answer no longer fits this code's shapes.
    Reading, validating and serialising run in a thread, never on the event loop.
    """
    rid, chosen = _split(reference, format)
    if chosen == "json":
        body = await to_thread.run_sync(_stored_json, store_of(request), rid, kind, model)
        if body is None:
            raise not_found(KIND_NAMES[kind], rid, "id")
        return Response(body, media_type="application/json")
    stored = await to_thread.run_sync(store_of(request).get, rid, kind)
    if stored is None:
        raise not_found(KIND_NAMES[kind], rid, "id")

    def export() -> bytes:
        try:
            model.model_validate(stored.response)
            return result_glb(registry, stored, with_scene=scene, with_overlays=overlays)
        except (ValidationError, KeyError, TypeError, IndexError) as exc:  # older code's
            raise _unreadable(stored) from exc

    data = await to_thread.run_sync(export)
    filename = f"{kind}-{rid}.glb"
    return Response(
        data,
        media_type=GLB_MEDIA,
        headers={"content-disposition": f'inline; filename="{filename}"'},
    )


@router.get("/results")
async def list_results(
    request: Request,
    kind: Annotated[Kind | None, Query(description="only this kind")] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_LIST, description="at most this many")] = 100,
) -> list[ResultSummary]:
    """Stored results, most recently used first (id, kind, character, scene, status, ...)."""
    metas = await to_thread.run_sync(store_of(request).summaries, limit, kind)
    return [ResultSummary.model_validate(meta) for meta in metas]
