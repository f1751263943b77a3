"""Contact sequence along a root path (anchor section 5), one contact change per state.

The root path is a guide, not a constraint. The walker repeats a gait cycle:

1. **advance**: whole-body IK moves the body toward the guide pose ``advance`` metres ahead
   while every contact is held (root free, the guide pose a soft target); the move is kept
   when the state stays valid (balanced with the margin, inside the kinematic polytopes,
   collision-free), else a shorter move is tried, then a taller one (legs clearing a rock);
2. **step**: each walking limb has a desired foothold: its reference effector position at
   the guide pose ``lookahead`` metres ahead of the body, moved to the nearest surface point
   where its contact fits with free space above (the goal contacts near the end). The next
   limb in a fixed gait order (each side back to front, left then right: a crawl for
   quadrupeds, a wave for hexapods) that is off its foothold is released (COM shifted over
   the other contacts, 2PAC) and put down again at its foothold or part of the way there
   (candidates from the limb database, projected by IK, checked for collision, balance with
   the margin and 2PAC feasibility); a leg is not put where no other leg could be released
   afterwards (the rear foot of a biped left unable to follow). The release is only emitted
   with the new contact, so a failed step leaves the sequence unchanged and another limb is
   tried. A stuck walker looks further ahead for footholds (stepping stones), then
   repositions a limb; it stays stuck, looking as far, until its body moves on.

A walk that strands a leg (the body cannot move on and a leg behind it cannot be released,
``STRANDED_CYCLES`` gait cycles in a row) goes back to its last state, every leg down, from
which that leg can be released and walks on from there with that leg guarded until it has
stepped (``SequenceParams.backtracks`` times at most). With ``release_guard`` (the planner's
retries once a walk stalled unable to release a leg it left behind, ``stats["stranded"]``),
neither an advance nor a step may leave a leg behind the body that it could release where it
cannot release it any more: a climber's rear leg left on a lower row as the body and the
front legs move on stretches the body until no leg can move.

Optional limbs (``limbs``, say a hand for a handrail) take a foothold only near their
nominal position and are let go when none is left.

Every emitted state differs from the previous one by exactly one contact added or removed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.contact.checks import check_state, com_of, kinematics_of
from planner.contact.context import ContactContext
from planner.contact.generation import (
    active_dofs,
    break_contact,
    create_contact,
    hold_tasks,
    nearest_foothold,
    posture_task,
)
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import FramePlacementTask, Priority, frame_placement, solve_ik
from planner.result import PlanResult, PlanStatus
from planner.termination import Termination

FloatArray = NDArray[np.float64]
_STEP_FRACTIONS = (1.0, 0.6, 0.3)
# (fraction of the advance, m the body is raised, raised over the body rather than the
# guide): a body that cannot move on at the guide's height may clear a rock with its legs
# when it walks taller
_ADVANCE_TRIES = (
    (1.0, 0.0, False),
    (0.5, 0.0, False),
    (0.25, 0.0, False),
    (0.5, 0.05, False),
    (0.5, 0.1, False),
    (0.5, 0.05, True),
)
_ADVANCE_SLACK = 0.03  # m: an advance leaves the COM this deep in every leg's range (or
# no shallower than it was): a leg left at the end of its range cannot be released
_ROOT_FRAME = 1  # Pinocchio frame of the free-flyer root joint
_PROGRESS_WEIGHTS = np.array([1.0, 1.0, 1.0 / 3.0])
STRIDE_SHARE = 0.35
"""Look-ahead on open ground as a share of the walking limbs' length (root to effector at
the reference posture, mean): 0.34 m for the 1 m humanoid legs, strides of about 0.4 m;
the quadrupeds and the hexapod in proportion to their legs."""
ADVANCE_SHARE = 0.7
"""Body advance per gait cycle on open ground, as a share of the look-ahead."""
OPEN_GROUND_GAIN = 2.0
"""Open-ground strides are used only when they are at least this many times the rough ones:
the bipeds' (humanoid 2.3, Talos 2.4). Measured on the four-legged and six-legged walkers
(HyQ 1.8, quadruped 1.5, hexapod 1.1): their flat-ground strides stay 0.35 m either way (the
crawl is bounded by the kinematic COM polytopes, not the look-ahead), while longer advances
made the HyQ slalom and the hexapod wall climb stop progressing."""
OPEN_GROUND_MARGIN = 0.15
"""m added to the legs' horizontal reach around the root: no scene surface vertex off the
ground's height may lie that close to the path ahead for the ground to count as open."""
ROUGH_LOOKAHEAD = 0.15  # m: look-ahead off open ground (stairs, rocks, walls, slopes)
ROUGH_ADVANCE = 0.1  # m: body advance per gait cycle off open ground
CLIMB_SHARE = 0.3
"""Look-ahead off open ground, as a share of the legs' length, of a walker with open-ground
strides (the bipeds) that walks on its legs alone: one tread of a flight of stairs per
step (0.29 m for the humanoid, 0.31 m for Talos). Measured on the stairs: the humanoid
goes up 0.07 -> 0.16 m/s in half the contact changes, Talos' bauzil flight in 19 states
instead of 47. A walker holding a rail or climbing with its hands keeps the rough lengths
(its hands went 10 mm into the climbing wall with these)."""
CLIMB_ADVANCE_SHARE = 1.0
CLIMB_MAX_HEADING = np.radians(10.0)
"""rad: the climb's long steps are taken only while the body faces the way it goes (its
heading within this of the guide's direction ahead); a body walking crabwise steps short.
Measured on Talos' stair_bauzil flight, whose guide turns and sways sideways: long steps
there crossed its legs (knees 47 mm into the steps, the legs into each other)."""
"""Body advance per gait cycle off open ground, as a share of ``CLIMB_SHARE``'s look-ahead
(the body follows the feet a whole tread)."""
OPEN_GROUND_RISE = 0.03
"""m: ground counts as open when the guide and every foothold one and two long strides
ahead stay within this height of the body's current contacts, each foothold this close to
under the foot's nominal position (no step, rock, slope or obstacle in the way)."""
_FOOTHOLD_RADIUS = 0.35  # m around a limb's nominal position searched for its foothold
_OPTIONAL_RADIUS = 0.3  # the same for an optional limb (a hand reaching for a rail)


LOOP_CONTACT_TOLERANCE = 0.01
"""m: two states whose every limb holds a contact this close to the other's (the same limbs
in contact) hold the same contacts, for ``SequenceParams.loop_visits``."""


STRANDED_CYCLES = 2
"""Gait cycles in a row in which the body did not move on and a leg behind it could not be
released, after which the walk counts as stranded there (``SequenceParams.backtracks``).
Measured on the hexapod's 1 m flat walk from starts moved 1 mm: half of them strand the
right rear leg 0.76 m along, and the walk then stepped its other legs to and fro for eight
more cycles (0.8 s) before it stalled and the planner walked again from the start with
``release_guard`` (0.9 s more). With one cycle, rubble_quadruped's walk at its own seed
counted as stranded where it goes on by itself."""
STRAND_LOOKBACK = 4
"""Gait rounds (a step per walking limb, two states each) a stranded walk looks back over for
a state from which its stranded leg can be released."""
FOLLOW_TRIAL_LEGS = 2
"""Most legs a walker may have for each of its steps to be tried by releasing another leg
from the state it reaches (a biped keeps one other leg, which its step may strand). Over the
14 reference plans, the walkers with four and six legs passed all 270 such trials (each a
release, a COM shift and a lift by IK: 28 of them, 0.05 s, on the hexapod's 1 m walk) and
the bipeds failed 17 of 166; a walker stranding a leg behind it is caught by
``STRANDED_CYCLES``."""


def release_point(
    ctx: ContactContext, states: Sequence[ContactState], leg: str, within: int
) -> int | None:
    """Index into ``states`` of the latest of the last ``within`` states, past the first,
    that holds as many contacts as the first (every leg down), ``leg`` among them, and from
    which ``leg`` can be released (:func:`break_contact`); None when there is none."""
    full = len(states[0].contacts)
    for k in range(len(states) - 1, max(0, len(states) - 1 - within), -1):
        state = states[k]
        down = len(state.contacts) >= full and state.contact(leg) is not None
        if down and break_contact(ctx, state, leg).ok:
            return k
    return None


def _same_contacts(a: ContactState, b: ContactState) -> bool:
    """Whether ``a`` and ``b`` hold the same limbs' contacts, each within
    ``LOOP_CONTACT_TOLERANCE`` of the other's."""
    held = {c.limb: c.position for c in b.contacts}
    return held.keys() == set(a.limbs) and all(
        float(np.linalg.norm(c.position - held[c.limb])) <= LOOP_CONTACT_TOLERANCE
        for c in a.contacts
    )


@dataclass(frozen=True, slots=True)
class SequenceParams:
    """spacing : m between root samples along the guide path. lookahead : m ahead of the body along
    the path where the desired footholds are taken (None: terrain-aware, see
    :func:`gait_lengths`). advance : m the body is moved toward per gait cycle (None:
    terrain-aware, like the lookahead). min_step : m, a limb closer than this
    to its foothold does not step. goal_tolerance : m, a contact this close to the goal's
    counts as reached. max_states : cap on emitted states. max_stuck : gait cycles with
    neither body progress nor a step, since the body last moved on, before giving up (a step
    made while stuck does not start the count again, :func:`stuck_count`: on the climbing
    wall the longer look-ahead kept after it found the holds its first walk missed, and
    rubble's first walk stops three cycles sooner where it stalls). idle_rounds : gait rounds (a
    cycle per walking limb) without the body getting further along the guide before giving
    up (steps that lead nowhere; the planner then retries along a new guide). loop_visits :
    how often the walk may reach the same contacts (every limb's within
    ``LOOP_CONTACT_TOLERANCE``) without getting further before giving up: a walk that went round
    a loop of steps twice stepped round it until its idle rounds ran out (the climbing
    wall's first walk, every seed: 2.9 s of its 3.6). jitter : m,
    scale of the random term added to the scores of contact candidates (``create_contact``'s
    ``randomness``); retries raise it. release_guard : no advance or step leaves a leg behind
    the body unable to be released when it could be before (the planner's retries after a
    walk stalled unable to release a leg behind; plans whose walks never strand are unchanged).
    backtracks : how often a walk that strands a leg goes back to its last state from which
    that leg can be released and walks on from there, that leg guarded until it has stepped
    (0: it walks on stranded until it stalls, and the planner walks again from the start
    with ``release_guard``).
    """

    spacing: float = 0.05
    lookahead: float | None = None
    advance: float | None = None
    min_step: float = 0.05
    goal_tolerance: float = 0.03
    max_states: int = 200
    max_stuck: int = 3
    idle_rounds: int = 6
    loop_visits: int = 3
    jitter: float = 0.05
    release_guard: bool = False
    backtracks: int = 4

    def __post_init__(self) -> None:
        if not 0 < self.spacing <= 0.5:
            raise ValueError("spacing must be in (0, 0.5] m")
        if self.lookahead is not None and not 0 < self.lookahead <= 2.0:
            raise ValueError("lookahead must be in (0, 2] m")
        if self.advance is not None and not 0 < self.advance <= 1.0:
            raise ValueError("advance must be in (0, 1] m")
        if not 0 < self.min_step <= 0.5:
            raise ValueError("min_step must be in (0, 0.5] m")
        if not 0 <= self.jitter <= 1.0:
            raise ValueError("jitter must be in [0, 1] m")
        if not 0 < self.idle_rounds <= 100:
            raise ValueError("idle_rounds must be in [1, 100]")
        if not 2 <= self.loop_visits <= 100:
            raise ValueError("loop_visits must be in [2, 100]")
        if not 0 < self.max_states <= 10_000:
            raise ValueError("max_states must be in [1, 10000]")
        if not 0 <= self.backtracks <= 20:
            raise ValueError("backtracks must be in [0, 20]")


def _effector_offsets(ctx: ContactContext) -> dict[str, FloatArray]:
    """Each limb's effector frame origin (3,) in the root frame at the reference posture (the
    point a contact's ``position`` is; ``reachability.reference_offsets`` gives the contact
    centre instead)."""
    q_ref = np.asarray(ctx.character.q_ref)
    root_inv = np.linalg.inv(frame_placement(ctx.model, q_ref, _ROOT_FRAME))
    out = {}
    for limb in ctx.character.limbs:
        placement = frame_placement(ctx.model, q_ref, limb.effector_frame)
        out[limb.name] = (root_inv @ placement)[:3, 3]
    return out


@dataclass(frozen=True, slots=True)
class GaitLengths:
    """Look-ahead and body advance per gait cycle (m) on open ground, off it (climb: a
    walker on its legs alone; rough: one using its hands too, or stuck)."""

    open_lookahead: float
    open_advance: float
    rough_lookahead: float
    rough_advance: float
    climb_lookahead: float | None = None
    climb_advance: float | None = None

    def of(
        self, open_ground: bool, stuck: bool = False, facing: bool = True
    ) -> tuple[float, float]:
        """(lookahead, advance) in m for the ground ahead; a stuck walker takes the rough
        lengths, and so does a climber not ``facing`` the way it goes."""
        if stuck:
            return self.rough_lookahead, self.rough_advance
        if open_ground:
            return self.open_lookahead, self.open_advance
        if facing and self.climb_lookahead is not None and self.climb_advance is not None:
            return self.climb_lookahead, self.climb_advance
        return self.rough_lookahead, self.rough_advance


def gait_lengths(
    offsets: dict[str, FloatArray],
    walking: Sequence[str],
    params: SequenceParams,
    legs_only: bool = True,
) -> GaitLengths:
    """The gait's lengths: the params' own where given (the same on any ground), else on open
    ground ``STRIDE_SHARE`` of the walking limbs' length (``offsets`` from
    :func:`_effector_offsets`, root frame) and ``ADVANCE_SHARE`` of that, and off it
    ``ROUGH_LOOKAHEAD`` and ``ROUGH_ADVANCE`` (never longer than on open ground). A walker
    with open-ground strides (``OPEN_GROUND_GAIN``) that walks on its legs alone
    (``legs_only``: no hand on a rail or a wall) climbs with ``CLIMB_SHARE`` of its legs'
    length and ``CLIMB_ADVANCE_SHARE`` of that off open ground."""
    lengths = [float(np.linalg.norm(offsets[name])) for name in walking if name in offsets]
    scale = float(np.mean(lengths)) if lengths else 1.0
    open_look = min(2.0, STRIDE_SHARE * scale)
    rough_look = min(ROUGH_LOOKAHEAD, open_look)
    climb_look: float | None = None
    if legs_only and open_look >= OPEN_GROUND_GAIN * rough_look:
        climb_look = min(open_look, CLIMB_SHARE * scale)
    if params.lookahead is not None:
        open_look = rough_look = params.lookahead
        climb_look = None
    open_adv = min(1.0, ADVANCE_SHARE * open_look)
    rough_adv = min(ROUGH_ADVANCE, open_adv)
    climb_adv = None if climb_look is None else min(1.0, CLIMB_ADVANCE_SHARE * climb_look)
    if params.advance is not None:
        open_adv = rough_adv = params.advance
        climb_look = climb_adv = None
    return GaitLengths(open_look, open_adv, rough_look, rough_adv, climb_look, climb_adv)


def _surface_points(ctx: ContactContext) -> FloatArray:
    """Every polygon vertex (n, 3) of the scene's surfaces (world frame, m; cached)."""

    def make() -> FloatArray:
        loops = [loop for surface in ctx.scene.surfaces for loop in surface.polygons]
        return np.concatenate(loops).reshape(-1, 3) if loops else np.zeros((0, 3))

    out: FloatArray = ctx.cached("surface_points", make)
    return out


def gait_order(offsets: dict[str, FloatArray], limbs: Sequence[str]) -> tuple[str, ...]:
    """``limbs`` in stepping order: left side (offset y > 0) back to front, then the right
    side back to front (a crawl for four legs, a wave for six, alternation for two)."""
    left = sorted((x for x in limbs if offsets[x][1] > 0.0), key=lambda x: offsets[x][0])
    right = sorted((x for x in limbs if offsets[x][1] <= 0.0), key=lambda x: offsets[x][0])
    return (*left, *right)


@dataclass(frozen=True, slots=True)
class _Guide:
    """The root path (n, 4, 4) with its cumulative arc lengths (n,) in metres."""

    poses: FloatArray
    lengths: FloatArray

    @staticmethod
    def of(poses: FloatArray) -> _Guide:
        steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
        return _Guide(poses, np.concatenate([[0.0], np.cumsum(steps)]))

    @property
    def length(self) -> float:
        return float(self.lengths[-1])

    def at(self, s: float) -> FloatArray:
        """The pose (4, 4) at arc length ``s`` (positions interpolated, rotation of the
        nearer sample)."""
        s = float(np.clip(s, 0.0, self.length))
        i = int(np.clip(np.searchsorted(self.lengths, s), 1, len(self.poses) - 1))
        span = self.lengths[i] - self.lengths[i - 1]
        w = 0.0 if span <= 1e-12 else (s - self.lengths[i - 1]) / span
        out = np.array(self.poses[i] if w >= 0.5 else self.poses[i - 1])
        out[:3, 3] = (1 - w) * self.poses[i - 1, :3, 3] + w * self.poses[i, :3, 3]
        return out

    def progress(self, position: FloatArray, near: float) -> float:
        """Arc length (m) of the path sample nearest to ``position`` (3,), searched from
        ``near - 0.3`` m on (the body never walks back along the guide). Heights count a
        third: a guide drawn straight up a staircase runs above the body on the treads."""
        start = int(np.searchsorted(self.lengths, near - 0.3))
        gaps = (self.poses[start:, :3, 3] - position) * _PROGRESS_WEIGHTS
        return float(self.lengths[start + int(np.argmin(np.linalg.norm(gaps, axis=1)))])

    def walked(self, states: Sequence[ContactState]) -> list[float]:
        """Arc length (m) of each of a walk's ``states`` along the guide, each searched from
        the one before's (:meth:`progress`)."""
        progress, s = [], 0.0
        for state in states:
            s = self.progress(np.asarray(state.q[:3]), s)
            progress.append(s)
        return progress

    def tangent(self, s: float) -> FloatArray:
        """Unit direction (3,) of the guide at arc length ``s`` (over the next 0.1 m)."""
        ahead = self.at(s + 0.1)[:3, 3] - self.at(s)[:3, 3]
        if float(np.linalg.norm(ahead)) < 1e-9:
            ahead = self.at(s)[:3, 3] - self.at(s - 0.1)[:3, 3]
        norm = float(np.linalg.norm(ahead))
        return ahead / norm if norm > 1e-9 else np.zeros(3)


def _steps_on(
    placed: FloatArray,
    old: LimbContact | None,
    target: FloatArray,
    before: float,
    tangent: FloatArray,
    reach: float,
    p: SequenceParams,
) -> bool:
    """Whether a contact put down at ``placed`` (3,) is a step: closer to its foothold
    ``target`` (3,) than ``before`` (m) by half a minimal step, or (the foothold itself being
    out of reach, as on a stair nosing) at least a minimal step further along the guide's
    ``tangent`` (3,) without passing the foothold by more than ``reach`` (m, the look-ahead
    in use)."""
    if float(np.linalg.norm(placed - target)) <= before - 0.5 * p.min_step:
        return True
    if old is None:
        return False
    forward = float(np.dot(placed - old.position, tangent))
    return forward >= p.min_step and float(np.dot(placed - target, tangent)) <= reach


def kinematic_slack(ctx: ContactContext, state: ContactState) -> float:
    """How deep (m) the COM of ``state`` is inside the kinematic polytope of its contacts
    (negative outside)."""
    return -float(kinematics_of(ctx, state.contacts).violation(com_of(ctx, state.q)))


def advance_body(
    ctx: ContactContext,
    state: ContactState,
    root_target: FloatArray,
    slack_floor: float = -np.inf,
) -> ContactState | None:
    """``state`` with the body moved toward the root pose ``root_target`` (4, 4) while every
    contact is held (whole-body IK, the root pose a soft target); None when the result leaves
    the COM less than ``slack_floor`` m deep in the kinematic polytope of its contacts
    (:func:`kinematic_slack`, tested first: a walk refuses such an advance whatever else
    holds) or is not a valid state (contacts held and on their surfaces, balanced,
    kinematic, collision-free). Remembered per state object, target and floor in ``ctx``
    (a walk stuck in place tries the same advances again, cycle after cycle): asked again,
    the same answer, at no work."""
    key = ("advance", np.asarray(root_target, dtype=np.float64).tobytes(), slack_floor)
    advanced: ContactState | None = ctx.per_state(
        state, key, lambda: _advance_body(ctx, state, root_target, slack_floor)
    )
    return advanced


def _advance_body(
    ctx: ContactContext, state: ContactState, root_target: FloatArray, slack_floor: float
) -> ContactState | None:
    """:func:`advance_body` computed."""
    tasks = [
        *hold_tasks(state.contacts, ctx),
        FramePlacementTask(_ROOT_FRAME, root_target, Priority.COM),
        posture_task(ctx),
    ]
    active = active_dofs(ctx, state.limbs)  # free limbs stay as they are
    result = solve_ik(
        ctx.model,
        state.q,
        tasks,
        data=ctx.pin_data,
        active=active,
        max_iterations=ctx.params.ik_iterations,
    )
    moved = ContactState(np.array(result.q), state.contacts)
    if kinematic_slack(ctx, moved) < slack_floor:
        return None
    return moved if check_state(ctx, moved).valid else None


def stuck_count(stuck: int, *, moved: bool, stepped: bool) -> int:
    """A walk's stuck count after a gait cycle: 0 once its body moved on along the guide,
    unchanged after a step alone (a stuck walker stays stuck, its look-ahead as long, until
    its body gets on), one more after a cycle with neither."""
    if moved:
        return 0
    return stuck if stepped else stuck + 1


def resume_index(states: Sequence[ContactState], poses: FloatArray, back_m: float) -> int:
    """Index into ``states`` (a walk along the guide ``poses`` (n, 4, 4)) of the state a retry
    resumes from: the last one at least ``back_m`` m of guide behind the walk's furthest
    progress that holds as many contacts as the first state (every leg down); 0 if none."""
    progress = _Guide.of(np.asarray(poses, dtype=np.float64)).walked(states)
    limit = max(progress) - back_m
    full = len(states[0].contacts)
    for k in range(len(states) - 1, 0, -1):
        if progress[k] <= limit and len(states[k].contacts) >= full:
            return k
    return 0


def contact_sequence(
    ctx: ContactContext,
    start: ContactState,
    poses: FloatArray,
    goal: ContactState | None,
    *,
    rng: np.random.Generator,
    until: Termination,
    params: SequenceParams | None = None,
    limbs: Sequence[str] = (),
    avoid: Sequence[tuple[str, FloatArray]] = (),
    resume: bool = False,
) -> PlanResult[tuple[ContactState, ...]]:
    """States from ``start`` along the guide ``poses`` (n, 4, 4) to ``goal``.

    The walking limbs are those in contact at the start or the goal, plus ``limbs`` (say a
    hand for a handrail); a walking limb the goal does not have is released at the end.

    SOLVED when the body has reached the end of the guide and every goal contact is made
    (within ``goal_tolerance``); APPROXIMATE with the states found so far when stuck
    (``stats["blocked"]`` 1 when stuck short of the guide's end, where no foothold up to the
    furthest lookahead could be stepped to); TIMEOUT (with the partial states) when
    ``until`` fires.

    Re-planning (``resume``): the start stands part-way along the guide, and the walk goes
    on from the guide sample nearest its root; no contact of a limb is made within
    ``AVOID_RADIUS`` of that limb's points in ``avoid`` ((limb, (3,) world point) each).
    """
    p = params or SequenceParams()
    guide = _Guide.of(np.asarray(poses, dtype=np.float64))
    avoided: dict[str, list[FloatArray]] = {}
    for limb_name, point in avoid:
        avoided.setdefault(limb_name, []).append(np.asarray(point, dtype=np.float64))
    offsets = _effector_offsets(ctx)
    walking = list(start.limbs)
    if goal is not None:
        walking += [x for x in goal.limbs if x not in walking]
    optional = [x for x in limbs if x not in walking]
    walking += optional
    order = gait_order(offsets, walking)
    legs = [x for x in walking if x not in optional]
    gait = gait_lengths(offsets, legs, p, legs_only=not optional)
    states: list[ContactState] = [start]
    current = start  # the body now: states[-1]'s contacts, its posture moved on by advances
    stats: dict[str, float | int | str] = {"breaks": 0, "creations": 0, "cycles": 0}
    s = guide.progress(np.asarray(start.q[:3]), 0.0) if resume else 0.0
    turn = 0  # index into ``order`` of the limb whose turn it is
    held_back: list[str] = []  # legs behind the body this cycle could not release
    guarded: str | None = None  # the leg a backtrack left guarded until it steps

    def result(status: PlanStatus, message: str = "") -> PlanResult[tuple[ContactState, ...]]:
        stats["states"] = len(states)
        stats["progress_m"] = round(s, 4)
        return PlanResult(status, tuple(states), dict(stats), message)

    def stalled(message: str) -> PlanResult[tuple[ContactState, ...]]:
        # a walk that gives up without reaching the goal, and whether it left a leg behind
        stats["stranded"] = int(stranded())
        return result(PlanStatus.APPROXIMATE, message)

    def finish() -> PlanResult[tuple[ContactState, ...]]:
        # release the contacts the goal does not have
        nonlocal current
        extra = [] if goal is None else [x for x in current.limbs if goal.contact(x) is None]
        for limb in extra:
            released = break_contact(ctx, current, limb)
            if not released.ok:
                return result(PlanStatus.APPROXIMATE, f"{limb}: cannot release for the goal")
            states.append(released.state)
            current = released.state
            stats["breaks"] = int(stats["breaks"]) + 1
        return result(PlanStatus.SOLVED)

    def footholds(at: float) -> dict[str, FloatArray | None]:
        # a limb's nominal position at the guide pose, moved to the nearest surface point
        # where it fits; an optional limb (a hand) with no surface near has none
        pose = guide.at(at)
        out: dict[str, FloatArray | None] = {}
        for limb in order:
            nominal = pose[:3, :3] @ offsets[limb] + pose[:3, 3]
            radius = _OPTIONAL_RADIUS if limb in optional else _FOOTHOLD_RADIUS
            found = nearest_foothold(ctx, limb, nominal, within=radius)
            out[limb] = found if found is not None or limb in optional else nominal
        if goal is not None and at >= guide.length - 1e-9:
            out.update({c.limb: c.position for c in goal.contacts})
        return out

    # m: horizontal reach of the legs around the root, plus a margin
    reach_radius = max(float(np.linalg.norm(offsets[x][:2])) for x in legs) + OPEN_GROUND_MARGIN

    def facing_the_way() -> bool:
        # the body's heading within CLIMB_MAX_HEADING of the guide's direction ahead
        ahead = guide.at(s + 2.0 * gait.open_lookahead)[:2, 3] - guide.at(s)[:2, 3]
        if float(np.linalg.norm(ahead)) < 1e-6:
            return True
        heading = frame_placement(ctx.model, current.q, _ROOT_FRAME)[:2, 0]
        cosine = float(ahead @ heading) / (
            float(np.linalg.norm(ahead)) * max(float(np.linalg.norm(heading)), 1e-9)
        )
        return cosine >= float(np.cos(CLIMB_MAX_HEADING))

    def open_ground() -> bool:
        # level open ground ahead: the guide stays level over two long look-aheads, no scene
        # surface off the ground's height lies within the legs' reach of it, and every leg
        # finds a foothold right under its nominal position there, at the height of the
        # contacts held now (no step, rock, gap or obstacle pushing a foot aside)
        return gait.open_lookahead >= OPEN_GROUND_GAIN * gait.rough_lookahead and level_ground()

    def level_ground() -> bool:
        # open_ground's ground, whatever the walker's strides
        heights = [float(c.position[2]) for c in current.contacts if c.limb in legs]
        if len(heights) != len(legs) or max(heights) - min(heights) > OPEN_GROUND_RISE:
            return False
        points = _surface_points(ctx)
        for ahead in (s, s + gait.open_lookahead, s + 2.0 * gait.open_lookahead):
            pose = guide.at(min(ahead, guide.length))
            near = np.linalg.norm(points[:, :2] - pose[:2, 3], axis=1) < reach_radius
            if np.any(np.abs(points[near, 2] - heights[0]) > OPEN_GROUND_RISE):
                return False  # a rock, a step, a wall or a hole within the legs' reach
            if abs(pose[2, 3] - guide.at(s)[2, 3]) > OPEN_GROUND_RISE:
                return False
            for limb in legs:
                nominal = pose[:3, :3] @ offsets[limb] + pose[:3, 3]
                found = nearest_foothold(ctx, limb, nominal, within=_FOOTHOLD_RADIUS)
                if (
                    found is None
                    or abs(float(found[2]) - heights[0]) > OPEN_GROUND_RISE
                    or float(np.linalg.norm(found[:2] - nominal[:2])) > OPEN_GROUND_RISE
                ):
                    return False
        return True

    def let_go(limb: str) -> bool:
        # an optional limb whose support has run out (the end of a handrail) is released
        nonlocal current
        released = break_contact(ctx, current, limb)
        if not released.ok:
            return False
        states.append(released.state)
        current = released.state
        stats["breaks"] = int(stats["breaks"]) + 1
        return True

    def _followable(state: ContactState, moved: str) -> bool:
        # whether a leg other than ``moved`` (just put down) can still be released from
        # ``state``: a biped whose front foot stepped where the rear one cannot follow (the
        # COM cannot be shifted off it) has only the front limbs left to move, and walks
        # them back and forth in ever wider straddles the whole body cannot play. A walker
        # with more legs is not asked (``FOLLOW_TRIAL_LEGS``)
        if len(legs) > FOLLOW_TRIAL_LEGS:
            return True
        others = [c.limb for c in state.contacts if c.limb != moved and c.limb in legs]
        return not others or any(break_contact(ctx, state, x).ok for x in others)

    def legs_behind(state: ContactState) -> list[str]:
        # the legs ``state`` holds down behind its root along the guide (in contact order)
        root, ahead = np.asarray(state.q[:3]), guide.tangent(s)
        return [
            c.limb for c in state.contacts if c.limb in legs and (c.position - root) @ ahead < 0
        ]

    def stranding(before: ContactState, after: ContactState, moved: str | None = None) -> bool:
        # with ``release_guard`` (else for the ``guarded`` leg alone, after a backtrack):
        # whether a leg behind the root along the guide (an advance takes the body further
        # from it), other than ``moved``, that ``before`` can release cannot be released
        # from ``after``
        if not p.release_guard and guarded is None:
            return False
        behind = [
            x for x in legs_behind(before) if x != moved and (p.release_guard or x == guarded)
        ]
        return any(
            break_contact(ctx, before, x).ok and not break_contact(ctx, after, x).ok for x in behind
        )

    def stranded() -> bool:
        # a stalled walk whose body cannot release a leg it left behind (the
        # ``release_guard``'s case: the planner retries with it)
        return any(not break_contact(ctx, current, x).ok for x in legs_behind(current))

    def step(limb: str, target: FloatArray, reposition: bool = False) -> bool:
        nonlocal current, guarded
        old = current.contact(limb)
        base = current
        if old is not None:
            released = break_contact(ctx, current, limb)
            if not released.ok:
                if limb in legs_behind(current):
                    held_back.append(limb)
                return False
            base = released.state
            before = float(np.linalg.norm(old.position - target))
        else:
            before = np.inf
        for fraction in _STEP_FRACTIONS:
            aim = target if old is None else old.position + fraction * (target - old.position)
            made = create_contact(
                ctx,
                base,
                limb,
                rng=rng,
                target=aim,
                randomness=p.jitter,
                avoid=avoided.get(limb, ()),
            )
            if not made.ok:
                continue
            placed = made.state.contact(limb)
            assert placed is not None
            if reposition:
                assert old is not None
                if float(np.linalg.norm(placed.position - old.position)) < 0.02:
                    continue  # put back where it was: nothing gained
            elif not _steps_on(placed.position, old, target, before, guide.tangent(s), reach, p):
                continue
            if not reposition and limb in legs and not _followable(made.state, limb):
                continue
            if stranding(current, made.state, limb):
                continue  # a leg behind would be left where it cannot be released
            if base is not current:
                states.append(base)
                stats["breaks"] = int(stats["breaks"]) + 1
            states.append(made.state)
            current = made.state
            stats["creations"] = int(stats["creations"]) + 1
            if limb == guarded:
                guarded = None  # the stranded leg has stepped
            return True
        return False

    stuck = 0
    stranded_for = 0  # cycles in a row the body stayed and a leg behind it stayed down
    backtracks = 0
    reach = gait.rough_lookahead  # m ahead where footholds are taken; grows while stuck
    furthest, idle = s, 0  # the furthest the body got, and cycles since
    # the states the walk has stepped to since it last got further
    visited: list[ContactState] = []
    while True:
        if until():
            return result(PlanStatus.TIMEOUT, "budget spent while walking the path")
        if len(states) >= p.max_states:
            return result(PlanStatus.APPROXIMATE, f"stopped at {p.max_states} states")
        stats["cycles"] = int(stats["cycles"]) + 1
        # long strides on open ground; a walker that is stuck goes back to short ones
        opened = stuck == 0 and open_ground()
        facing = gait.climb_lookahead is None or facing_the_way()
        lookahead, advance = gait.of(opened, stuck > 0, facing)
        stats["open_cycles"] = int(stats.get("open_cycles", 0)) + int(opened)
        # 1. advance the body along the guide
        moved = False
        held_back.clear()  # the legs behind the body this cycle finds it cannot release
        if s < guide.length - 1e-9:
            slack = kinematic_slack(ctx, current)
            level: bool | None = None  # whether the ground is level here, asked once
            for fraction, rise, over_body in _ADVANCE_TRIES:
                if rise > 0.0:
                    level = level_ground() if level is None else level
                    if level:
                        break  # a taller body clears a rock; there is none in reach
                target_s = min(s + fraction * advance, guide.length)
                target = guide.at(target_s)
                if over_body:
                    target[2, 3] = max(target[2, 3], float(current.q[2]))
                target[2, 3] += rise
                # refused when a leg would be left at the end of its range
                advanced = advance_body(ctx, current, target, min(slack, _ADVANCE_SLACK))
                if advanced is None:
                    continue
                if stranding(current, advanced):
                    continue  # a leg behind would be left where it cannot be released
                new_s = guide.progress(advanced.q[:3], s)
                if new_s > s + 1e-3:
                    current = advanced  # same contacts: the body moves within the phase
                    s = new_s
                    moved = True
                break
        # 2. step the limb furthest from its foothold
        # at the end of the guide (or stuck where the footholds ahead are the guide's last):
        # the goal's contacts are the footholds
        at_end = s >= guide.length - p.spacing or (
            stuck > 0 and s + lookahead * (1 + stuck) >= guide.length
        )
        # a stuck walker looks further ahead for footholds (a gap between stepping stones)
        reach = lookahead * (1 + stuck)
        wanted = footholds(guide.length if at_end else s + reach)
        gaps = {}
        for limb in order:
            c, aim = current.contact(limb), wanted[limb]
            if aim is None:  # nothing to hold near here: no step; let go if holding
                gaps[limb] = np.inf if c is not None else 0.0
                continue
            gaps[limb] = np.inf if c is None else float(np.linalg.norm(c.position - aim))
        tol = p.goal_tolerance if at_end else p.min_step
        needed = goal.limbs if goal is not None else [x for x in order if x not in optional]
        if at_end and all(gaps[x] <= p.goal_tolerance for x in needed):
            return finish()
        rotation = order[turn:] + order[:turn]
        candidates = [x for x in rotation if gaps[x] > tol]
        stepped = False
        for limb in candidates:
            aim = wanted[limb]
            if aim is None:
                if let_go(limb):
                    stepped = True
                    break
                continue
            if step(limb, aim):
                turn = (order.index(limb) + 1) % len(order)
                stepped = True
                break
        if not stepped and not moved:
            # reposition: a limb on its foothold may still block the body (a shin against a
            # rock after the body moved); put each down again somewhere near its foothold
            for limb in rotation:
                aim = wanted[limb]
                if (
                    limb not in candidates
                    and aim is not None
                    and current.contact(limb) is not None
                    and step(limb, aim, reposition=True)
                ):
                    turn = (order.index(limb) + 1) % len(order)
                    stepped = True
                    stats["repositions"] = int(stats.get("repositions", 0)) + 1
                    break
        if s > furthest + 1e-3:
            furthest, idle = s, 0
            visited.clear()
        else:
            idle += 1
        if idle > p.idle_rounds * len(order):
            return stalled(
                f"no progress in {p.idle_rounds} gait rounds at {s:.2f} m of {guide.length:.2f} m"
            )
        if stepped and idle:
            visited.append(current)
            if sum(_same_contacts(current, seen) for seen in visited) >= p.loop_visits:
                stats["loops"] = 1
                return stalled(
                    f"no progress at {s:.2f} m of {guide.length:.2f} m: the walk came back to "
                    f"the same contacts {p.loop_visits} times"
                )
        stranded_for = stranded_for + 1 if held_back and not moved else 0
        if stranded_for >= STRANDED_CYCLES and backtracks < p.backtracks and not p.release_guard:
            # stranded: walk on from the last state that can release the leg, guarding it
            leg = held_back[0]
            k = release_point(ctx, states, leg, 2 * STRAND_LOOKBACK * len(order))
            if k is not None:
                backtracks += 1
                stats["backtracks"] = backtracks
                del states[k + 1 :]
                current, guarded, turn = states[k], leg, order.index(leg)
                s = guide.walked(states)[-1]
                stranded_for = idle = stuck = 0
                visited.clear()
                continue
        stuck = stuck_count(stuck, moved=moved, stepped=stepped)
        if moved or stepped:
            continue
        if stuck > p.max_stuck:
            # stuck short of the guide's end: no foothold up to the furthest lookahead could
            # be stepped to from here (``stats["blocked"]``)
            stats["blocked"] = int(not at_end)
            far = ", ".join(f"{x} {gaps[x]:.2f} m" for x in candidates) or "none"
            return stalled(
                f"stuck at {s:.2f} m of {guide.length:.2f} m; limbs off their footholds: {far}"
            )
