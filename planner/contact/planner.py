"""The whole contact-planning pipeline: start and goal states, root path, contact sequence,
COM trajectory and keyframes (DESIGN.md steps 3-8).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner import budgets
from planner.character import MAX_PITCH, Character
from planner.contact.context import ContactContext, ContactParams, make_context
from planner.contact.generation import stand_up
from planner.contact.heading import face_the_way
from planner.contact.reachability import ReachabilityChecker
from planner.contact.root_path import RootPath, edge_valid, plan_root_path
from planner.contact.root_sampler import OrientationBounds
from planner.contact.sequence import SequenceParams, contact_sequence, resume_index
from planner.contact.slope import LEVEL_PITCH, follow_slope, straight_slope_path
from planner.contact.standing import standing_state, state_from_root_pose
from planner.contact.state import ContactState
from planner.kinematics import frame_placement
from planner.motion.sequence import SequenceMotion, Timing, sequence_motion
from planner.offline import OfflineData
from planner.result import PlanResult, PlanStatus
from planner.scene import Scene
from planner.shapes import Capsule
from planner.termination import Deadline, Termination

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Endpoint:
    """Where a plan starts or ends: a root pose (4, 4), a point to stand at (3,), or a state."""

    root_pose: FloatArray | None = None
    stand_at: FloatArray | None = None
    state: ContactState | None = None

    def __post_init__(self) -> None:
        given = [x is not None for x in (self.root_pose, self.stand_at, self.state)]
        if sum(given) != 1:
            raise ValueError("an endpoint is exactly one of root_pose, stand_at or state")


@dataclass(frozen=True, slots=True)
class PlanOptions:
    """rate : keyframes per second. step : m between root-path checks (<= 0.05).
    sequence : contact-sequence tuning. contact : contact-generation tuning. limbs : limbs
    the walk may use besides those in contact at the start or goal (a hand on a handrail).
    max_pitch : rad, how far the trunk may pitch (None: the character's ``max_pitch``); above
    ``LEVEL_PITCH`` the root path is laid along the terrain's slope (a hexapod climbing).
    timing : pace, transition-point cost and user attractors of the COM (2PAC)."""

    rate: float = 30.0
    step: float = 0.05
    sequence: SequenceParams = field(default_factory=SequenceParams)
    contact: ContactParams = field(default_factory=ContactParams)
    limbs: tuple[str, ...] = ()
    max_pitch: float | None = None
    timing: Timing = field(default_factory=Timing)

    def __post_init__(self) -> None:
        if self.max_pitch is not None and not 0.0 <= self.max_pitch <= MAX_PITCH:
            raise ValueError(f"max_pitch must be in [0, {MAX_PITCH}] rad")


@dataclass(frozen=True, slots=True)
class ContactPlan:
    """A planned motion: states (one contact change apart), root path and the motion."""

    states: tuple[ContactState, ...]
    root_path: FloatArray
    motion: SequenceMotion | None
    timings: dict[str, float]


def _detour_checker(
    scene: Scene,
    character: Character,
    data: OfflineData,
    checker: ReachabilityChecker,
    stalls: Sequence[FloatArray],
    ends: Sequence[FloatArray],
) -> ReachabilityChecker | None:
    """``checker``'s condition with the trunk also kept ``DETOUR_RADIUS`` m from a vertical
    line through each of the ``stalls`` (root positions (3,) where walks stalled) that lies
    farther than that plus the trunk's reach from both ``ends`` (the guide's end root
    positions (3,)); None when no stall is kept."""
    clear = DETOUR_RADIUS + checker.radius
    kept = [
        p
        for p in stalls
        if min(float(np.linalg.norm(np.asarray(p)[:2] - e[:2])) for e in ends) > clear
    ]
    if not kept:
        return None
    column = Capsule(DETOUR_RADIUS, 2.0 * float(character.q_ref[2]) + 1.0)
    obstacles = []
    for p in kept:
        pose = np.eye(4)
        pose[:3, 3] = p
        obstacles.append((column, pose))
    return ReachabilityChecker(scene, character, data, obstacles=obstacles)


def _resolve(
    endpoint: Endpoint,
    scene: Scene,
    character: Character,
    data: OfflineData,
    checker: ReachabilityChecker,
    rng: np.random.Generator,
    until: Termination,
    facing: FloatArray | None = None,
) -> PlanResult[ContactState]:
    """The state of ``endpoint``; a ``stand_at`` endpoint faces the point ``facing`` (3,)
    when given (so that a walk starts and ends looking along the way), else any yaw."""
    if endpoint.state is not None:
        return PlanResult(PlanStatus.SOLVED, endpoint.state)
    if endpoint.stand_at is not None:
        yaw = None
        if facing is not None:
            d = np.asarray(facing, dtype=np.float64)[:2] - endpoint.stand_at[:2]
            if float(np.linalg.norm(d)) > 0.05:
                yaw = float(np.arctan2(d[1], d[0]))
        found = standing_state(
            scene,
            character,
            data,
            endpoint.stand_at,
            rng=rng,
            until=until,
            checker=checker,
            yaw=yaw,
        )
        if found.status in (PlanStatus.SOLVED, PlanStatus.TIMEOUT) or yaw is None:
            return found
        return standing_state(  # no room facing the way: any heading
            scene, character, data, endpoint.stand_at, rng=rng, until=until, checker=checker
        )
    assert endpoint.root_pose is not None
    return state_from_root_pose(scene, character, data, endpoint.root_pose, checker=checker)


_RETRY_JITTERS = (0.05, 0.15, 0.3, 0.3, 0.3, 0.3)
"""m, the contact candidates' score jitter of each contact walk a plan tries, in order: at
most this many walks, while the search budget lasts."""
RESUME_BACK_M = 0.4
"""m of guide a retry backs off from where a walk stalled: the walk is resumed from its last
state with every leg down this far behind its furthest progress."""
DETOUR_RADIUS = 0.3
"""m: once a walk along a straight guide stalled, a guide planned again keeps the trunk this
far from a vertical line through the root where each walk stalled (``_detour_checker``): the
straight line a new search finds first over open ground would lead the walk back to the same
footholds (a searched guide is random and goes elsewhere anyway)."""
BLOCKED_RESUMES = 1
"""Times a plan walks on from before where a walk was blocked short of its guide's end (no
foothold ahead in its reach), every foothold that walk took in its last ``RESUME_BACK_M`` of
guide avoided for its limb (within ``generation.AVOID_RADIUS``): on rubble the first walk,
along the straight line, put its right foot on a slab from which no foothold ahead could be
reached, on every seed; walked on again with the same choices, it stuck there again, and
with those footholds avoided it walks on to the goal on 13 seeds of 20 (the others start
over on a new guide, as before)."""
SEARCH_SHARE = budgets.SEARCH_SHARE  # of the work (and of the clock cap) for the search
MAX_REPLAN_WALKS = 8
"""Contact walks a plan may start again when its whole-body motion cannot make a contact
change (2PAC 7.2's last resort, after re-sampling the swing, slowing and stopping at
rest)."""
REPLAN_DEPTH = 2
"""How far back a contact change is planned again: the change itself, then the one that
put its limb where the failing swing starts."""
REPLAN_RESERVE = 1.5
"""A contact change is planned again only while the work left would build the fallback
(2PAC's curve through the states first planned, whole) this many times over: re-planning
never costs the answer its keyframes."""
REPLAN_SHARE_KEPT = 0.5
"""Share of the work left that a re-plan leaves for the keyframes when that work could not
build the fallback whole anyway (a long plan whose motion is short of work): the last clean
trial is then the answer if the re-plan fails."""
REPLAN_JITTERS = (0.05, 0.15, 0.3)
"""m, the contact candidates' score jitter of the walks tried for one re-planned change (as
a stuck walk's retries)."""


def _after(
    prefix: tuple[ContactState, ...], walk: PlanResult[tuple[ContactState, ...]]
) -> PlanResult[tuple[ContactState, ...]]:
    """The walk ``walk`` resumed from the state after ``prefix``, with ``prefix`` before it
    (its stats count the whole sequence's states and how many were kept)."""
    states = (*prefix, *(walk.value or ()))
    stats = {**walk.stats, "states": len(states), "resumed_at": len(prefix)}
    return PlanResult(walk.status, states, stats, walk.message)


def _footholds_taken(states: Sequence[ContactState], since: int) -> list[tuple[str, FloatArray]]:
    """(limb, position (3,)) of every contact made in ``states`` after state ``since``."""
    taken = []
    for k in range(since, len(states) - 1):
        limb = _made(states, k)
        contact = None if limb is None else states[k + 1].contact(limb)
        if contact is not None:
            taken.append((contact.limb, np.asarray(contact.position, dtype=np.float64)))
    return taken


def _better(
    new: PlanResult[tuple[ContactState, ...]], old: PlanResult[tuple[ContactState, ...]]
) -> bool:
    """Whether contact sequence ``new`` beats ``old``: solved, else further along the path."""
    if (new.status is PlanStatus.SOLVED) != (old.status is PlanStatus.SOLVED):
        return new.status is PlanStatus.SOLVED
    return float(new.stats.get("progress_m", 0.0)) > float(old.stats.get("progress_m", 0.0))


def _position(endpoint: Endpoint) -> FloatArray:
    """The world position (3,) an endpoint names."""
    if endpoint.state is not None:
        return np.asarray(endpoint.state.q[:3])
    if endpoint.stand_at is not None:
        return np.asarray(endpoint.stand_at)
    assert endpoint.root_pose is not None
    return np.asarray(endpoint.root_pose[:3, 3])


def _made(states: Sequence[ContactState], k: int) -> str | None:
    """The limb whose contact the change from state k to k + 1 makes, if it makes one."""
    created = set(states[k + 1].limbs) - set(states[k].limbs)
    return next(iter(created)) if created else None


def _root_pose(character: Character, q: FloatArray) -> FloatArray:
    return frame_placement(character.model, q, 1)


def plan_contact_motion(
    scene: Scene,
    character: Character,
    data: OfflineData,
    start: Endpoint,
    goal: Endpoint,
    *,
    rng: np.random.Generator,
    time_budget_s: float,
    options: PlanOptions | None = None,
    cap_s: float | None = None,
) -> PlanResult[ContactPlan]:
    """Plan from ``start`` to ``goal`` with the work ``time_budget_s`` seconds buy.

    The status is the worst of the stages: INVALID_START / INVALID_GOAL when an endpoint has
    no valid standing state, the root path's status when it fails (TIMEOUT, INFEASIBLE), the
    contact sequence's otherwise (SOLVED, or APPROXIMATE with the partial plan). Keyframes
    are computed for whatever states were found.

    Work, not the clock, decides (``planner.budgets``): ``time_budget_s`` buys a number of
    work units, the search (endpoints, root path, contacts) stops once it has used
    ``SEARCH_SHARE`` of them and keyframes stop when the rest is spent, so the answer for a
    seed is the same on any machine. The wall clock is only a cap, ``cap_s`` seconds from
    now (default ``time_budget_s``; the search's cap is ``SEARCH_SHARE`` of it): when it
    stops a stage first, ``stats["clock_cap_hit"]`` is True and the message says so.
    """
    opts = options or PlanOptions()
    names = [limb.name for limb in character.limbs]
    unknown = [x for x in opts.limbs if x not in names]
    if unknown:
        raise ValueError(f"options.limbs: unknown limbs {unknown}; expected some of {names}")
    max_pitch = character.max_pitch if opts.max_pitch is None else opts.max_pitch
    budget = budgets.plan_budget(time_budget_s, cap_s)
    assert budget.cap is not None
    cap_seconds = budget.cap.seconds
    search_units = SEARCH_SHARE * budget.units  # the search; keyframes get the rest
    search_cap = Deadline(SEARCH_SHARE * cap_seconds, budget.cap.start)

    def search(cost: float) -> Termination:
        return budget.stage(cost, limit=search_units, cap=search_cap)

    def search_spent() -> bool:
        return budget.spent(search_units) or budget.cap_hit

    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[name] = timings.get(name, 0.0) + now - clock
        clock = now

    def budget_stats() -> dict[str, float | int | str]:
        return {
            "work_units": round(budget.units, 3),
            "work_used": round(budget.used, 3),
            "clock_cap_hit": budget.cap_hit,
        }

    def capped(message: str) -> str:
        if not budget.cap_hit:
            return message
        note = (
            f"the wall-clock cap ({cap_seconds:.3g} s) stopped the work before its budget "
            "was spent: a replay may differ"
        )
        return f"{message}; {note}" if message else note

    checker = ReachabilityChecker(scene, character, data)
    empty_path = np.zeros((0, 4, 4))
    standing = search(budgets.STANDING_ATTEMPT_UNITS)
    start_state = _resolve(start, scene, character, data, checker, rng, standing, _position(goal))
    if not start_state.status or start_state.value is None:
        lap("endpoints")
        timed_out = start_state.status is PlanStatus.TIMEOUT
        status = PlanStatus.TIMEOUT if timed_out else PlanStatus.INVALID_START
        plan = ContactPlan((), empty_path, None, timings)
        return PlanResult(status, plan, budget_stats(), capped(f"start: {start_state.message}"))
    away = 2.0 * _position(goal) - _position(start)  # face on, the way the walk went
    goal_state = _resolve(goal, scene, character, data, checker, rng, standing, away)
    lap("endpoints")
    if not goal_state.status or goal_state.value is None:
        timed_out = goal_state.status is PlanStatus.TIMEOUT
        status = PlanStatus.TIMEOUT if timed_out else PlanStatus.INVALID_GOAL
        plan = ContactPlan((start_state.value,), empty_path, None, timings)
        return PlanResult(status, plan, budget_stats(), capped(f"goal: {goal_state.message}"))

    ctx = make_context(scene, character, data, opts.contact)
    start_root = _root_pose(character, start_state.value.q)
    goal_root = _root_pose(character, goal_state.value.q)
    direct = None  # a trunk that may pitch first tries the straight line over the terrain
    if max_pitch > LEVEL_PITCH:
        direct = straight_slope_path(
            checker, start_root, goal_root, spacing=opts.sequence.spacing, max_pitch=max_pitch
        )
        lap("root_path")
    terrain_guide = None  # a level trunk whose straight line leaves its legs' reach (a flight
    # of stairs between a landing and the floor) first tries that line at standing height over
    # the terrain: a search wandered 0.8 m sideways going down Talos's stair_bauzil flight
    if direct is None and not edge_valid(checker, start_root, goal_root, opts.step):
        terrain_guide = straight_slope_path(
            checker, start_root, goal_root, spacing=opts.sequence.spacing, max_pitch=0.0
        )
        lap("root_path")
    walking = {c.limb for c in (*start_state.value.contacts, *goal_state.value.contacts)}
    walking.update(opts.limbs)
    cycle_units = budgets.SEQUENCE_CYCLE_UNITS_PER_LIMB * max(1, len(walking))
    checked = ctx.work.states_checked

    def walk() -> bool:
        # a cycle, and the states the previous one checked (a cycle of failures costs more)
        nonlocal checked
        new, checked = ctx.work.states_checked - checked, ctx.work.states_checked
        cost = cycle_units + budgets.STATE_CHECK_UNITS * new
        return budget.poll(cost, search_units, search_cap)

    best: tuple[PlanResult[tuple[ContactState, ...]], FloatArray, PlanResult[Any]] | None = None
    attempts = 0
    stranded = False  # a walk stalled unable to release a leg it left behind
    stalls: list[FloatArray] = []  # root positions (3,) where walks stalled
    straight = False  # the last guide searched is the straight line from start to goal
    fenced = False  # a walk along a straight guide stalled: later guides go round stalls
    resume_gained = True  # the best walk may be walked on (no resume from it gained nothing)
    dead_ends: list[tuple[str, FloatArray]] = []  # footholds a resumed walk avoids
    blocked_resumes = 0  # walks resumed after a walk was blocked (``BLOCKED_RESUMES``)
    for jitter in _RETRY_JITTERS:
        # A stuck walk is walked on from before where it stalled, with noisier foothold
        # choices; the best attempt (SOLVED, else the furthest along) is kept.
        if best is not None and (best[0].status is PlanStatus.SOLVED or search_spent()):
            break
        attempts += 1
        path: PlanResult[RootPath]
        resumed = best is not None and resume_gained and not stranded
        if resumed:
            # a walk that stalled is walked on from a little before where it stalled, along
            # the same guide, its states up to there kept; once that gains nothing, or after
            # a walk left a leg behind that it could not release, the next walk starts over
            # on a new guide
            assert best is not None
            poses, path = best[1], best[2]
            kept = best[0].value or (start_state.value,)
            k = resume_index(kept, poses, RESUME_BACK_M)
            prefix, start_from = tuple(kept[:k]), kept[k]
        elif direct is not None:
            poses, path = direct, PlanResult(PlanStatus.SOLVED, None, {"direct_path": 1})
        elif terrain_guide is not None and best is None:
            poses = terrain_guide
            path = PlanResult(PlanStatus.SOLVED, None, {"terrain_path": 1})
        else:
            # a search over open ground finds the straight line first, every time: once a
            # walk along it stalled, a guide round where walks stalled is sought first
            ends = (start_root[:3, 3], goal_root[:3, 3])
            detour = None
            if fenced:
                detour = _detour_checker(scene, character, data, checker, stalls, ends)
            path = PlanResult(PlanStatus.INFEASIBLE, None)
            for guide_checker in [c for c in (detour, checker) if c is not None]:
                path = plan_root_path(
                    guide_checker,
                    start_root,
                    goal_root,
                    rng=rng,
                    until=search(budgets.ROOT_PATH_ITERATION_UNITS),
                    step=opts.step,
                    orientation_bounds=OrientationBounds(pitch=(-max_pitch, max_pitch)),
                )
                if path.status and path.value is not None:
                    break
            lap("root_path")
            straight = path.value is not None and len(path.value.poses) == 2
            if not path.status or path.value is None:
                if best is None:
                    plan = ContactPlan((start_state.value,), empty_path, None, timings)
                    stats = {**path.stats, **budget_stats()}
                    return PlanResult(path.status, plan, stats, capped(path.message))
                break
            poses = path.value.resample(opts.sequence.spacing)
            if max_pitch > LEVEL_PITCH:
                poses = follow_slope(checker, poses, max_pitch=max_pitch)
            elif len(start_state.value.contacts) == 2:
                # a searched path's yaws are drawn at random: a biped faces its way (its feet
                # turn with its pelvis only as far as its hips' yaw goes; a quadruped's legs
                # stand at its body's corners whatever its heading, and HyQ turned to face
                # its detour round the debris tilted 24 degrees instead of 11)
                poses = face_the_way(checker, poses, path.value.length / (len(poses) - 1))
        # after a walk stalled unable to release a leg it left behind (its body stretched
        # over it), the retries keep the legs behind the body releasable; elsewhere the guard
        # would only cost steps that lead on (rubble_quadruped's plan at its seed)
        params = replace(
            opts.sequence,
            jitter=max(opts.sequence.jitter, jitter),
            release_guard=opts.sequence.release_guard or stranded,
        )
        if not resumed:
            prefix, start_from = (), start_state.value
        sequence = contact_sequence(
            ctx,
            start_from,
            poses,
            goal_state.value,
            rng=rng,
            until=walk,
            params=params,
            limbs=opts.limbs,
            avoid=tuple(dead_ends) if resumed else (),
            resume=resumed,
        )
        if prefix:
            sequence = _after(prefix, sequence)
        lap("contacts")
        stranded = stranded or bool(sequence.stats.get("stranded"))
        if sequence.status is not PlanStatus.SOLVED and sequence.value:
            stalls.append(np.array(sequence.value[-1].q[:3], dtype=np.float64))
            fenced = fenced or straight
        gained = best is None or _better(sequence, best[0])
        if resumed:
            resume_gained = gained
        elif gained:
            resume_gained = True  # a new best walk may be walked on in turn
        if gained:
            best = (sequence, poses, path)
        if sequence.stats.get("blocked"):
            # stuck short of the guide's end with every foothold ahead out of its reach: a
            # walk resumed from behind that point, along the same guide, came back to it
            # and stuck there again on every rubble_humanoid seed measured. It is walked on
            # from there once more with the footholds that led to it avoided
            # (``BLOCKED_RESUMES``); then a new guide
            taken: list[tuple[str, FloatArray]] = []
            walked = sequence.value or ()
            if blocked_resumes < BLOCKED_RESUMES and walked and gained:
                taken = _footholds_taken(walked, resume_index(walked, poses, RESUME_BACK_M))
            resume_gained = bool(taken)
            if taken:
                blocked_resumes += 1
                dead_ends.extend(taken)
    assert best is not None
    sequence, poses, path = best
    states = _standing_up(ctx, sequence.value or (start_state.value,))
    budget.charge(budgets.COM_STATE_UNITS * len(states))  # the COM trajectory, never cut
    goal_reached = goal_state.value
    avoided: list[tuple[str, FloatArray]] = []
    walks = [0]  # contact walks started again
    swings_replanned: set[tuple[str, int, tuple[float, ...]]] = set()  # (limb, origin, root)
    replanned = [0]  # states checked by the re-plans' walks so far (charged per cycle)

    def replan_walk(limit: float) -> Termination:
        # a walk's cycle and the states it checked, until ``limit`` units are used in all
        def poll() -> bool:
            new = ctx.work.states_checked - replanned[0]
            replanned[0] = ctx.work.states_checked
            cost = cycle_units + budgets.STATE_CHECK_UNITS * new
            return budget.poll(cost, limit, budget.cap)

        return poll

    keyframe_units = budgets.keyframe_units(character)

    def replan(
        planned: Sequence[ContactState], phase: int, reserve_s: float
    ) -> tuple[ContactState, ...] | None:
        # the contact change phase ``phase`` could not make, planned again from the last
        # state before its limb let go, that contact sought elsewhere; failing that, from
        # before the limb was put where the swing starts, that contact sought elsewhere too
        change = next(
            (k for k in (phase, phase - 1) if 0 <= k < len(planned) - 1 and _made(planned, k)),
            None,
        )
        # the work the fallback (2PAC's curve through the first states, built whole) needs;
        # when the work left cannot build it anyway, re-planning is the better use of it
        fallback = reserve_s * opts.rate * keyframe_units
        reserve = REPLAN_RESERVE * fallback
        if budget.left() < fallback:
            reserve = REPLAN_SHARE_KEPT * budget.left()
        if change is None or opts.timing.attractors or budget.left() <= reserve:
            return None
        limb = _made(planned, change)
        assert limb is not None
        made = planned[change + 1].contact(limb)
        assert made is not None
        # (contact to avoid, the state the swing changes from): the contact made, then the
        # one the swing starts from, each as far back as the state before the limb let go
        levels: list[tuple[FloatArray, int]] = []
        before = change
        point = np.asarray(made.position)
        for _ in range(REPLAN_DEPTH):
            held = [j for j in range(before + 1) if planned[j].contact(limb) is not None]
            origin = held[-1] if held else before
            levels.append((point, origin))
            start = planned[origin].contact(limb)
            freed = [j for j in range(origin) if planned[j].contact(limb) is None]
            if start is None or not freed:
                break
            point, before = np.asarray(start.position), freed[-1]
        # a swing that failed again from the same contact: its start is what fails
        first = levels[0][1]
        key = (limb, first, tuple(np.round(np.asarray(planned[first].q[:3]), 3).tolist()))
        if key in swings_replanned and len(levels) > 1:
            levels = levels[1:]
        swings_replanned.add(key)
        for point, origin in levels:
            avoided.append((limb, point))
            for jitter in REPLAN_JITTERS:
                if walks[0] >= MAX_REPLAN_WALKS or budget.left() <= reserve:
                    return None
                walks[0] += 1
                replanned[0] = ctx.work.states_checked
                again = contact_sequence(
                    ctx,
                    planned[origin],
                    poses,
                    goal_reached,
                    rng=rng,
                    until=replan_walk(budget.units - reserve),
                    params=replace(opts.sequence, jitter=max(opts.sequence.jitter, jitter)),
                    limbs=opts.limbs,
                    avoid=tuple(avoided),
                    resume=True,
                )
                if again.value is not None and (
                    again.status is PlanStatus.SOLVED or sequence.status is not PlanStatus.SOLVED
                ):
                    return _standing_up(ctx, (*planned[:origin], *again.value))
        return None

    motion = sequence_motion(
        character,
        data,
        scene.collision.bvh,
        states,
        rate=opts.rate,
        timing=opts.timing,
        until=budget.stage(keyframe_units),  # every unit left, whole cap
        replan=replan,
    )
    states = motion.states or states
    lap("motion")
    status = sequence.status
    if status is PlanStatus.TIMEOUT and len(states) > 1:
        status = PlanStatus.APPROXIMATE
    message = sequence.message
    shortfall = motion.quality.shortfall()
    if status is PlanStatus.SOLVED and shortfall is not None:
        # SOLVED means every planned phase has keyframes that collide nowhere and hold every
        # stance contact; a motion short of that is the valid part of a plan
        status = PlanStatus.APPROXIMATE
        message = f"whole-body motion: {shortfall}"
    stats = {**path.stats, **sequence.stats, "attempts": attempts, **budget_stats()}
    return PlanResult(status, ContactPlan(states, poses, motion, timings), stats, capped(message))


def _standing_up(ctx: ContactContext, states: Sequence[ContactState]) -> tuple[ContactState, ...]:
    """``states`` with the last one's chest stood up (``generation.stand_up``): a plan ends
    standing, not bent over the hand holds it has let go."""
    return (*states[:-1], stand_up(ctx, states[-1])) if states else tuple(states)
