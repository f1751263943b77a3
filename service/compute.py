"""Planning work run inside worker processes: request JSON in, response JSON out.

Each function takes the validated request as a JSON string (cheap to pickle), resolves the
character and scene in the worker's registry, calls the planner and converts the answer.
Errors the client can fix are raised as :class:`~service.errors.ApiError` (picklable).
"""

from __future__ import annotations

import gzip
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from planner.ballistic.planner import JumpEnd, JumpParams, RoadmapStore, plan_jumps
from planner.ballistic.roadmap import RoadmapParams
from planner.contact.context import ContactParams, character_obstacles, make_context
from planner.contact.generation import state_from_configuration
from planner.contact.one_step import StepAction, twister_step
from planner.contact.planner import Endpoint, PlanOptions, plan_contact_motion
from planner.contact.sequence import SequenceParams
from planner.contact.standing import standing_state
from planner.kinematics import borrowed_data
from planner.motion.sequence import Timing
from planner.poses import normalize_quaternion, pose_matrix, quaternion_to_matrix
from planner.scene import Scene
from planner.termination import Deadline
from service import convert, schemas
from service.errors import ApiError, not_found
from service.jobs import SqliteJobStore
from service.quota import QuotaExceeded
from service.registry import CharacterEntry, Registry
from service.results import Kind, ResultStore, stored_result
from service.roadmap_storage import admission, quota_exceeded
from service.workers import worker_registry, worker_settings
from trajectory import TransitionCost

MIN_BUDGET_S = 0.01  # s: a request that waited out its budget still gets a (quick) answer
PROGRESS_STEP = 0.02  # fraction of a roadmap build between two progress writes


def timing_of(options: schemas.TimingOptionsIn) -> Timing:
    """The planner's COM timing from a request's options (bounds checked by the schema); a
    Twister step's transition point is its new state's COM, so only plans choose a cost."""
    cost = TransitionCost("tired")
    overlap = True
    if isinstance(options, schemas.PlanOptionsIn):
        cost = TransitionCost(options.transition_cost, strength=options.cost_strength)
        overlap = options.overlap_swings
    return Timing(
        speed=options.speed,
        cost=cost,
        overlap=overlap,
        attractors=tuple(
            (a.transition, np.asarray(a.point, dtype=np.float64)) for a in options.attractors
        ),
    )


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


def budget_left(deadline: float | None, budget_s: float) -> float:
    """Seconds of planning left: until ``deadline`` (a :func:`time.monotonic` time, shared by
    the processes of a machine: the request's arrival plus its budget), else ``budget_s``."""
    if deadline is None:
        return budget_s
    return max(MIN_BUDGET_S, deadline - time.monotonic())


def run_plan(request_json: str, seed: int, deadline: float | None = None) -> dict[str, Any]:
    """``POST /v1/plans`` in a worker: the response as a JSON-ready dict. The request's
    ``time_budget_s`` alone sets the plan's work budget (so the answer replays whatever the
    queue and the load); ``deadline`` (monotonic s; None: the request's budget from now) is
    only the wall-clock cap, and the report says ``clock_cap_hit`` when it bound."""
    request = schemas.PlanRequest.model_validate_json(request_json)
    entry = character_entry(request.character)
    scene = scene_by_id(request.scene)
    limb_names = sorted(limb.name for limb in entry.character.limbs)
    for name in request.options.limbs:
        if name not in limb_names:
            raise invalid(f"unknown limb '{name}'; expected some of {limb_names}", "options.limbs")
    options = PlanOptions(
        rate=request.options.rate,
        limbs=tuple(request.options.limbs),
        sequence=SequenceParams(
            lookahead=request.options.lookahead, max_states=request.options.max_states
        ),
        contact=ContactParams(margin=request.options.margin),
        max_pitch=request.options.max_pitch,
        timing=timing_of(request.options),
    )
    result = plan_contact_motion(
        scene,
        entry.character,
        entry.data,
        _endpoint(request.start),
        _endpoint(request.goal),
        rng=np.random.default_rng(seed),
        time_budget_s=request.time_budget_s,
        cap_s=budget_left(deadline, request.time_budget_s),
        options=options,
    )
    plan = result.value
    character = entry.character
    motion = plan.motion if plan is not None else None
    report: dict[str, Any] = dict(motion.report) if motion is not None else {}
    # Wall-clock figures belong to ``timings``; the report must replay bit for bit.
    report["stats"] = {k: v for k, v in result.stats.items() if "second" not in k}
    # the clock, not the work budget, stopped the plan: a replay may differ
    report["clock_cap_hit"] = bool(result.stats.get("clock_cap_hit", False))
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


def run_twister_step(request_json: str, seed: int, deadline: float | None = None) -> dict[str, Any]:
    """``POST /v1/twister/step`` in a worker: one contact change, as a JSON-ready dict.
    ``auto`` tries the limbs in the seed's order; ``deadline`` (monotonic s; None: the
    budget from now) is only a wall-clock cap on it (``report.clock_cap_hit``)."""
    request = schemas.TwisterStepRequest.model_validate_json(request_json)
    entry = character_entry(request.character)
    with borrowed_data(entry.character.model) as pin_data:  # the step's context's
        return _twister_step(request, entry, seed, deadline, pin_data)


def _twister_step(
    request: schemas.TwisterStepRequest,
    entry: CharacterEntry,
    seed: int,
    deadline: float | None,
    pin_data: Any,
) -> dict[str, Any]:
    """:func:`run_twister_step` with the request read and its context's pin.Data lent."""
    cap = Deadline(budget_left(deadline, request.time_budget_s))
    scene = scene_by_id(request.scene)
    character, data = entry.character, entry.data
    rng = np.random.default_rng(seed)
    clock = Stopwatch()
    with clock.stage("state"):
        obstacles = []
        for index, other in enumerate(request.others):
            other_entry = worker_registry().get_character(other.character)
            if other_entry is None:
                raise not_found("character", other.character, f"others.{index}.character")
            q_other = convert.q_from_configuration(
                other_entry.character, other.configuration, f"others.{index}.configuration"
            )
            obstacles.extend(character_obstacles(other_entry.character, q_other))
        params = ContactParams(
            allowed_surfaces=None if request.surfaces is None else tuple(request.surfaces)
        )
        surface_count = len(scene.surfaces)
        for index, surface in enumerate(request.surfaces or ()):
            if surface >= surface_count:
                raise invalid(f"scene has {surface_count} surfaces", f"surfaces.{index}")
        ctx = make_context(scene, character, data, params, obstacles=obstacles, pin_data=pin_data)
        if request.state is not None:
            q, contacts = convert.state_request(character, request.state, "state")
            made = state_from_configuration(ctx, q, contacts)
            if not made.ok:
                raise invalid(f"the state is not valid here: {made.message}", "state")
            state = made.state
        else:
            assert request.stand_at is not None
            standing = standing_state(
                scene, character, data, np.asarray(request.stand_at), rng=rng, yaw=request.yaw
            )
            if not standing.status or standing.value is None:
                raise invalid(f"no standing state there: {standing.message}", "stand_at")
            contacts = {c.limb: c.surface for c in standing.value.contacts}
            made = state_from_configuration(ctx, standing.value.q, contacts)
            state = made.state if made.ok else standing.value
    limb_names = {limb.name for limb in character.limbs}
    if request.action.limb is not None and request.action.limb not in limb_names:
        raise invalid(
            f"unknown limb '{request.action.limb}'; expected one of {sorted(limb_names)}",
            "action.limb",
        )
    action = StepAction(
        kind=request.action.kind,
        limb=request.action.limb,
        surface=request.action.surface,
        target=None if request.action.target is None else np.asarray(request.action.target),
    )
    with clock.stage("step"):
        result = twister_step(
            ctx,
            state,
            action,
            rng=rng,
            cap=cap,
            rate=request.rate,
            timing=timing_of(request.options),
        )
    failure = None
    if result.failure is not None:
        failure = schemas.FailureOut(
            reason=result.failure.reason.value,
            message=result.failure.message,
            limb=result.failure.limb,
        )
    report = {k: v for k, v in result.report.items() if "second" not in k}
    report["action"] = result.action
    report["limb"] = result.limb
    response = schemas.TwisterStepResponse(
        status="SOLVED" if result.ok else "INFEASIBLE",
        seed=seed,
        state=convert.state_out(character, result.state),
        phases=[convert.phase_out(p) for p in result.phases],
        com=[convert.com_segment_out(s) for s in result.com],
        keyframes=[convert.keyframe_out(character, k) for k in result.keyframes],
        failure=failure,
        report=report,
        timings={**clock.timings, **{f"step.{k}": v for k, v in result.timings.items()}},
    )
    return response.model_dump(mode="json")


# -- jumps --------------------------------------------------------------------------------


def jump_params(request: schemas.RoadmapRequest | schemas.JumpRequest) -> JumpParams:
    """Jump-planner parameters from a request's friction, speed bounds and roadmap size."""
    return JumpParams(
        roadmap=RoadmapParams(
            v0max=request.vmax_takeoff, vimpmax=request.vmax_landing, max_gap=0.1, lazy=True
        ),
        n_nodes=request.nodes,
        mu=request.mu,
        rate=getattr(request, "rate", 30.0),
    )


def roadmap_id(request: schemas.RoadmapRequest, registry: Registry) -> str:
    """The content id of the roadmap a request builds (same inputs, same id)."""
    entry = registry.get_character(request.character)
    if entry is None:
        raise not_found("character", request.character, "character")
    scene = registry.get_scene(request.scene)
    if scene is None:
        raise not_found("scene", request.scene, "scene")
    params = jump_params(request)
    return RoadmapStore.roadmap_id(
        scene, entry.character, entry.data, params, request.nodes, request.seed
    )


def build_roadmap_job(request_json: str, job_id: str, jobs_db: str) -> dict[str, Any]:
    """Build and store a roadmap in a worker, writing its progress to the job store at
    ``jobs_db``; returns the job's result (the roadmap's id and size)."""
    request = schemas.RoadmapRequest.model_validate_json(request_json)
    store = SqliteJobStore(Path(jobs_db))
    last = [-1.0]

    def progress(fraction: float) -> None:
        if fraction - last[0] >= PROGRESS_STEP or fraction >= 1.0:
            last[0] = fraction
            store.progress(job_id, fraction)

    entry = character_entry(request.character)
    scene = scene_by_id(request.scene)
    settings = worker_settings()
    roadmaps = RoadmapStore(settings.roadmaps_path)
    try:
        rid = roadmaps.build(
            scene,
            entry.character,
            entry.data,
            jump_params(request),
            request.nodes,
            request.seed,
            progress=progress,
            admit=admission(settings.roadmaps_path, settings.roadmaps_quota_bytes),
        )
    except QuotaExceeded as exc:  # others' builds filled the quota meanwhile
        raise quota_exceeded(exc) from exc
    info = roadmaps.info(rid) or {}
    return {
        "kind": "roadmap",
        "id": rid,
        "url": f"/v1/roadmaps/{rid}",
        "nodes": int(info.get("nodes", 0)),
        "edges": int(info.get("edges", 0)),
    }


def _jump_endpoint(endpoint: schemas.EndpointIn) -> np.ndarray:
    if endpoint.stand_at is not None:
        return np.asarray(endpoint.stand_at, dtype=np.float64)
    return _endpoint(endpoint).root_pose  # type: ignore[return-value]


def _jump_end(end: JumpEnd) -> schemas.JumpEndOut:
    return schemas.JumpEndOut(
        position=convert.vec3(end.position),
        velocity=convert.vec3(end.velocity),
        contacts=[
            schemas.JumpContactOut(
                limb=c.limb,
                point=convert.vec3(c.point),
                normal=convert.vec3(c.normal),
                mu=float(c.mu),
            )
            for c in end.contacts
        ],
    )


def run_jumps(request_json: str, seed: int, deadline: float | None = None) -> dict[str, Any]:
    """``POST /v1/jumps`` in a worker: the response as a JSON-ready dict; planning (and a
    roadmap built on the way) stops at ``deadline`` (monotonic s; None: the budget from
    now)."""
    request = schemas.JumpRequest.model_validate_json(request_json)
    entry = character_entry(request.character)
    scene = scene_by_id(request.scene)
    params = jump_params(request)
    roadmap = None
    if request.roadmap is not None:
        store = RoadmapStore(worker_settings().roadmaps_path)
        if not request.roadmap.isalnum() or not store.exists(request.roadmap):
            raise not_found("roadmap", request.roadmap, "roadmap")
        try:
            roadmap = store.load(request.roadmap)
            params = store.params(request.roadmap)
        except FileNotFoundError as exc:  # deleted since it was found
            raise not_found("roadmap", request.roadmap, "roadmap") from exc
    try:
        result = plan_jumps(
            scene,
            entry.character,
            entry.data,
            _jump_endpoint(request.start),
            _jump_endpoint(request.goal),
            rng=np.random.default_rng(seed),
            roadmap=roadmap,
            params=params,
            until=Deadline(budget_left(deadline, request.time_budget_s)),
        )
    except ValueError as exc:  # a roadmap built for another scene or character
        raise invalid(str(exc), "roadmap") from exc
    plan = result.value
    character = entry.character
    response = schemas.JumpResponse(
        status=result.status.value,
        seed=seed,
        message=result.message,
        roadmap=request.roadmap,
        jumps=[
            schemas.JumpOut(
                takeoff=_jump_end(j.takeoff),
                landing=_jump_end(j.landing),
                apex=convert.vec3(j.apex),
                duration=float(j.duration),
                t_start=float(j.t_start),
                push_start=float(j.push_start),
                takeoff_time=float(j.contact_break),
                landing_time=float(j.contact_create),
                rest_time=float(j.rest),
            )
            for j in (plan.jumps if plan else ())
        ],
        keyframes=[convert.keyframe_out(character, k) for k in (plan.keyframes if plan else ())],
        phases=[convert.phase_out(p) for p in (plan.phases if plan else ())],
        com=[convert.com_segment_out(s) for s in (plan.com if plan else ())],
        report=(
            {
                **plan.report.as_dict(),
                "nodes_refused": int(result.stats.get("nodes_refused", 0)),
                "jumps_refused": int(result.stats.get("jumps_refused", 0)),
            }
            if plan and plan.report
            else {}
        ),
        timings=dict(plan.timings) if plan else {},
    )
    return response.model_dump(mode="json")


# -- answers made ready in the worker ------------------------------------------------------


@dataclass(frozen=True, slots=True)
class ReadyAnswer:
    """A plan, Twister step or jump answer computed, stored and serialised in the worker, so
    that the service process (its event loop, ``/health``) only sends bytes: ``body`` the
    JSON answer (gzip-compressed when ``gzipped``), ``id`` its content id, ``status`` and
    ``timings`` for the request's log line and metrics."""

    body: bytes
    gzipped: bool
    id: str
    status: str
    timings: dict[str, float]


_RUNNERS: dict[str, Callable[[str, int, float | None], dict[str, Any]]] = {
    "plan": run_plan,
    "step": run_twister_step,
    "jump": run_jumps,
}
_MODELS: dict[str, tuple[type[BaseModel], type[BaseModel]]] = {
    "plan": (schemas.PlanRequest, schemas.PlanResponse),
    "step": (schemas.TwisterStepRequest, schemas.TwisterStepResponse),
    "jump": (schemas.JumpRequest, schemas.JumpResponse),
}
_RESULTS: list[ResultStore] = []  # the worker's result store, made on first use


def _result_store() -> ResultStore:
    if not _RESULTS:
        settings = worker_settings()
        _RESULTS.append(
            ResultStore(
                settings.results_path,
                max_count=settings.results_max_count,
                max_bytes=settings.results_max_bytes,
            )
        )
    return _RESULTS[0]


def run_ready(
    kind: Kind,
    request_json: str,
    seed: int,
    deadline: float | None = None,
    *,
    gzip_from: int | None = None,
    gzip_level: int = 6,
) -> ReadyAnswer:
    """``kind``'s work (``run_plan``, ``run_twister_step`` or ``run_jumps``) in a worker, its
    answer given its content id and stored (the store is the service's, shared by every
    process), then validated against the response model and serialised as the route would;
    gzip-compressed when ``gzip_from`` is given (the client accepts gzip) and the body has
    at least that many bytes."""
    answer = _RUNNERS[kind](request_json, seed, deadline)
    request_model, response_model = _MODELS[kind]
    request = request_model.model_validate_json(request_json).model_dump(mode="json")
    stored, summary = stored_result(kind, request, seed, answer)
    body = response_model.model_validate(stored.response).model_dump_json().encode()
    _result_store().put(stored, summary, response_json=body)
    gzipped = gzip_from is not None and len(body) >= gzip_from
    if gzipped:
        body = gzip.compress(body, compresslevel=gzip_level, mtime=0)
    timings = stored.response.get("timings") or {}
    return ReadyAnswer(body, gzipped, stored.id, str(stored.response.get("status")), timings)
