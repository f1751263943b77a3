"""The motion of one contact change: contact phases, a COM curve and whole-body keyframes.

Two phases (before, after). The COM moves rest-to-rest (quintic, peak acceleration bounded)
while the larger contact set holds it, to the new state's COM, which is a 2PAC transition
point (in equilibrium of the smaller set with the robustness margin and in both kinematic
COM polytopes, Eq. 5-6); the swing happens with the COM at rest, so every phase passes the
dynamic check of Eq. 1. Keyframes follow the COM by IK (2PAC section 7.2) holding the stance
contacts and moving the swing effector along an arc; outside the swing IK runs every
``_STRIDE`` keyframes and the rest are interpolated on the configuration manifold (any whose
stance slips more than 2 mm is re-solved). Local collision handling (2PAC 7.2): a colliding keyframe
sequence is recomputed with a higher swing arc, then with the transition point moved along
the obstacle normal (colliding contact postures are re-sampled earlier, in
``generation.create_contact``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.contact.checks import (
    balance_margin,
    check_state,
    com_of,
    effector_pose,
    forward,
    hold_error,
    kinematics_of,
    obstacle_normal,
    phase_of,
    scene_collisions,
    self_collides,
)
from planner.contact.context import ContactContext
from planner.contact.generation import balance_ik, hold_tasks, posture_task
from planner.contact.reachability import ground_limbs
from planner.contact.state import ContactState
from planner.kinematics import (
    ComTask,
    FramePlacementTask,
    FramePositionTask,
    Priority,
    keyframe_times,
    solve_ik,
    swing_trajectory,
    track_com,
)
from planner.motion import ComSegment, Keyframe, Phase
from trajectory import BezierCurve, PiecewiseBezier, quasi_static_polyline, validate_dynamics

FloatArray = NDArray[np.float64]

_LIFTS = (0.08, 0.18)  # m, swing arc heights tried in turn
_MIN_SWING = 0.4  # s, shortest swing
_ACC_FEW = 0.2  # m/s^2, peak COM acceleration over the smaller contact set (creation)
_ACC_MANY = 0.2  # m/s^2, peak COM acceleration over the larger contact set (break)
_SETTLE = 0.1  # s, the short phase without swing
_N_CHECKS = 5  # dynamic checks per phase
_STRIDE = 5  # outside the swing, IK every _STRIDE keyframes, interpolated in between
_REPAIR_TOL = 2e-3  # m, keyframes whose stance slips more are re-solved
_TRANSITION_SHIFTS = (0.03, 0.06)  # m, moves of the transition point off an obstacle
_BLEND = 0.3  # s, a re-sampled free limb's posture is blended in and out over this
_LANDING = 0.8  # s: when keyframes collide, those this close to the end settle into the state
_REPOSE_RANKS = (0, 10, 30, 100, 300, 1000, 3000, 10000)  # database samples tried, by rank


@dataclass(frozen=True, slots=True)
class StepMotion:
    """Motion between two states differing by one contact.

    phases : (before, after). com : Bezier segments covering [0, duration] s.
    keyframes : at ``rate`` Hz, the first at ``before.q`` and the last at ``after.q``.
    report : per-phase dynamic validity, transition slack, hold errors, collisions.
    """

    phases: tuple[Phase, ...]
    com: tuple[ComSegment, ...]
    keyframes: tuple[Keyframe, ...]
    report: dict[str, Any]
    state: ContactState


def step_motion(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
) -> StepMotion:
    """Phases, COM curve and keyframes taking ``before`` to ``after`` (``limb`` changes).

    When keyframes still collide after the higher swing arc, the transition point (the COM
    of ``after``) is moved along the obstacle normal and the motion recomputed (2PAC 7.2);
    the motion then ends in the re-posed state, ``StepMotion.state`` (same contacts). The
    report gives ``transition_shift`` (m, 0 when not moved).
    """
    motion = _motion(ctx, before, after, limb, rate)
    if motion.report["colliding_keyframes"] == 0:
        return motion
    normal = next(
        (
            n
            for k in motion.keyframes[1:-1]
            if (n := obstacle_normal(ctx, k.q, _stance_of(motion, k))) is not None
        ),
        None,
    )
    if normal is not None:  # (self-collision only: nothing to move away from)
        motion = _shift_transition(ctx, before, after, limb, rate, motion, normal)
    # free arms swept through the thighs or the seat by a deep crouch: keep them in place;
    # a tracking IK that drifts off the swing (a thigh grazing a seat edge): land on the state
    tracked: dict[float, tuple[list[FloatArray], list[float], float]] = {}
    for landing in (0.0, _LANDING):
        if motion.report["colliding_keyframes"] == 0:
            break
        held = _motion(
            ctx, before, motion.state, limb, rate, hold_arms=True, landing=landing, tracked=tracked
        )
        held.report["transition_shift"] = motion.report["transition_shift"]
        if held.report["colliding_keyframes"] < motion.report["colliding_keyframes"]:
            motion = held
    if motion.report["colliding_keyframes"] > 0:
        motion = _repose_free_limbs(ctx, motion, limb)
    return motion


def _repose_free_limbs(ctx: ContactContext, motion: StepMotion, limb: str) -> StepMotion:
    """``motion`` with the limbs that are free throughout (neither in contact nor swinging)
    re-sampled (2PAC 7.2): each takes a posture from its sample database, blended in over the
    first ``_BLEND`` of the motion and out over the last, and the posture leaving the fewest
    colliding keyframes is kept (``motion`` itself when none does better)."""
    held = {c.limb for p in motion.phases for c in p.contacts}
    free = [x for x in ctx.character.default_limbs if x.name != limb and x.name not in held]
    if not free:
        return motion
    keys = motion.keyframes
    t0, t1 = keys[0].t, keys[-1].t
    ramp = np.array([min(1.0, (k.t - t0) / _BLEND, (t1 - k.t) / _BLEND) for k in keys])
    ramp = np.clip(ramp, 0.0, 1.0)
    stances = [_stance_of(motion, k) for k in keys]

    base = [np.array(k.q) for k in keys]
    best, best_hits = base, _colliding(ctx, base, stances)
    sizes = [len(ctx.data.limb(x.name).database.q) for x in free]
    for rank in _REPOSE_RANKS:
        trial = [q.copy() for q in base]
        for spec, size in zip(free, sizes, strict=True):
            posture = ctx.data.limb(spec.name).database.q[min(rank, size - 1)]
            for q, w in zip(trial, ramp, strict=True):
                q[spec.idx_q] = (1.0 - w) * q[spec.idx_q] + w * posture
        count = _colliding(ctx, trial, stances)
        if count < best_hits:
            best, best_hits = trial, count
        if best_hits == 0:
            break
    if best is base:
        return motion
    keyframes = tuple(Keyframe(k.t, q, k.contacts) for k, q in zip(keys, best, strict=True))
    report = dict(motion.report)
    report["colliding_keyframes"] = best_hits
    report["free_limbs_reposed"] = [x.name for x in free]
    return StepMotion(motion.phases, motion.com, keyframes, report, motion.state)


def _shift_transition(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    rate: float,
    motion: StepMotion,
    normal: FloatArray,
) -> StepMotion:
    """``motion`` recomputed with the transition point moved along the obstacle ``normal``
    (3,) when that leaves fewer colliding keyframes (2PAC 7.2)."""
    creating = after.contact(limb) is not None
    fewer = before.contacts if creating else after.contacts
    kin_b, kin_a = kinematics_of(ctx, before.contacts), kinematics_of(ctx, after.contacts)
    c1 = com_of(ctx, after.q)
    # lifted legs keep their pose while the body moves (not dragged into the floor)
    lifted = [x for x in _legs(ctx) if after.contact(x) is None]
    keep = [
        FramePlacementTask(
            ctx.character.limb(x).frame_id, effector_pose(ctx, x, after.q), Priority.EFFECTOR
        )
        for x in lifted
    ]
    for shift in _TRANSITION_SHIFTS:
        target = c1 + shift * normal
        res = balance_ik(ctx, np.array(after.q), after.contacts, target, extra=keep, moving=lifted)
        moved = ContactState(np.array(res.q), after.contacts)
        com = com_of(ctx, moved.q)
        if (
            not check_state(ctx, moved).valid
            or balance_margin(ctx, fewer, com) < ctx.params.margin
            or max(kin_b.violation(com), kin_a.violation(com)) > 1e-3
        ):
            continue
        again = _motion(ctx, before, moved, limb, rate)
        again.report["transition_shift"] = shift
        if again.report["colliding_keyframes"] < motion.report["colliding_keyframes"]:
            motion = again
        if motion.report["colliding_keyframes"] == 0:
            break
    return motion


def _legs(ctx: ContactContext) -> tuple[str, ...]:
    """The character's ground limbs (memoised in the context)."""
    legs: tuple[str, ...] = ctx.cached("ground_limbs", lambda: ground_limbs(ctx.character))
    return legs


def _braced_elbows(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    legs: Sequence[str],
) -> list[FramePositionTask]:
    """Soft holds keeping the middle joint (the elbow) of each arm braced on a contact in both
    states where it was in ``before``: the crouch that shifts the trunk over the other
    contacts would otherwise fold the forearm onto the surface the hand rests on."""
    model, data = ctx.model, ctx.pin_data
    forward(ctx, before.q)
    tasks = []
    for spec in ctx.character.limbs:
        if spec.name == limb or spec.name in legs or len(spec.joint_ids) < 3:
            continue
        if before.contact(spec.name) is None or after.contact(spec.name) is None:
            continue
        joint = int(spec.joint_ids[len(spec.joint_ids) // 2])
        frame = model.getFrameId(model.names[joint])
        where = np.array(data.oMf[frame].translation)
        tasks.append(FramePositionTask(frame, where, priority=Priority.EFFECTOR, weight=0.3))
    return tasks


def _stance_of(motion: StepMotion, key: Keyframe) -> tuple[Any, ...]:
    """The contacts held at keyframe ``key`` (those of its phase that it lists)."""
    phase = motion.phases[0] if key.t < motion.phases[0].t1 else motion.phases[1]
    return tuple(c for c in phase.contacts if c.limb in key.contacts)


def _motion(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    rate: float,
    hold_arms: bool = False,
    landing: float = 0.0,
    tracked: dict[float, tuple[list[FloatArray], list[float], float]] | None = None,
) -> StepMotion:
    """:func:`step_motion` for a fixed transition point (the COM of ``after``); with
    ``hold_arms``, free arms too keep their world pose instead of following the trunk; the
    keyframes of the last ``landing`` seconds are blended into ``after``. ``tracked`` keeps
    the tracked keyframes per swing lift across calls that differ only by ``landing``."""
    phase_b, phase_a = phase_of(ctx, before.contacts), phase_of(ctx, after.contacts)
    kin_b, kin_a = kinematics_of(ctx, before.contacts), kinematics_of(ctx, after.contacts)
    c0, c1 = com_of(ctx, before.q), com_of(ctx, after.q)
    creating = after.contact(limb) is not None
    # The COM moves rest-to-rest while the larger contact set holds it (quasi-static, 2PAC
    # section 5: the end point is a transition point, in equilibrium(fewer contacts) and in
    # both kinematic sets); the swing then happens with the COM at rest.
    acc = _ACC_FEW if creating else _ACC_MANY
    move: list[BezierCurve] = []
    if float(np.linalg.norm(c1 - c0)) > 1e-6:
        move = list(quasi_static_polyline(np.stack([c0, c1]), acc).segments)
    t_move = move[-1].t1 if move else 0.0
    if creating:
        t_phase = max(t_move, _MIN_SWING)
        times = np.array([0.0, t_phase, t_phase + _SETTLE])
    else:
        t_phase = max(t_move, _SETTLE)
        times = np.array([0.0, t_phase, t_phase + _MIN_SWING])
    curves = list(move)
    if t_phase > t_move + 1e-9:
        curves.append(BezierCurve(np.stack([c1, c1]), t_move, t_phase))
    curves.append(BezierCurve(np.stack([c1, c1]), t_phase, float(times[2])))
    curve = PiecewiseBezier(tuple(curves))
    reports = validate_dynamics(curve, [phase_b, phase_a], times, _N_CHECKS)
    segments = [ComSegment(g.t0, g.t1, np.array(g.control_points)) for g in curve.segments]
    t_first, t_last = float(curve.t0), float(curve.t1)
    fewer = before.contacts if creating else after.contacts
    transition = {
        "point": c1.tolist(),
        "margin": balance_margin(ctx, fewer, c1),
        "kinematic_violation": float(max(kin_b.violation(c1), kin_a.violation(c1))),
    }

    def com_samples(ts: FloatArray) -> FloatArray:
        tt = np.clip(ts, t_first, t_last)
        return np.asarray(curve(tt), dtype=np.float64)

    def com_at(t: float) -> FloatArray:
        out: FloatArray = com_samples(np.array([t]))[0]
        return out

    spec = ctx.character.limb(limb)
    start_pose = effector_pose(ctx, limb, before.q)
    end_pose = effector_pose(ctx, limb, after.q)
    swing_phase = 0 if creating else 1
    stances = (before.contacts, after.contacts)
    # legs neither in contact nor swinging stay where they hang (a foot lifted earlier does
    # not sink into the floor while the body shifts over the others)
    legs = _legs(ctx)
    idle = [
        FramePlacementTask(
            other.frame_id, effector_pose(ctx, other.name, before.q), Priority.EFFECTOR
        )
        for other in ctx.character.default_limbs
        if other.name != limb
        and (hold_arms or other.name in legs)
        and before.contact(other.name) is None
        and after.contact(other.name) is None
    ]
    braced = _braced_elbows(ctx, before, after, limb, legs)

    def track(lift: float) -> tuple[list[FloatArray], list[float], float]:
        """Keyframes (configurations, times) tracking the COM with a swing arc raised
        ``lift`` m, and the worst stance hold error [m] among them."""
        qs: list[FloatArray] = []
        ts: list[float] = []
        q = np.array(before.q)
        worst_hold = 0.0
        for j in range(2):
            t0, t1 = float(times[j]), float(times[j + 1])
            if t1 - t0 < 1e-9:
                continue
            swing: Callable[[float], FloatArray] | None = None
            frame = None
            if j == swing_phase:
                arc = swing_trajectory(
                    start_pose, end_pose, t0, t1, lift=lift, normal_in_frame=spec.normal
                )
                swing = _positions(arc) if spec.contact == "point" else arc
                frame = spec.frame_id
            kf_times = keyframe_times(t0, t1, rate)
            stride = 1 if j == swing_phase else _STRIDE
            knots = kf_times if stride == 1 else keyframe_times(t0, t1, rate / stride)
            track = track_com(
                ctx.model,
                q,
                (knots, com_samples(knots)),
                stance=[*hold_tasks(stances[j], ctx), *idle, *braced],
                swing_frame=frame,
                swing=swing,
                reference=after.q,
                rate=rate / stride,
                data=ctx.pin_data,
                max_iterations=12,
            )
            if ts:  # the boundary keyframe belongs to the later phase
                qs.pop()
                ts.pop()
            stance = stances[j]
            configs = _resample(ctx, track.times, track.configurations, kf_times)
            for i, qq in enumerate(configs):
                error = hold_error(ctx, qq, stance)
                if error > _REPAIR_TOL:
                    configs[i] = _repair(ctx, qq, stance, com_at(float(kf_times[i])))
                    error = hold_error(ctx, configs[i], stance)
                worst_hold = max(worst_hold, error)
            track_times = kf_times
            qs.extend(configs)
            ts.extend(float(t) for t in track_times)
            q = np.array(configs[-1])
        qs[0] = np.array(before.q)
        qs[-1] = np.array(after.q)
        return qs, ts, worst_hold

    best: tuple[list[FloatArray], list[float], float, int, float] | None = None
    for lift in _LIFTS:
        raw = tracked.get(lift) if tracked is not None else None
        if raw is None:
            raw = track(lift)
            if tracked is not None:
                tracked[lift] = raw
        qs, ts, worst_hold = [np.array(q) for q in raw[0]], list(raw[1]), raw[2]
        if landing > 0.0:
            for i in _land(ctx.model, qs, ts, after.q, landing):
                stance = _stance_at(ts[i], times, stances)
                if hold_error(ctx, qs[i], stance) > 2e-4:  # the blend let go a little
                    qs[i] = _repair(ctx, qs[i], stance, com_at(ts[i]))
        held = tuple(c for c in before.contacts if c.limb in after.limbs)
        hits = _colliding(ctx, qs, [held] * len(qs))
        if best is None or hits < best[3]:
            best = (qs, ts, worst_hold, hits, lift)
        if hits == 0:
            break
    assert best is not None
    qs, ts, worst_hold, hits, lift = best
    keyframes = tuple(
        Keyframe(t, qq, tuple(c.limb for c in _stance_at(t, times, stances)))
        for t, qq in zip(ts, qs, strict=True)
    )
    phases = (
        Phase(float(times[0]), float(times[1]), before.contacts),
        Phase(float(times[1]), float(times[2]), after.contacts),
    )
    com = tuple(segments)
    report: dict[str, Any] = {
        "phases": [
            {
                "phase": r.phase,
                "t0": r.t0,
                "t1": r.t1,
                "fraction_valid": r.fraction_valid,
                "worst_violation": r.worst_violation,
            }
            for r in reports
        ],
        "transition": transition,
        "transition_slack": [max(0.0, transition["kinematic_violation"])],
        "quasi_static_feasible": bool(
            transition["margin"] >= ctx.params.margin and transition["kinematic_violation"] <= 1e-3
        ),
        "max_hold_error": worst_hold,
        "colliding_keyframes": hits,
        "swing_lift": float(lift),
        "transition_shift": 0.0,
    }
    return StepMotion(phases, com, keyframes, report, after)


def _colliding(
    ctx: ContactContext, qs: Sequence[FloatArray], stances: Sequence[Sequence[Any]]
) -> int:
    """Interior keyframes of ``qs`` where the body touches itself, the scene or an obstacle;
    ``stances[i]`` are the contacts whose effector shapes rest on their surfaces at ``qs[i]``."""
    return sum(
        int(self_collides(ctx, q) or bool(scene_collisions(ctx, q, contacts=stance)))
        for q, stance in zip(qs[1:-1], stances[1:-1], strict=True)
    )


def _resample(
    ctx: ContactContext, knots: FloatArray, configs: FloatArray, times: FloatArray
) -> list[FloatArray]:
    """Configurations at ``times`` (k,) interpolated on the configuration manifold between
    those solved at ``knots`` (m,)."""
    if len(knots) == len(times) and np.array_equal(knots, times):
        return [np.array(c) for c in configs]
    out: list[FloatArray] = []
    for t in times.tolist():
        i = int(np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2))
        span = float(knots[i + 1] - knots[i])
        u = 0.0 if span <= 0 else min(max((t - float(knots[i])) / span, 0.0), 1.0)
        out.append(np.asarray(pin.interpolate(ctx.model, configs[i], configs[i + 1], u)))
    return out


def _repair(ctx: ContactContext, q: FloatArray, stance: Any, com: FloatArray) -> FloatArray:
    """Re-solve one keyframe whose stance contacts slipped, with a larger iteration budget;
    when the COM target (3,) still pulls a contact off (four contacts leave little freedom),
    the contacts are held alone, the COM staying where the first solve left it."""
    tasks = [*hold_tasks(stance, ctx), ComTask(com), posture_task(ctx)]
    best = q
    for attempt in (tasks, [*hold_tasks(stance, ctx), posture_task(ctx)]):
        result = solve_ik(ctx.model, best, attempt, data=ctx.pin_data, max_iterations=100)
        if hold_error(ctx, result.q, stance) < hold_error(ctx, best, stance):
            best = np.array(result.q)
        if hold_error(ctx, best, stance) <= _REPAIR_TOL:
            break
    return best


def _positions(arc: Callable[[float], FloatArray]) -> Callable[[float], FloatArray]:
    def position(t: float) -> FloatArray:
        return np.asarray(arc(t)[:3, 3], dtype=np.float64)

    return position


def _land(
    model: Any, qs: list[FloatArray], ts: list[float], goal: FloatArray, landing: float
) -> list[int]:
    """Blend the keyframes of the last ``landing`` seconds into ``goal`` (nq,) (in place,
    along the configuration manifold): the motion settles on the state it was planned to
    reach instead of whatever posture the tracking IK drifted to (a thigh grazing a seat).
    The first and last keyframes are never changed. Returns the indices of those changed."""
    end = ts[-1]
    window = min(landing, end - ts[0])  # a short motion blends from its start, not mid-way
    changed = []
    for i in range(1, len(ts) - 1):
        w = (ts[i] - (end - window)) / window
        if 0.0 < w < 1.0:
            qs[i] = np.asarray(pin.interpolate(model, qs[i], goal, w), dtype=np.float64)
            changed.append(i)
    return changed


def _stance_at(t: float, times: FloatArray, stances: tuple[Any, Any]) -> Any:
    return stances[0] if t < float(times[1]) else stances[1]
