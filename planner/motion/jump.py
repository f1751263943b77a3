"""The motion of a sequence of ballistic jumps as a :class:`MotionSpec`, animated by the one
builder.

Per jump, four phases: a rest-to-rest shift on the takeoff contacts into the crouch the
push starts from; the takeoff push, in which the COM accelerates at a constant rate from
rest to the takeoff velocity ``v0`` (a quadratic Bezier); the flight, in which the COM
follows the parabola ``c0 + v0 t + g t^2 / 2`` exactly (a quadratic Bezier is that
parabola) and every limb that lands or took off is carried from its takeoff pose to its
landing pose; the landing, in which the COM decelerates at a constant rate from the impact
velocity to rest. The landing contacts are made where the legs, their joints at their speed
limits, move the COM as fast as it falls, or as nearly as the reach allows: on the parabola
at or below the landing node, the legs drawn up in flight (``_touchdown``); a stance with
nearly straight knees moves it at a fraction of a fast landing's speed. A
last shift stands the body up on the last landing's contacts. The COM velocity is continuous
everywhere; its acceleration is ``JUMP_ACCELERATION``, more when the legs' reach demands a
shorter push: the crouch the push starts from and the point the landing stops at are never
further from the takeoff COM or the landing node's COM than the stance reaches (a
short-legged body pushes and lands harder, it does not crouch below its feet). The contact
force it needs, m (c'' - g), is checked against the node's centroidal cone (the
push or landing is lengthened within reach or shortened until it passes, or the timing says
it does not; likewise when even the shortest push travels beyond reach). The shift before
each push is lengthened so that the push and the landing each hold a keyframe, and the
motion lasts a whole number of keyframe periods. Every stance phase of a jump holds its
contacts rigidly (equality constraints of the tracker's QP, finer control steps): the tracked
COM lags its curve where the joint speed limits cannot follow it, the feet never slide. The
push and the landing lead the joints along the whole-body IK's crouch (``_crouched``: the
stance with its COM where the curve puts it) as the COM goes (``MotionPhase.posture_from``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.optimize import linprog

import trajectory
from planner.character import Character
from planner.kinematics import (
    ComTask,
    FrameAxisTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    Priority,
    Task,
    borrowed_data,
    com_position,
    frame_placement,
    frame_placements,
    has_free_flyer_root,
    solve_ik,
)
from planner.motion import tuning
from planner.motion.builder import BuiltMotion, build_motion
from planner.motion.sequence import rest_to_rest
from planner.motion.spec import FlightLimb, MotionPhase, MotionSpec, natural_posture
from planner.motion.tracker import speed_limits
from planner.termination import Termination, never

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class JumpLeg:
    """One jump between two stances, as the builder needs it (world frame, SI units).

    com0 : (3,) m, the COM when the contacts break (the takeoff stance's COM). v0 : (3,)
    m/s takeoff velocity. duration : s of flight. g : gravity magnitude (m/s^2).
    takeoff_axis / landing_axis : (3,) unit axes of the two nodes' centroidal cones (zeros:
    unchecked), takeoff_mu / landing_mu their friction coefficients. vimp_max : m/s, the
    fastest the COM may move at touchdown (the roadmap's bound): a touchdown delayed on the
    parabola (``_touchdown``) never lands faster.
    """

    com0: FloatArray
    v0: FloatArray
    duration: float
    g: float
    takeoff_axis: FloatArray
    takeoff_mu: float
    landing_axis: FloatArray
    landing_mu: float
    vimp_max: float = math.inf

    @property
    def gravity(self) -> FloatArray:
        """(3,) m/s^2."""
        return np.array([0.0, 0.0, -self.g])

    @property
    def com1(self) -> FloatArray:
        """(3,) m, the COM at touchdown."""
        t = self.duration
        return np.asarray(self.com0 + self.v0 * t + 0.5 * self.gravity * t * t, dtype=np.float64)

    @property
    def vimp(self) -> FloatArray:
        """(3,) m/s, the COM velocity at touchdown."""
        return np.asarray(self.v0 + self.gravity * self.duration, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class JumpTiming:
    """When one jump's phases start (s from the motion's start) and how its stances came
    out. crouch : the shift into the push's crouch begins; push : the COM leaves rest;
    takeoff : the contacts break; apex : the COM is highest (clamped to the flight);
    touchdown : the landing contacts are made; rest : the COM is at rest again.
    push_acceleration / landing_acceleration : (3,) m/s^2, the COM's constant acceleration
    in each; push_in_cone / landing_in_cone : the contact force m (c'' - g) lies in the node's
    centroidal cone; push_in_reach / landing_in_reach : the COM's travel in each stays within
    the stance's reach (``_reach``). touchdown_com / touchdown_velocity : (3,) m, m/s, the
    COM when the landing contacts are made, on the jump's parabola (``_touchdown``: at or
    after the leg's ``com1``)."""

    crouch: float
    push: float
    takeoff: float
    apex: float
    touchdown: float
    rest: float
    push_acceleration: FloatArray
    landing_acceleration: FloatArray
    push_in_cone: bool
    landing_in_cone: bool
    push_in_reach: bool
    landing_in_reach: bool
    touchdown_com: FloatArray
    touchdown_velocity: FloatArray


def in_cone(force: FloatArray, axis: FloatArray, mu: float) -> bool:
    """Whether ``force`` (3,) lies in the cone of unit ``axis`` (3,) and half-angle atan(mu)
    (a zero axis: no cone to check, True)."""
    if float(np.linalg.norm(axis)) < 1e-12:
        return True
    norm = float(np.linalg.norm(force))
    return norm > 0.0 and float(force @ axis) >= norm * math.cos(math.atan(mu)) - 1e-9


@dataclass(frozen=True, slots=True)
class StanceTiming:
    """A takeoff push or a landing at constant acceleration: its duration (s), whether its
    contact force lies in the cone (``in_cone``) and whether its COM travel, |v| duration / 2,
    stays within the stance's reach (``in_reach``)."""

    duration: float
    in_cone: bool
    in_reach: bool


def stance_duration(
    velocity: FloatArray,
    gravity: FloatArray,
    axis: FloatArray,
    mu: float,
    reach: float,
    *,
    landing: bool,
) -> StanceTiming:
    """A takeoff push reaching ``velocity`` (3,) m/s from rest (or, with ``landing``, a
    landing stopping it) at constant acceleration, its contact force c'' - g (per kg) checked
    against the cone (``axis`` (3,), ``mu``).

    The COM travels |v| T / 2 in a stance of T s, which the legs' ``reach`` (m) bounds: T <=
    2 reach / |v|. Nominally the push accelerates at ``JUMP_ACCELERATION``, shortened (pushing
    harder) until its travel is within reach. When the cone refuses it, longer durations up to
    that bound (and ``JUMP_MAX_STANCE_S``), then shorter ones down to ``JUMP_MIN_STANCE_S``,
    are tried; when none passes, the nominal one is kept and ``in_cone`` says so. A reach so
    short that even ``JUMP_MIN_STANCE_S`` travels beyond it gives that shortest stance, with
    ``in_reach`` False: the velocity cannot be reached (or stopped) within the legs' reach."""
    speed = float(np.linalg.norm(velocity))
    longest = tuning.JUMP_MAX_STANCE_S
    if speed > 0.0:
        longest = min(longest, 2.0 * reach / speed)
    longest = max(longest, tuning.JUMP_MIN_STANCE_S)
    nominal = min(max(speed / tuning.JUMP_ACCELERATION, tuning.JUMP_MIN_STANCE_S), longest)
    in_reach = 0.5 * speed * nominal <= reach + 1e-9
    sign = -1.0 if landing else 1.0
    longer = np.linspace(nominal, longest, 12)
    shorter = np.linspace(nominal, tuning.JUMP_MIN_STANCE_S, 6)[1:]
    for duration in (*longer, *shorter):
        force = sign * velocity / duration - gravity
        if in_cone(force, axis, mu):
            return StanceTiming(float(duration), True, in_reach)
    return StanceTiming(nominal, False, in_reach)


def _reach(state: ContactState, com: FloatArray) -> float:
    """m the COM may travel in a push or landing on ``state``: ``JUMP_CROUCH_SHARE`` of its
    height ``com`` (3,) above the mean contact point."""
    if not state.contacts:
        return 0.0
    floor = float(np.mean([c.points[:, 2].mean() for c in state.contacts]))
    return tuning.JUMP_CROUCH_SHARE * max(float(com[2]) - floor, 0.0)


def _crouched(
    character: Character, state: ContactState, point: FloatArray
) -> tuple[FloatArray, bool]:
    """The configuration (nq,) of ``state`` with its COM moved to ``point`` (3,) m, its
    contacts held and its joints within their limits (whole-body IK from ``state.q``, pulled
    toward it), and whether the COM got there (within 1 mm); when not, the nearest the IK
    found. A push's crouch and a landing's end are aimed at it: pulled toward the standing
    posture, the tracker met a joint limit (an ankle's dorsiflexion, the torso's pitch) and
    held the humanoid's COM 40 mm off a point the legs reach with the torso bent. The trunk
    (a free-flyer root) keeps the tilt of ``state.q`` (its up axis, yaw free:
    ``JUMP_CROUCH_TRUNK_WEIGHT``): the legs fold at the hips as the knees bend and the chest
    leans forward over the feet; without it, the IK lowered the COM with the hips' angles
    kept and the pelvis pitched backward by up to 42 degrees, the tracked landing squat
    leaning back with it."""
    model = character.model
    if not state.contacts:
        return np.array(state.q, dtype=np.float64), False
    holds: list[Task] = []
    for c in state.contacts:
        limb = character.limb(c.limb)
        if limb.contact == "point":
            target = c.placement[:3, 3]
            holds.append(FramePositionTask(limb.frame_id, target, np.zeros(3), Priority.CONTACT))
        else:
            holds.append(FramePlacementTask(limb.frame_id, c.placement, Priority.CONTACT))
    free_root = has_free_flyer_root(model)
    weights = np.ones(model.nv)
    if free_root:
        weights[:6] = 0.0  # the root's tangent dofs: the trunk tasks decide them
    trunk: list[Task] = []
    if free_root:
        frames = [_ROOT_FRAME, *_chest_frames(character)]
        placed = frame_placements(model, state.q, frames)
        trunk = [
            FrameAxisTask(f, pose[:3, 2], weight=tuning.JUMP_CROUCH_TRUNK_WEIGHT)
            for f, pose in zip(frames, placed, strict=True)
        ]
    tasks: list[Task] = [*holds, ComTask(point), *trunk]
    result = solve_ik(
        model,
        state.q,
        [*tasks, PostureTask(state.q, weights, gain=0.3)],
        max_iterations=tuning.JUMP_CROUCH_IK_ITERATIONS,
        tolerance=1e-3,
    )
    # reached: the contacts held and the COM there (the trunk's tilt is a preference)
    held = result.residuals[: len(holds) + 1]
    reached = bool(np.all(held[:, 0] <= 1e-3) and np.all(held[:, 1] <= 1e-3))
    return np.array(result.q, dtype=np.float64), reached


def _touchdown(
    character: Character, state: ContactState, com: FloatArray, leg: JumpLeg, reach: float
) -> tuple[float, FloatArray]:
    """How much later (s) than the leg's ``duration`` the landing contacts are made, and the
    configuration (nq,) of ``state`` (whose COM is ``com`` (3,)) they are made in.

    The landing starts at the touchdown velocity, which the legs must give the COM at once
    with their joints within ``speed_limits``: a stance with nearly straight knees moves its
    COM down at 1.5 to 2 m/s at 10 rad/s (the humanoid, knees at 0.3 to 0.5 rad), while a
    jump lands at up to 4.6 m/s, so the tracked COM lagged its curve by 50 to 90 mm. The
    contacts are made instead further down the parabola, the legs drawn up in flight (the
    stance crouched by ``_crouched`` as the COM is there): the first of the times
    k ``JUMP_TOUCHDOWN_STEP_S`` whose crouch moves its COM along the touchdown velocity at
    least that fast (``com_speed``), its travel below ``com1`` within
    ``JUMP_TOUCHDOWN_SHARE`` of the landing's ``reach`` (m) and the touchdown speed within
    ``leg.vimp_max``; else the one whose crouch comes nearest (0: the stance itself)."""
    best = (0.0, np.asarray(state.q, dtype=np.float64))
    if not state.contacts:
        return best
    limits = speed_limits(character.model, root_bounded=False)
    best_ratio = -math.inf
    g = leg.gravity
    for k in range(tuning.JUMP_TOUCHDOWN_STEPS + 1):
        late = k * tuning.JUMP_TOUCHDOWN_STEP_S
        t = leg.duration + late
        velocity = leg.v0 + g * t
        point = leg.com0 + leg.v0 * t + 0.5 * g * t * t
        travel = float(np.linalg.norm(point - leg.com1))
        speed = float(np.linalg.norm(velocity))
        if k and (travel > tuning.JUMP_TOUCHDOWN_SHARE * reach or speed > leg.vimp_max):
            break
        q = np.asarray(state.q, dtype=np.float64)
        if k:
            q, _ = _crouched(character, state, com + point - leg.com1)
        ratio = com_speed(character, q, state, velocity, limits) / max(speed, 1e-9)
        if ratio > best_ratio:
            best, best_ratio = (late, q), ratio
        if ratio >= 1.0:
            return late, q
    return best


def com_speed(
    character: Character,
    q: FloatArray,
    state: ContactState,
    direction: FloatArray,
    limits: FloatArray,
) -> float:
    """m/s, the fastest the COM of ``q`` (nq,) moves along ``direction`` (3,) with the
    contacts of ``state`` held (their Jacobians' rows null: position for a point, placement
    for a patch) and each joint within ``limits`` (nv,) rad/s (the root free): a linear
    program over the joint velocities."""
    model = character.model
    unit = np.asarray(direction, dtype=np.float64) / max(float(np.linalg.norm(direction)), 1e-12)
    rows = []
    with borrowed_data(model) as data:
        jcom = np.array(pin.jacobianCenterOfMass(model, data, np.asarray(q, dtype=np.float64)))
        pin.updateFramePlacements(model, data)
        for c in state.contacts:
            limb = character.limb(c.limb)
            jac = pin.getFrameJacobian(model, data, limb.frame_id, pin.LOCAL)
            rows.append(jac[:3] if limb.contact == "point" else jac)
    nv = model.nv
    # variables (qdot (nv,), s): max s with J_com qdot = s unit, J_c qdot = 0
    a_eq = np.zeros((3 + sum(len(r) for r in rows), nv + 1))
    a_eq[:3, :nv] = jcom
    a_eq[:3, nv] = -unit
    a_eq[3:, :nv] = np.vstack(rows)
    bounds = [(-x, x) if math.isfinite(x) else (None, None) for x in limits]
    cost = np.zeros(nv + 1)
    cost[nv] = -1.0
    result = linprog(
        cost, A_eq=a_eq, b_eq=np.zeros(len(a_eq)), bounds=[*bounds, (0.0, None)], method="highs"
    )
    return float(result.x[nv]) if result.success else 0.0


_ROOT_FRAME = 1
"""The frame of the root joint (pinocchio's frame 0 is the universe)."""


def _chest_frames(character: Character) -> tuple[int, ...]:
    """The frame (a 1-tuple) of the chest, or none: the deepest joint, in no limb and not the root,
    that carries a limb (a humanoid's torso joint that holds the shoulders; a body whose
    limbs all hang from the root has none)."""
    model = character.model
    in_limbs = {int(j) for limb in character.limbs for j in limb.joint_ids}
    carriers = {int(model.parents[int(limb.joint_ids[0])]) for limb in character.limbs}
    chest = [j for j in carriers if j > 1 and j not in in_limbs]
    if not chest:
        return ()
    deepest = max(chest, key=lambda j: len(model.supports[j]))
    return (int(model.getFrameId(model.names[deepest], pin.FrameType.JOINT)),)


def _quadratic(p0: FloatArray, p1: FloatArray, p2: FloatArray, t0: float, t1: float) -> Any:
    return trajectory.BezierCurve(np.array([p0, p1, p2], dtype=np.float64), t0, t1)


def _shift(a: FloatArray, b: FloatArray, t0: float, min_s: float) -> Any:
    """Rest-to-rest quintic from ``a`` to ``b`` (3,) starting at ``t0``."""
    curve, times = rest_to_rest(
        np.stack([a, b]), min_durations=[min_s], max_acceleration=tuning.JUMP_SHIFT_ACCELERATION
    )
    control = curve.segments[0].control_points
    return trajectory.BezierCurve(control, t0, t0 + float(times[-1]))


def _keyed_start(earliest: float, windows: Sequence[tuple[float, float]], period: float) -> float:
    """A time p in [``earliest``, ``earliest`` + ``period``) (s) at which a phase sequence may
    start so that each of ``windows`` ((offset from p, duration) s) holds a keyframe of the
    grid k ``period``, as near its middle as can be (a velocity changing within a keyframe
    period is then seen half before and half after it); when no p gives every window one, as
    many of the first ones as can be (a push or landing shorter than a keyframe period then
    still shows in a keyframe)."""
    candidates = earliest + period * np.arange(_KEY_CANDIDATES) / _KEY_CANDIDATES
    for count in range(len(windows), 0, -1):
        scores = [
            max(_off_middle(p + offset, length, period) for offset, length in windows[:count])
            for p in candidates
        ]
        best = int(np.argmin(scores))
        if math.isfinite(scores[best]):
            return float(candidates[best])
    return earliest


def _off_middle(t0: float, length: float, period: float) -> float:
    """How far (a share of ``length``) the grid time k ``period`` nearest the middle of
    [t0, t0 + length] (s) lies from that middle; inf when none lies ``_KEY_MARGIN_S`` (or a
    quarter of ``length``) inside it."""
    margin = min(_KEY_MARGIN_S, 0.25 * length)
    middle = t0 + 0.5 * length
    nearest = round(middle / period) * period
    if not t0 + margin <= nearest <= t0 + length - margin:
        return math.inf
    return abs(nearest - middle) / length


_KEY_MARGIN_S = 1e-3
"""s: a keyframe that shows a push or landing lies at least this far inside it."""

_KEY_CANDIDATES = 64
"""Start times tried per keyframe period by ``_keyed_start``."""


def _aimed(
    posture: FloatArray, stance_q: FloatArray, com: FloatArray, stance_com: FloatArray
) -> FloatArray:
    """``posture`` (nq,) with its root where the root of ``stance_q`` would be with the COM
    at ``com`` instead of ``stance_com`` (3,): the trunk height aimed at a phase's start."""
    out = np.array(posture, dtype=np.float64)
    out[:3] = np.asarray(stance_q[:3]) + com - stance_com
    return out


def _flight_limbs(
    character: Character, before: ContactState, after: ContactState
) -> tuple[FlightLimb, ...]:
    """Limbs in contact at takeoff or landing, carried from their pose in ``before`` to
    their pose in ``after``; tucked toward their natural-posture offset from the COM,
    raised by ``FLIGHT_TUCK_LIFT``."""
    model = character.model
    natural = np.array(character.q_ref, dtype=np.float64)
    natural[:7] = after.q[:7]
    com_natural = com_position(model, natural)
    names = list(dict.fromkeys([*before.limbs, *after.limbs]))
    out = []
    for name in names:
        frame = character.limb(name).effector_frame
        start_contact, end_contact = before.contact(name), after.contact(name)
        start = (
            np.asarray(start_contact.placement)
            if start_contact is not None
            else frame_placement(model, before.q, frame)
        )
        end = (
            np.asarray(end_contact.placement)
            if end_contact is not None
            else frame_placement(model, after.q, frame)
        )
        tuck = frame_placement(model, natural, frame)[:3, 3] - com_natural
        tuck[2] += tuning.FLIGHT_TUCK_LIFT
        out.append(FlightLimb(name, start, end, tuck))
    return tuple(out)


def jump_spec(
    character: Character,
    stances: Sequence[ContactState],
    legs: Sequence[JumpLeg],
    *,
    rate: float = 30.0,
) -> tuple[MotionSpec, tuple[JumpTiming, ...]]:
    """The phases and COM curve of ``legs`` (k >= 0 jumps) between ``stances`` (k + 1
    whole-body contact states, the nodes), and each jump's timing. The motion starts at
    rest in ``stances[0].q`` and ends at rest with the COM of ``stances[-1].q`` (without a
    jump, it stands still for ``JUMP_MIN_SHIFT_S``)."""
    if len(stances) != len(legs) + 1:
        raise ValueError("need k + 1 stances for k jumps")
    model = character.model
    coms = [com_position(model, np.asarray(s.q)) for s in stances]
    segments: list[Any] = []
    phases: list[MotionPhase] = []
    timings: list[JumpTiming] = []
    t = 0.0
    here = coms[0]
    for i, leg in enumerate(legs):
        before, after = stances[i], stances[i + 1]
        g = leg.gravity
        push = stance_duration(
            leg.v0, g, leg.takeoff_axis, leg.takeoff_mu, _reach(before, coms[i]), landing=False
        )
        reach = _reach(after, coms[i + 1])
        late, td_q = _touchdown(character, after, coms[i + 1], leg, reach)
        big_t = leg.duration + late
        vimp = leg.v0 + g * big_t
        com1 = leg.com0 + leg.v0 * big_t + 0.5 * g * big_t * big_t
        land_reach = reach - float(np.linalg.norm(com1 - leg.com1))
        land = stance_duration(
            vimp,
            g,
            leg.landing_axis,
            leg.landing_mu,
            max(land_reach, 0.0),
            landing=True,
        )
        push_s, land_s = push.duration, land.duration
        crouch = leg.com0 - 0.5 * push_s * leg.v0
        rest = com1 + 0.5 * land_s * vimp
        # the postures the crouch and the landing's end aim at: the stances with their COM
        # moved as the curve moves it (from each stance's own COM, which the curve's ends
        # are within millimetres of)
        crouch_q, _ = _crouched(character, before, coms[i] + crouch - leg.com0)
        landed_q, _ = _crouched(character, after, coms[i + 1] + rest - leg.com1)
        # shift into the crouch, on the takeoff contacts, lengthened so that the push and
        # the landing each hold a keyframe (they may be shorter than a keyframe period)
        natural = _shift(here, crouch, t, tuning.JUMP_MIN_SHIFT_S).t1
        start = _keyed_start(natural, ((0.0, push_s), (push_s + big_t, land_s)), 1.0 / rate)
        shift = _shift(here, crouch, t, max(start - t, tuning.JUMP_MIN_SHIFT_S))
        segments.append(shift)
        posture = _aimed(crouch_q, crouch_q, here, com_position(model, crouch_q))
        phases.append(
            MotionPhase(
                t,
                shift.t1,
                before.contacts,
                posture,
                level_trunk=False,
                fast_com=True,
                rigid_stance=True,
            )
        )
        t_crouch, t = t, shift.t1
        # the push: from rest to v0 at constant acceleration
        segments.append(_quadratic(crouch, crouch, leg.com0, t, t + push_s))
        posture = _aimed(np.asarray(before.q), before.q, crouch, coms[i])
        phases.append(
            MotionPhase(
                t,
                t + push_s,
                before.contacts,
                posture,
                level_trunk=False,
                fast_com=True,
                rigid_stance=True,
                posture_from=_aimed(crouch_q, crouch_q, crouch, com_position(model, crouch_q)),
            )
        )
        t_push, t = t, t + push_s
        # the flight: the parabola itself
        segments.append(_quadratic(leg.com0, leg.com0 + 0.5 * big_t * leg.v0, com1, t, t + big_t))
        flight_posture = natural_posture(character, np.asarray(after.q), after.limbs)
        flight_posture = _aimed(flight_posture, before.q, leg.com0, coms[i])
        phases.append(
            MotionPhase(
                t,
                t + big_t,
                (),
                flight_posture,
                level_trunk=False,
                flight=_flight_limbs(character, before, after),
                turn_from=np.asarray(before.q[3:7], dtype=np.float64),
            )
        )
        t_takeoff, t = t, t + big_t
        apex = t_takeoff + min(max(float(leg.v0[2]) / leg.g, 0.0), big_t)
        # the landing: from the impact velocity to rest at constant deceleration
        segments.append(_quadratic(com1, rest, rest, t, t + land_s))
        posture = _aimed(landed_q, landed_q, com1, com_position(model, landed_q))
        phases.append(
            MotionPhase(
                t,
                t + land_s,
                after.contacts,
                posture,
                level_trunk=False,
                fast_com=True,
                rigid_stance=True,
                posture_from=_aimed(td_q, td_q, com1, com_position(model, td_q)),
            )
        )
        t_touchdown, t = t, t + land_s
        timings.append(
            JumpTiming(
                t_crouch,
                t_push,
                t_takeoff,
                apex,
                t_touchdown,
                t,
                np.asarray(leg.v0 / push_s, dtype=np.float64),
                np.asarray(-vimp / land_s, dtype=np.float64),
                push.in_cone,
                land.in_cone,
                push.in_reach,
                land.in_reach,
                np.asarray(com1, dtype=np.float64),
                np.asarray(vimp, dtype=np.float64),
            )
        )
        here = rest
    # stand up on the last landing's contacts, until a whole number of keyframe periods
    # (the keyframe grid is then k / rate, the one the pushes and landings were keyed on)
    last = stances[-1]
    natural = _shift(here, coms[-1], t, tuning.JUMP_MIN_SHIFT_S).t1
    end = math.ceil(natural * rate - 1e-9) / rate
    shift = _shift(here, coms[-1], t, end - t)
    segments.append(shift)
    posture = _aimed(np.asarray(last.q), last.q, here, coms[-1])
    phases.append(
        MotionPhase(
            t, shift.t1, last.contacts, posture, level_trunk=False, fast_com=True, rigid_stance=True
        )
    )
    curve = trajectory.PiecewiseBezier(tuple(segments))
    spec = MotionSpec(np.asarray(stances[0].q, dtype=np.float64), tuple(phases), curve, rate)
    return spec, tuple(timings)


def build_jumps(
    character: Character,
    scene_bvh: Any,
    stances: Sequence[ContactState],
    legs: Sequence[JumpLeg],
    *,
    rate: float = 30.0,
    until: Termination = never,
) -> tuple[BuiltMotion, tuple[JumpTiming, ...]]:
    """Keyframes, phases, COM curve and report of ``legs`` between ``stances`` in the scene
    ``scene_bvh`` (coal BVH), every keyframe checked (see :func:`build_motion`)."""
    spec, timings = jump_spec(character, stances, legs, rate=rate)
    return build_motion(character, scene_bvh, spec, until=until), timings
