"""Planning work run inside worker processes: request JSON in, response JSON out.

Each function takes the validated request as a JSON string (cheap to pickle), resolves the
character and scene in the worker's registry, calls the planner and converts the answer.
Errors the client can fix are raised as :class:`~service.errors.ApiError` (picklable).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from planner.contact.context import ContactParams
from planner.contact.planner import Endpoint, PlanOptions, plan_contact_motion
from planner.contact.sequence import SequenceParams
from planner.poses import normalize_quaternion, pose_matrix, quaternion_to_matrix
from planner.scene import Scene
from service import convert, schemas
from service.errors import ApiError, not_found
from service.registry import CharacterEntry
from service.workers import worker_registry


def character_entry(character_id: str) -> CharacterEntry:
    """The served character, or a 404 naming the ``character`` field."""
    entry = worker_registry().get_character(character_id)
    if entry is None:
        raise not_found("character", character_id, "character")
    return entry


def scene_by_id(scene_id: str) -> Scene:
    """The scene, or a 404 naming the ``scene`` field."""
    scene = worker_registry().get_scene(scene_id)
    if scene is None:
        raise not_found("scene", scene_id, "scene")
    return scene


class Stopwatch:
    """Wall-clock seconds per named stage, for the ``timings`` of a response."""

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - start


def invalid(message: str, field: str) -> ApiError:
    """A 422 the client can fix."""
    return ApiError(422, "invalid_request", message, field)


def _endpoint(endpoint: schemas.EndpointIn) -> Endpoint:
    if endpoint.stand_at is not None:
        return Endpoint(stand_at=np.asarray(endpoint.stand_at, dtype=np.float64))
    assert endpoint.position is not None
    orientation = endpoint.orientation or (0.0, 0.0, 0.0, 1.0)
    rotation = quaternion_to_matrix(normalize_quaternion(np.asarray(orientation)))
    return Endpoint(root_pose=pose_matrix(np.asarray(endpoint.position), rotation))


def run_plan(request_json: str, seed: int) -> dict[str, Any]:
    """``POST /v1/plans`` in a worker: the response as a JSON-ready dict."""
    request = schemas.PlanRequest.model_validate_json(request_json)
    entry = character_entry(request.character)
    scene = scene_by_id(request.scene)
    options = PlanOptions(
        rate=request.options.rate,
        sequence=SequenceParams(
            lookahead=request.options.lookahead, max_states=request.options.max_states
        ),
        contact=ContactParams(margin=request.options.margin),
    )
    result = plan_contact_motion(
        scene,
        entry.character,
        entry.data,
        _endpoint(request.start),
        _endpoint(request.goal),
        rng=np.random.default_rng(seed),
        time_budget_s=request.time_budget_s,
        options=options,
    )
    plan = result.value
    character = entry.character
    motion = plan.motion if plan is not None else None
    report: dict[str, Any] = dict(motion.report) if motion is not None else {}
    # Wall-clock figures belong to ``timings``; the report must replay bit for bit.
    report["stats"] = {k: v for k, v in result.stats.items() if "second" not in k}
    response = schemas.PlanResponse(
        status=result.status.value,
        seed=seed,
        message=result.message,
        phases=[convert.phase_out(p) for p in motion.phases] if motion else [],
        com=[convert.com_segment_out(s) for s in motion.com] if motion else [],
        keyframes=[convert.keyframe_out(character, k) for k in motion.keyframes] if motion else [],
        states=[convert.state_out(character, s) for s in plan.states] if plan else [],
        report=report,
        timings=dict(plan.timings) if plan else {},
    )
    return response.model_dump(mode="json")
