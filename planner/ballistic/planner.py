"""Ballistic jump planning on a real scene: the domain API behind ``/v1/roadmaps`` and
``/v1/jumps``.

``plan_jumps`` turns a start and a goal (root poses or ``stand_at`` points) into a sequence of
parabolic jumps with whole-body keyframes: reduced model (``nodes``), roadmap (given, loaded
from a ``RoadmapStore`` or built within the termination budget), query, contact
configurations at the nodes (``stance``), then the whole-body motion (takeoff push, flight,
landing per jump) from the one motion builder (``planner.motion.jump``). The roadmap plans
the root's parabolas; the answer's jumps are the COM's: the same parabola translated by the
COM's offset from the root in the takeoff stance, so velocities, flight times and cone
checks are unchanged. ``RoadmapStore`` builds, persists (atomically) and reloads roadmaps
by id.
"""

from __future__ import annotations

import bisect
import hashlib
import json
import os
import tempfile
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.ballistic.cones import centroidal_cones
from planner.ballistic.nodes import ReducedModel, SceneSampler
from planner.ballistic.roadmap import (
    GOAL,
    START,
    JumpPath,
    Roadmap,
    RoadmapNodes,
    RoadmapParams,
    build_roadmap,
)
from planner.ballistic.stance import NodeStancer, Stance
from planner.ballistic.steering import jump_at
from planner.character import Character
from planner.contact.body import contact_points
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import com_position
from planner.motion import ComSegment, Keyframe, Phase, tuning
from planner.motion.builder import BuiltMotion, MotionReport, build_motion
from planner.motion.checker import KeyframeChecker
from planner.motion.jump import JumpLeg, JumpTiming, jump_spec
from planner.motion.spec import MotionSpec
from planner.offline import OfflineData
from planner.result import PlanResult, PlanStatus
from planner.scene import Scene
from planner.termination import Deadline, Termination, any_of, never

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _ro(value: object) -> FloatArray:
    out = np.array(value, dtype=np.float64)
    out.flags.writeable = False
    return out


# --------------------------------------------------------------------------------------------
# Parameters and results


@dataclass(frozen=True, slots=True)
class JumpParams:
    """Jump planning parameters.

    roadmap : steering, connection and collision parameters (its ``scene_key`` is filled in
    by the planner). n_nodes : roadmap size when one is built. min_limbs : contacts a node needs
    (None: half the limbs, rounded up). lean : Lean surfaces count as contact surfaces. mu :
    friction of every contact (None: the limbs' own). rate : keyframes per second.
    phase_fraction, limb_collisions : read by nothing since the motion builder animates
    jumps (kept so that stored roadmaps' parameters still load). stand_radius : m, how
    far from a ``stand_at`` point its surface point may be. roadmap_seed : seed of roadmaps
    built through a ``RoadmapStore`` by ``plan_jumps``. build_share : when
    ``plan_jumps`` builds a roadmap under a ``Deadline``, the build gets this share of the
    time left (the query and keyframes the rest).
    """

    roadmap: RoadmapParams = field(
        default_factory=lambda: RoadmapParams(v0max=6.0, vimpmax=8.0, max_gap=0.1, lazy=True)
    )
    n_nodes: int = 300
    min_limbs: int | None = None
    lean: bool = False
    mu: float | None = None
    rate: float = 30.0
    phase_fraction: float = 1.0 / 3.0
    stand_radius: float = 0.5
    roadmap_seed: int = 0
    limb_collisions: bool = True
    build_share: float = 0.5

    def __post_init__(self) -> None:
        if self.n_nodes < 1 or not self.rate > 0 or not 0.0 < self.phase_fraction <= 0.5:
            raise ValueError("n_nodes >= 1, rate > 0 and phase_fraction in (0, 0.5] required")
        if self.min_limbs is not None and self.min_limbs < 1:
            raise ValueError("min_limbs must be >= 1")
        if self.mu is not None and not self.mu > 0:
            raise ValueError("mu must be positive")
        if not 0.0 < self.build_share <= 1.0:
            raise ValueError("build_share must be in (0, 1]")

    def to_json(self) -> str:
        """Canonical JSON of every field (``roadmap`` as its own JSON)."""
        data = {
            "roadmap": self.roadmap.to_json(),
            "n_nodes": self.n_nodes,
            "min_limbs": self.min_limbs,
            "lean": self.lean,
            "mu": self.mu,
            "rate": self.rate,
            "phase_fraction": self.phase_fraction,
            "stand_radius": self.stand_radius,
            "roadmap_seed": self.roadmap_seed,
            "limb_collisions": self.limb_collisions,
            "build_share": self.build_share,
        }
        return json.dumps(data, sort_keys=True)

    @staticmethod
    def from_json(text: str) -> JumpParams:
        """Inverse of ``to_json``."""
        data = json.loads(text)
        data["roadmap"] = RoadmapParams.from_json(data["roadmap"])
        return JumpParams(**data)

    def limbs_needed(self, character: Character) -> int:
        """The number of contacts a node needs for ``character``."""
        if self.min_limbs is not None:
            return min(self.min_limbs, len(character.default_limbs))
        return (len(character.default_limbs) + 1) // 2

    def model_key(self, scene: Scene, character: Character, data: OfflineData) -> str:
        """Identifies the reduced model: scene content, character data, sampler settings."""
        return json.dumps(
            {
                "scene": scene.content_hash,
                "character": character.id,
                "data": data.cache_key,
                "min_limbs": self.limbs_needed(character),
                "lean": self.lean,
                "mu": self.mu,
            },
            sort_keys=True,
        )

    def roadmap_params(
        self, scene: Scene, character: Character, data: OfflineData
    ) -> RoadmapParams:
        """``roadmap`` with its ``scene_key`` set for this scene and character."""
        key = hashlib.sha256(self.model_key(scene, character, data).encode()).hexdigest()[:32]
        return replace(self.roadmap, scene_key=key)


@dataclass(frozen=True, slots=True)
class JumpContact:
    """One contact: limb name, point (3,) m and unit surface normal (3,) (world), mu."""

    limb: str
    point: FloatArray
    normal: FloatArray
    mu: float


@dataclass(frozen=True, slots=True)
class JumpEnd:
    """Takeoff or landing: the COM position (3,) m and velocity (3,) m/s when the contacts
    break (takeoff) or are made (landing), the contacts held there, and the node's centroidal
    cone (axis (3,), mu) the velocity was checked against (V0 inside it at takeoff, -Vimp at
    landing)."""

    position: FloatArray
    velocity: FloatArray
    contacts: tuple[JumpContact, ...]
    cone_axis: FloatArray
    cone_mu: float


@dataclass(frozen=True, slots=True)
class JumpInfo:
    """One jump: takeoff, landing, the COM's apex (3,) m, flight duration (s), and its
    absolute times (s from the motion's start): start (the crouch begins), push (the COM
    leaves rest), contact break (takeoff), apex, contact creation (touchdown), rest (the
    landing has stopped the COM). push_acceleration / landing_acceleration : (3,) m/s^2, the
    COM's constant acceleration in the push and the landing; push_in_cone / landing_in_cone
    : the contact force they need lies in the node's centroidal cone; push_in_reach /
    landing_in_reach : the COM's travel in them stays within the legs' reach."""

    takeoff: JumpEnd
    landing: JumpEnd
    apex: FloatArray
    duration: float
    t_start: float
    push_start: float
    contact_break: float
    apex_time: float
    contact_create: float
    rest: float
    push_acceleration: FloatArray
    landing_acceleration: FloatArray
    push_in_cone: bool
    landing_in_cone: bool
    push_in_reach: bool
    landing_in_reach: bool


@dataclass(frozen=True, slots=True)
class JumpPlan:
    """The answer of ``plan_jumps``.

    jumps : the jumps in order. keyframes : whole-body keyframes, absolute times, evenly
    spaced. phases : contact phases (flights hold none). com : the COM curve's Bezier
    segments (the flights are the jumps' parabolas). report : the motion builder's report.
    timings : seconds per stage (model, roadmap, endpoints, query, keyframes, total). path :
    the roadmap path (node ids, START = -1, GOAL = -2). roadmap : the roadmap used.
    """

    jumps: tuple[JumpInfo, ...]
    keyframes: tuple[Keyframe, ...]
    timings: dict[str, float]
    path: JumpPath
    roadmap: Roadmap
    phases: tuple[Phase, ...] = ()
    com: tuple[ComSegment, ...] = ()
    report: MotionReport | None = None


# --------------------------------------------------------------------------------------------
# End points


def _as_node(
    model: ReducedModel,
    spec: FloatArray,
    min_limbs: int,
    radius: float,
    rng: np.random.Generator,
    toward: FloatArray | None,
) -> RoadmapNodes | None:
    """A node for a root pose (4, 4) or a ``stand_at`` point (3,); None if none is valid."""
    value = np.asarray(spec, dtype=np.float64)
    if value.shape == (4, 4):
        nodes, _ = model.nodes(value[None], min_limbs)
        return nodes if len(nodes) else None
    if value.shape != (3,) or not np.all(np.isfinite(value)):
        raise ValueError("start and goal must be (4, 4) root poses or (3,) stand_at points")
    # Surface points near the request, nearest first.
    found: list[tuple[float, FloatArray, FloatArray]] = []
    for surface in model.surfaces:
        point = surface.closest_point(value[None])[0]
        gap = float(np.linalg.norm(point - value))
        if gap <= radius:
            found.append((gap, point, surface.normal))
    found.sort(key=lambda item: item[0])
    stance = model.reference_points[model.stance].mean(axis=0)
    yaws = rng.uniform(-np.pi, np.pi, size=15)
    if toward is not None and np.hypot(*(toward - value)[:2]) > 1e-6:
        yaws = np.concatenate([[np.arctan2(*(toward - value)[1::-1])], yaws])
    for _, point, normal in found:
        for lift in (0.0, 0.03, 0.08):
            for begin in range(0, len(yaws), 4):  # small batches: the first usually succeeds
                batch = yaws[begin : begin + 4]
                m = len(batch)
                poses = _place(
                    model, np.tile(point, (m, 1)), np.tile(normal, (m, 1)), batch, stance
                )
                poses[:, :3, 3] += lift * normal
                nodes, _ = model.nodes(poses, min_limbs)
                if len(nodes):
                    return nodes.take(slice(0, 1))
    return None


def _place(
    model: ReducedModel, points: FloatArray, normals: FloatArray, yaw: FloatArray, ref: FloatArray
) -> FloatArray:
    """Like ``ReducedModel.place`` with a fixed root-frame reference point ``ref`` (3,)."""
    poses = model.place(points, normals, yaw, np.zeros(len(points), np.int64))
    offset = model.reference_points[0] - ref
    poses[:, :3, 3] += np.einsum("nij,j->ni", poses[:, :3, :3], offset)
    return poses


# --------------------------------------------------------------------------------------------
# Planning


def _node_row(nodes: RoadmapNodes, i: int) -> dict[str, Any]:
    return {key: value[i] for key, value in nodes.contacts.items()}


def plan_jumps(
    scene: Scene,
    character: Character,
    data: OfflineData,
    start: FloatArray,
    goal: FloatArray,
    *,
    rng: np.random.Generator,
    roadmap: Roadmap | None = None,
    params: JumpParams | None = None,
    until: Termination = never,
    store_dir: str | Path | None = None,
) -> PlanResult[JumpPlan]:
    """Jumps from ``start`` to ``goal`` (each a (4, 4) root pose or a (3,) ``stand_at`` point).

    Without ``roadmap``: with ``store_dir`` the store's roadmap for these inputs (seed
    ``params.roadmap_seed``) is loaded or built and saved; otherwise one of ``params.n_nodes``
    nodes is built with ``rng`` within ``until``. A given roadmap must have been built for this
    scene, character and parameters (ValueError otherwise). Statuses: SOLVED; INVALID_START /
    INVALID_GOAL (no valid node there, or no jump leaves / reaches it); INFEASIBLE (not
    connected); TIMEOUT (``until`` fired before the query ended).

    The roadmap checks the trunk along each parabola: a path whose whole-body motion holds a
    keyframe the builder's checker refuses, or a push or landing beyond the legs' reach or
    the contact cone, has its first such jump refused and the roadmap is asked again, at
    most ``tuning.JUMP_REPLANS`` times (``stats["jumps_refused"]``); the cleanest answer
    found is returned (APPROXIMATE, with the reasons, when none is clean).

    The work is counted, not timed: the roadmap's size (``params.n_nodes``) decides what is
    built. A ``Deadline`` ``until`` is only a wall-clock cap (the build gets
    ``params.build_share`` of it): when it stops the work, ``stats["clock_cap_hit"]`` is 1
    and the message says a replay may differ.
    """
    params = JumpParams() if params is None else params
    clock = time.perf_counter()
    timings: dict[str, float] = {}
    rparams = params.roadmap_params(scene, character, data)
    min_limbs = params.limbs_needed(character)
    model = ReducedModel.build(
        scene, character, data, lean=params.lean, mu=params.mu, margin=rparams.max_gap / 2
    )
    timings["model"] = time.perf_counter() - clock
    mark = time.perf_counter()
    s_spec = np.asarray(start, dtype=np.float64)
    g_spec = np.asarray(goal, dtype=np.float64)
    start_node = _as_node(model, s_spec, min_limbs, params.stand_radius, rng, _point(g_spec))
    goal_node = _as_node(model, g_spec, min_limbs, params.stand_radius, rng, _point(s_spec))
    timings["endpoints"] = time.perf_counter() - mark
    if start_node is None:
        return PlanResult(PlanStatus.INVALID_START, None, dict(timings), "no valid node at start")
    if goal_node is None:
        return PlanResult(PlanStatus.INVALID_GOAL, None, dict(timings), "no valid node at goal")

    mark = time.perf_counter()
    stats: dict[str, float | int | str] = {}
    caps = [until] if isinstance(until, Deadline) else []  # wall-clock caps polled

    def capped(message: str) -> str:
        # whether a wall-clock cap, not the counted work, stopped a stage, in the stats
        hit = any(cap.fired for cap in caps)
        stats["clock_cap_hit"] = int(hit)
        if not hit:
            return message
        note = "the wall-clock cap stopped the work: a replay may differ"
        return f"{message}; {note}" if message else note

    if roadmap is None and store_dir is not None:
        store = RoadmapStore(store_dir)
        rid = store.build(scene, character, data, params, params.n_nodes, params.roadmap_seed)
        roadmap = store.load(rid)
    elif roadmap is None:
        # Leave a share of a deadline to the query and the keyframes.
        if isinstance(until, Deadline):
            build_cap = Deadline(params.build_share * until.remaining())
            caps.append(build_cap)
            build_until = any_of(until, build_cap)
        else:
            build_until = until
        built = build_roadmap(
            SceneSampler(model, min_limbs),
            params.n_nodes,
            rparams,
            rng=rng,
            collides_many=model.collider,
            until=build_until,
        )
        if built.value is None:
            message = capped(built.message)
            return PlanResult(built.status, None, {**timings, **stats}, message)
        roadmap = built.value
    elif roadmap.params.digest() != rparams.digest():
        raise ValueError("the roadmap was built for another scene, character or parameters")
    timings["roadmap"] = time.perf_counter() - mark
    stats.update({f"roadmap_{k}": v for k, v in roadmap.stats.items() if k in ("nodes", "edges")})

    mark = time.perf_counter()
    stances = _NodeStances(model, data, roadmap)
    refused: list[tuple[int, int]] = []
    best: tuple[tuple[int, int, int], JumpPlan, list[str], PlanResult[JumpPath]] | None = None
    unbuilt: tuple[_PathMotion, PlanResult[JumpPath]] | None = None
    timings["keyframes"] = 0.0
    for attempt in range(tuning.JUMP_REPLANS + 1):
        found = roadmap.query(
            start_node,
            goal_node,
            collides_many=model.collider,
            node_clear=stances.clear,
            refused=refused,
            until=until,
        )
        if found.value is None:
            break
        path = found.value
        keyframes_mark = time.perf_counter()
        planned = _path_motion(model, params, path, start_node, goal_node, stances)
        beyond = planned.beyond_the_body()
        if beyond is not None and attempt < tuning.JUMP_REPLANS:
            # a push or landing beyond the legs' reach or the contact cone: refused before
            # the builder runs
            unbuilt = unbuilt or (planned, found)
            refused.append(path.jump_labels(beyond))
            timings["keyframes"] += time.perf_counter() - keyframes_mark
            continue
        plan, problems, unplayable, score = _animated(model, roadmap, planned, len(refused), until)
        timings["keyframes"] += time.perf_counter() - keyframes_mark
        if best is None or score < best[0]:
            best = (score, plan, problems, found)
        if not problems or unplayable is None or score[0]:  # clean, or nothing to refuse
            break
        if attempt == tuning.JUMP_REPLANS:
            break  # no query left to ask without it
        # the roadmap checks the trunk only: a jump whose whole-body motion the builder
        # cannot play cleanly is refused and the query asked again (jump paper section 5)
        refused.append(path.jump_labels(unplayable))
    if best is None and unbuilt is not None:
        # every path found went beyond the body: the first, animated, says so
        planned, found = unbuilt
        keyframes_mark = time.perf_counter()
        plan, problems, _, score = _animated(model, roadmap, planned, 0, until)
        timings["keyframes"] += time.perf_counter() - keyframes_mark
        best = (score, plan, problems, found)
    timings["query"] = time.perf_counter() - mark - timings["keyframes"]
    timings["total"] = time.perf_counter() - clock
    stats["jumps_refused"] = len(refused)
    if best is None:
        stats.update(found.stats)
        stats.update(timings)
        return PlanResult(found.status, None, stats, capped(found.message))
    _, plan, problems, found = best
    plan = replace(plan, timings=dict(timings))
    stats.update(found.stats)
    stats.update(timings)
    if problems:
        return PlanResult(PlanStatus.APPROXIMATE, plan, stats, capped("; ".join(problems)))
    return PlanResult(PlanStatus.SOLVED, plan, stats, capped(found.message))


def _animated(
    model: ReducedModel,
    roadmap: Roadmap,
    planned: _PathMotion,
    refusals: int,
    until: Termination,
) -> tuple[JumpPlan, list[str], int | None, tuple[int, int, int]]:
    """The plan of ``planned`` with its whole-body motion built, what keeps it from being
    played as is (:func:`_problems`), the first jump at fault, and its score (cut short by
    ``until`` or not, keyframes the checker refuses plus problems, then ``refusals``: lower
    is cleaner)."""
    motion = build_motion(model.character, model.scene.collision.bvh, planned.spec, until=until)
    plan = JumpPlan(
        planned.jumps,
        motion.keyframes,
        {},
        planned.path,
        roadmap,
        motion.phases,
        motion.com,
        motion.report,
    )
    problems, unplayable = _problems(planned, motion)
    refused_keys = sum(not check.valid for check in motion.checks)
    score = (int(motion.report.cut_short), refused_keys + len(problems), refusals)
    return plan, problems, unplayable, score


def _problems(planned: _PathMotion, motion: BuiltMotion) -> tuple[list[str], int | None]:
    """What keeps a jump plan's motion from being played as is, in words, and the index of
    the first jump at fault (its crouch, push, flight or landing, or the stand after the last
    landing, holds a keyframe the checker refuses, or it pushes or lands beyond the legs'
    reach or the contact cone); None when no jump is (the motion was cut short)."""
    report = motion.report
    problems = [f"whole-body motion: {report.shortfall()}"] if not report.complete else []
    beyond = planned.beyond_the_body()
    at_fault = [] if beyond is None else [beyond]
    jumps = planned.jumps
    for i, j in enumerate(jumps):
        for what, in_cone, in_reach in (
            ("push", j.push_in_cone, j.push_in_reach),
            ("landing", j.landing_in_cone, j.landing_in_reach),
        ):
            if not in_cone:
                problems.append(f"jump {i}: the {what} needs a force outside the contact cone")
            if not in_reach:
                problems.append(
                    f"jump {i}: the {what} needs the COM to travel beyond the legs' reach"
                )
    starts = [j.t_start for j in jumps]
    for key, check in zip(motion.keyframes, motion.checks, strict=True):
        if not check.valid and starts:
            at_fault.append(max(0, bisect.bisect_right(starts, key.t) - 1))
            break
    return problems, (min(at_fault) if at_fault else None)


def _point(spec: FloatArray) -> FloatArray:
    return np.asarray(spec[:3, 3] if spec.shape == (4, 4) else spec, dtype=np.float64)


class _NodeStances:
    """The whole-body contact stance of each node a query touches (computed once), and
    whether it is clear of the scene and of itself (the builder's keyframe check): the
    roadmap checks only the trunk, and a limb placed on its contact may still pass through
    a wall beside it (jump paper section 5: the contact configurations are collision-free)."""

    def __init__(self, model: ReducedModel, data: OfflineData, roadmap: Roadmap) -> None:
        self.character = model.character
        self.stancer = NodeStancer(model.character, data)
        self.checker = KeyframeChecker(model.character, model.scene.collision.bvh)
        self.surfaces = {surface.id: surface for surface in model.surfaces}
        self.roadmap = roadmap
        self._made: dict[int, tuple[ContactState, bool]] = {}

    def of(self, nodes: RoadmapNodes, i: int, label: int) -> tuple[ContactState, bool]:
        """The contact state of node ``i`` of ``nodes`` (``label``: its index in the roadmap,
        or START / GOAL) and whether it is clear."""
        made = self._made.get(label)
        if made is None:
            row = _node_row(nodes, i)
            stance = self.stancer.stance(
                nodes.positions[i],
                nodes.orientations[i],
                row["active"],
                row["points"],
                row["normals"],
                [self.surfaces.get(int(sid)) for sid in row["surfaces"]],
            )
            state = _state(self.character, row, stance)
            check = self.checker.check(np.asarray(state.q), state.contacts)
            made = (state, not check.colliding)
            self._made[label] = made
        return made

    def clear(self, i: int) -> bool:
        """Whether roadmap node ``i``'s stance is clear (``query_roadmap``'s ``node_clear``)."""
        return self.of(self.roadmap.nodes, i, i)[1]


@dataclass(frozen=True, slots=True)
class _PathMotion:
    """A roadmap path's jumps (of the COM) and the motion spec that animates them, before
    the builder runs: ``jumps`` as the timing makes them (the landing where the motion
    makes its contacts), ``spec`` the builder's input."""

    path: JumpPath
    jumps: tuple[JumpInfo, ...]
    spec: MotionSpec

    def beyond_the_body(self) -> int | None:
        """The first jump whose push or landing needs a force outside its cone or a COM
        travel beyond the legs' reach (None: none)."""
        for i, j in enumerate(self.jumps):
            if not (
                j.push_in_cone and j.push_in_reach and j.landing_in_cone and j.landing_in_reach
            ):
                return i
        return None


def _path_motion(
    model: ReducedModel,
    params: JumpParams,
    path: JumpPath,
    start: RoadmapNodes,
    goal: RoadmapNodes,
    stances: _NodeStances,
) -> _PathMotion:
    """The jumps (of the COM) along a roadmap path and the motion spec that animates them."""
    char = model.character
    states: list[ContactState] = []
    rows: list[dict[str, Any]] = []
    for label in path.nodes:
        nodes, i = (
            (start, 0)
            if label == START
            else (goal, 0)
            if label == GOAL
            else (stances.roadmap.nodes, int(label))
        )
        rows.append(_node_row(nodes, i))
        states.append(stances.of(nodes, i, int(label))[0])
    ends: list[tuple[JumpEnd, JumpEnd, FloatArray, float]] = []
    legs: list[JumpLeg] = []
    for i in range(len(path)):
        jump = jump_at(path.positions[i], path.positions[i + 1], float(path.t[i]), path.g)
        # the COM's parabola: the root's, translated by the takeoff stance's COM offset
        offset = com_position(char.model, states[i].q) - states[i].q[:3]
        takeoff = _end(model, rows[i], states[i], jump.p0 + offset, jump.v0)
        landing = _end(model, rows[i + 1], states[i + 1], jump.p1 + offset, jump.vimp)
        ends.append((takeoff, landing, jump.apex + offset, jump.duration))
        legs.append(
            JumpLeg(
                takeoff.position,
                jump.v0,
                jump.duration,
                jump.g,
                takeoff.cone_axis,
                takeoff.cone_mu,
                landing.cone_axis,
                landing.cone_mu,
                params.roadmap.vimpmax,
            )
        )
    spec, timing = jump_spec(char, states, legs, rate=params.rate)
    # the landing as the motion makes it: its contacts may be made later on the parabola
    # than the roadmap's node (the legs drawn up in flight, ``planner.motion.jump``)
    jumps = tuple(
        _info(
            takeoff,
            replace(
                landing,
                position=_ro(when.touchdown_com),
                velocity=_ro(when.touchdown_velocity),
            ),
            apex,
            when.touchdown - when.takeoff,
            when,
        )
        for (takeoff, landing, apex, _), when in zip(ends, timing, strict=True)
    )
    return _PathMotion(path, jumps, spec)


def _info(
    takeoff: JumpEnd, landing: JumpEnd, apex: FloatArray, duration: float, when: JumpTiming
) -> JumpInfo:
    return JumpInfo(
        takeoff,
        landing,
        _ro(apex),
        duration,
        when.crouch,
        when.push,
        when.takeoff,
        when.apex,
        when.touchdown,
        when.rest,
        _ro(when.push_acceleration),
        _ro(when.landing_acceleration),
        when.push_in_cone,
        when.landing_in_cone,
        when.push_in_reach,
        when.landing_in_reach,
    )


def _state(character: Character, row: dict[str, Any], stance: Stance) -> ContactState:
    """The contact state of a node's stance: the limbs whose contact was made, each held at
    its effector placement in ``stance.q``, touching at the limb's contact points."""
    achieved = stance.achieved & np.asarray(row["active"], dtype=bool)
    contacts = []
    for k in np.flatnonzero(achieved):
        limb = character.default_limbs[k]
        normal = np.asarray(row["normals"][k], dtype=np.float64)
        placement = np.asarray(stance.placements[k], dtype=np.float64)
        contacts.append(
            LimbContact(
                limb.name,
                placement,
                contact_points(limb, placement, normal),
                normal,
                float(row["mus"][k]),
                int(row["surfaces"][k]),
            )
        )
    return ContactState(stance.q, tuple(contacts))


def _end(
    model: ReducedModel,
    row: dict[str, Any],
    state: ContactState,
    position: FloatArray,
    velocity: FloatArray,
) -> JumpEnd:
    """Takeoff or landing description (COM ``position`` (3,), ``velocity`` (3,)): the
    contacts the stance achieved (each at the centre of its contact points); the cone of the
    node (recomputed from the achieved contacts when some could not be made)."""
    char = model.character
    names = [limb.name for limb in char.default_limbs]
    achieved = np.zeros(len(names), dtype=bool)
    for contact in state.contacts:
        achieved[names.index(contact.limb)] = True
    contacts = tuple(
        JumpContact(c.limb, _ro(c.points.mean(axis=0)), _ro(c.normal), float(c.mu))
        for c in state.contacts
    )
    mask = achieved if achieved.any() else np.asarray(row["active"], dtype=bool)
    axes, mus, _ = centroidal_cones(row["normals"][None], row["mus"][None], mask[None])
    return JumpEnd(_ro(position), _ro(velocity), contacts, _ro(axes[0]), float(mus[0]))


# --------------------------------------------------------------------------------------------
# Roadmap store


class RoadmapStore:
    """Roadmaps on disk, by id: ``<id>.npz`` (``Roadmap.save``) and ``<id>.json`` (info).

    The id hashes the scene content, the character's offline data key, the parameters, the
    node count and the seed, so equal requests share a roadmap. Files are written to a
    temporary name and renamed, so a finished roadmap survives a restart and a crash never
    leaves a truncated one.
    """

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)

    @staticmethod
    def roadmap_id(
        scene: Scene,
        character: Character,
        data: OfflineData,
        params: JumpParams,
        n_nodes: int,
        seed: int,
    ) -> str:
        """24 hex digits identifying the roadmap these inputs build."""
        text = json.dumps(
            {
                "model": params.model_key(scene, character, data),
                "roadmap": params.roadmap.to_json(),
                "n_nodes": int(n_nodes),
                "seed": int(seed),
            },
            sort_keys=True,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:24]

    def path(self, roadmap_id: str) -> Path:
        """The .npz file of a roadmap id."""
        if not roadmap_id.isalnum():
            raise ValueError("invalid roadmap id")
        return self.directory / f"{roadmap_id}.npz"

    def exists(self, roadmap_id: str) -> bool:
        """True when the roadmap is finished and stored."""
        return self.path(roadmap_id).is_file()

    def info(self, roadmap_id: str) -> dict[str, Any] | None:
        """{"status": "ready", "nodes", "edges", "bytes", "build_seconds", ...} or None."""
        if not self.exists(roadmap_id):
            return None
        meta = self.path(roadmap_id).with_suffix(".json")
        out: dict[str, Any] = json.loads(meta.read_text()) if meta.is_file() else {}
        out["status"] = "ready"
        out["bytes"] = self.path(roadmap_id).stat().st_size
        return out

    def load(self, roadmap_id: str) -> Roadmap:
        """The stored roadmap; FileNotFoundError if absent."""
        return Roadmap.load(self.path(roadmap_id))

    def params(self, roadmap_id: str) -> JumpParams:
        """The ``JumpParams`` the roadmap was built with (pass them to ``plan_jumps`` with the
        roadmap); FileNotFoundError if absent."""
        meta = json.loads(self.path(roadmap_id).with_suffix(".json").read_text())
        return JumpParams.from_json(meta["params"])

    def delete_of_scene(self, scene_id: str) -> int:
        """Remove every stored roadmap built on scene ``scene_id`` (its info names the scene):
        the .npz first (the roadmap is no longer ready), then its info. Returns how many."""
        removed = 0
        for meta in sorted(self.directory.glob("*.json")):
            try:
                scene = json.loads(meta.read_text()).get("scene")
            except (OSError, ValueError):
                continue  # being written, or not a roadmap's info
            if scene != scene_id:
                continue
            meta.with_suffix(".npz").unlink(missing_ok=True)
            meta.unlink(missing_ok=True)
            removed += 1
        return removed

    def delete(self, roadmap_id: str) -> bool:
        """Remove a stored roadmap (the .npz first: it is no longer ready, then its info);
        False when none was stored under ``roadmap_id``."""
        path = self.path(roadmap_id)
        if not path.is_file():
            return False
        path.unlink(missing_ok=True)
        path.with_suffix(".json").unlink(missing_ok=True)
        return True

    def used_bytes(self) -> int:
        """Bytes the stored roadmaps (their .npz and .json files) take in the directory."""
        total = 0
        for entry in self.directory.glob("*"):
            if entry.suffix in (".npz", ".json"):
                try:
                    total += entry.stat().st_size
                except OSError:
                    continue  # removed meanwhile
        return total

    def save(
        self,
        roadmap_id: str,
        roadmap: Roadmap,
        meta: dict[str, Any],
        admit: Callable[[int], AbstractContextManager[None]] | None = None,
    ) -> None:
        """Store a roadmap atomically: both files written under temporary names, then the
        .json renamed into place and the .npz (which marks it ready). ``admit(bytes)``, when
        given, is entered around the renames with the two files' size: it may refuse by
        raising (nothing is then stored) or hold a lock meanwhile (a storage quota)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        path = self.path(roadmap_id)
        written: list[Path] = []
        try:
            info = _temporary_file(self.directory, json.dumps(meta).encode(), ".json.tmp")
            written.append(info)
            fd, name = tempfile.mkstemp(dir=self.directory, suffix=".npz.tmp")
            os.close(fd)
            written.append(Path(name))
            roadmap.save(name)
            size = sum(p.stat().st_size for p in written)
            with admit(size) if admit is not None else nullcontext():
                os.replace(info, path.with_suffix(".json"))
                os.replace(name, path)
        finally:
            for leftover in written:
                leftover.unlink(missing_ok=True)

    def build(
        self,
        scene: Scene,
        character: Character,
        data: OfflineData,
        params: JumpParams,
        n_nodes: int,
        seed: int,
        progress: Callable[[float], None] | None = None,
        until: Termination = never,
        admit: Callable[[int], AbstractContextManager[None]] | None = None,
    ) -> str:
        """Build (unless already stored) and store the roadmap; returns its id.

        ``progress`` receives fractions in [0, 1]. A build cut short by ``until`` is stored
        too, with ``complete`` False in its info. ``admit`` : see :meth:`save`.
        """
        rid = self.roadmap_id(scene, character, data, params, n_nodes, seed)
        if self.exists(rid):
            if progress is not None:
                progress(1.0)
            return rid
        clock = time.perf_counter()
        rparams = params.roadmap_params(scene, character, data)
        model = ReducedModel.build(
            scene, character, data, lean=params.lean, mu=params.mu, margin=rparams.max_gap / 2
        )
        result = build_roadmap(
            SceneSampler(model, params.limbs_needed(character)),
            n_nodes,
            rparams,
            rng=np.random.default_rng(seed),
            collides_many=model.collider,
            until=until,
            progress=progress,
        )
        if result.value is None:
            raise RuntimeError(f"roadmap build failed: {result.status.value} {result.message}")
        roadmap = result.value
        meta = {
            "params": params.to_json(),
            "nodes": len(roadmap.nodes),
            "edges": len(roadmap.edges),
            "build_seconds": time.perf_counter() - clock,
            "complete": result.status is PlanStatus.SOLVED,
            "scene": scene.id,
            "character": character.id,
            "seed": int(seed),
        }
        self.save(rid, roadmap, meta, admit)
        return rid


def _temporary_file(directory: Path, payload: bytes, suffix: str) -> Path:
    """``payload`` written to a new temporary file in ``directory``; its path."""
    fd, tmp = tempfile.mkstemp(dir=directory, suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


__all__ = [
    "JumpContact",
    "JumpEnd",
    "JumpInfo",
    "JumpParams",
    "JumpPlan",
    "RoadmapStore",
    "plan_jumps",
]
