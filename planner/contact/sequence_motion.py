"""Motion through a sequence of contact states: 2PAC COM curve, phases and whole-body keyframes.

States differ by one contact each. Phase k holds the contacts of state k; the limb created at
the end of a phase swings during it, from its previous contact to its new one. The COM
follows a 2PAC trajectory through the phases' equilibrium and kinematic polytopes, and
whole-body inverse kinematics tracks it while holding the stance contacts (2PAC section 7.2).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

import trajectory
from planner.character import Character
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import (
    ComTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    Priority,
    com_position,
    frame_placement,
    keyframe_times,
    solve_ik,
    swing_trajectory,
    track_com,
)
from planner.motion import ComSegment, Keyframe, Phase
from planner.offline import OfflineData
from planner.termination import Termination, never

FloatArray = NDArray[np.float64]
_QUINTIC_PEAK = 10.0 / np.sqrt(3.0)  # peak |c''| T^2 / L of the rest-to-rest quintic


@dataclass(frozen=True, slots=True)
class SequenceMotion:
    """Phases, COM segments and keyframes of a contact sequence, plus a per-phase report."""

    phases: tuple[Phase, ...]
    com: tuple[ComSegment, ...]
    keyframes: tuple[Keyframe, ...]
    report: dict[str, object]


def contact_phase(character: Character, state: ContactState) -> trajectory.ContactPhase:
    """The trajectory-library phase of a state (its contact points, normals, frictions)."""
    contacts = [
        trajectory.Contact(points=c.points, normal=c.normal, mu=c.mu) for c in state.contacts
    ]
    return trajectory.ContactPhase(contacts=contacts, mass=float(character.mass))


def phase_kinematics(data: OfflineData, state: ContactState) -> trajectory.Halfspaces | None:
    """K c <= k (world frame) from the COM polytopes of the state's effectors (2PAC Eq. 4)."""
    constraints = []
    for contact in state.contacts:
        polytope = data.com_constraint(contact.limb).polytope
        constraints.append(
            trajectory.EffectorConstraint(
                halfspaces=trajectory.Halfspaces(polytope.A, polytope.b),
                rotation=contact.placement[:3, :3],
                position=contact.placement[:3, 3],
            )
        )
    return trajectory.kinematic_polytope(constraints) if constraints else None


def rest_to_rest(
    waypoints: FloatArray,
    *,
    min_durations: Sequence[float],
    max_acceleration: float,
) -> tuple[trajectory.PiecewiseBezier, FloatArray]:
    """COM through (n + 1, 3) waypoints, at rest at each, one quintic per leg.

    Control points [a, a, a, b, b, b] keep each leg on the segment a-b with zero velocity and
    acceleration at both ends (C2 joins). Leg k lasts long enough that the peak acceleration
    (10 / sqrt(3) |b - a| / T^2 for this quintic) stays under ``max_acceleration`` (m/s^2),
    and at least min_durations[k]. Returns the curve and the (n + 1,) leg times.
    """
    segments = []
    times = [0.0]
    for k in range(len(waypoints) - 1):
        a, b = waypoints[k], waypoints[k + 1]
        length = float(np.linalg.norm(b - a))
        duration = max(float(min_durations[k]), np.sqrt(_QUINTIC_PEAK * length / max_acceleration))
        control = np.array([a, a, a, b, b, b])
        segments.append(trajectory.BezierCurve(control, times[-1], times[-1] + duration))
        times.append(times[-1] + duration)
    return trajectory.PiecewiseBezier(tuple(segments)), np.asarray(times, dtype=np.float64)


def _stance_tasks(
    character: Character, contacts: Sequence[LimbContact]
) -> list[FramePlacementTask | FramePositionTask]:
    """Contact-tier tasks holding ``contacts``: the pose of a patch, the position of a point.

    Both are explicitly in the contact tier: a FramePositionTask defaults to the effector
    tier, ten times below the COM, and point feet then slid wherever the COM pulled them.
    """
    tasks: list[FramePlacementTask | FramePositionTask] = []
    for contact in contacts:
        limb = character.limb(contact.limb)
        if limb.contact == "patch":
            tasks.append(
                FramePlacementTask(limb.effector_frame, contact.placement, Priority.CONTACT)
            )
        else:
            tasks.append(
                FramePositionTask(
                    limb.effector_frame, contact.position, np.zeros(3), Priority.CONTACT
                )
            )
    return tasks


def _swinging_limb(states: Sequence[ContactState], k: int) -> str | None:
    """The limb created at the end of phase k, if the next change is a creation."""
    if k + 1 >= len(states):
        return None
    created = set(states[k + 1].limbs) - set(states[k].limbs)
    return next(iter(created)) if created else None


def _last_placement(
    character: Character, states: Sequence[ContactState], k: int, limb: str, q: FloatArray
) -> FloatArray:
    """Where ``limb`` was last in contact up to state k, else where ``q`` puts it."""
    for state in reversed(states[: k + 1]):
        contact = state.contact(limb)
        if contact is not None:
            return np.asarray(contact.placement)
    return frame_placement(character.model, q, character.limb(limb).effector_frame)


def _positions(arc: Callable[[float], FloatArray]) -> Callable[[float], FloatArray]:
    """The position (3,) part of a pose-valued path."""

    def position(t: float) -> FloatArray:
        return np.asarray(arc(t)[:3, 3], dtype=np.float64)

    return position


_HOLD_REPAIR = 0.005  # m, a keyframe whose stance slipped more than this is re-solved


def _hold_first(
    model: Any,
    q: FloatArray,
    stance: Sequence[FramePlacementTask | FramePositionTask],
    com: FloatArray,
    holding: FloatArray,
) -> tuple[FloatArray, float]:
    """Re-solve a keyframe whose stance contacts slipped: contacts and the COM target first;
    if the contacts still slip, contacts alone with the posture kept near ``q`` (the COM then
    leaves its curve; the report's COM error says by how much); last, the same two from
    ``holding`` (nq,), the phase's own state, which holds the stance (a tracker wound into
    a corner does not unwind from where it is). Returns the configuration and its largest
    contact error (m)."""
    attempts: list[list[Any]] = [[*stance, ComTask(com)], list(stance)]
    best_q, best_err = q, _stance_error(model, q, stance)
    weights = np.ones(model.nv)
    weights[:6] = 0.0
    for seed in (q, holding):
        start = best_q if seed is q else np.asarray(holding, dtype=np.float64)
        for tasks in attempts:
            result = solve_ik(
                model, start, [*tasks, PostureTask(seed, weights, gain=0.3)], max_iterations=200
            )
            err = _stance_error(model, np.asarray(result.q), stance)
            if err < best_err:
                best_q, best_err = np.array(result.q), err
                start = best_q
            if best_err <= _HOLD_REPAIR:
                return best_q, best_err
    return best_q, best_err


def _stance_error(
    model: Any, q: FloatArray, stance: Sequence[FramePlacementTask | FramePositionTask]
) -> float:
    """Largest distance (m) of a stance frame from its target at ``q``."""
    worst = 0.0
    for task in stance:
        frame = frame_placement(model, q, task.frame)
        target = task.target if task.target.shape == (3,) else task.target[:3, 3]
        worst = max(worst, float(np.linalg.norm(frame[:3, 3] - target)))
    return worst


def sequence_motion(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    *,
    rate: float = 30.0,
    lift: float = 0.08,
    seconds_per_metre: float = 4.0,
    min_swing_s: float = 0.6,
    min_phase_s: float = 0.2,
    max_acceleration: float = 0.6,
    until: Termination = never,
) -> SequenceMotion:
    """COM trajectory and keyframes through ``states`` (at least one), keyframes at ``rate`` Hz.

    If ``until`` fires while keyframes are computed, the remaining phases keep their COM curve
    but get no keyframes; the report says how many phases were animated.
    """
    if not states:
        raise ValueError("states: at least one contact state is needed")
    model = character.model
    phases_tr = [contact_phase(character, s) for s in states]
    kinematics = [phase_kinematics(data, s) for s in states]
    start_com = com_position(model, states[0].q)
    end_com = com_position(model, states[-1].q)
    com_trajectory = trajectory.plan_com_trajectory(
        phases_tr,
        start_com,
        end_com,
        kinematics=kinematics,
        seconds_per_metre=seconds_per_metre,
    )
    times = np.asarray(com_trajectory.phase_times, dtype=np.float64)
    curve: trajectory.PiecewiseBezier = com_trajectory.curve
    method = "2pac"
    swing_phases = [k for k in range(len(states)) if _swinging_limb(states, k) is not None]
    if any(times[k + 1] - times[k] < min_swing_s for k in swing_phases):
        # A swing needs time; 2PAC may pass the phase in an instant when consecutive
        # transition points coincide. Rest at each transition point instead: every segment
        # joins two points of its phase's convex feasible set, so it stays inside it.
        waypoints = [start_com, *(t.point for t in com_trajectory.transitions), end_com]
        curve, times = rest_to_rest(
            np.asarray(waypoints, dtype=np.float64),
            min_durations=[
                min_swing_s if k in swing_phases else min_phase_s for k in range(len(states))
            ],
            max_acceleration=max_acceleration,
        )
        method = "rest_to_rest"
    reports = trajectory.validate_dynamics(curve, phases_tr, times)

    def com_at(t: float) -> FloatArray:
        return np.asarray(curve(np.array([t]))[0], dtype=np.float64)

    phases = tuple(
        Phase(t0=float(times[k]), t1=float(times[k + 1]), contacts=s.contacts)
        for k, s in enumerate(states)
    )
    segments = tuple(
        ComSegment(t0=float(seg.t0), t1=float(seg.t1), control_points=seg.control_points)
        for seg in curve.segments
    )

    keyframes: list[Keyframe] = []
    contact_error = 0.0
    com_error = 0.0
    animated = 0
    repaired = 0
    q = np.array(states[0].q, dtype=np.float64)
    for k, state in enumerate(states):
        if until():
            break
        t0, t1 = float(times[k]), float(times[k + 1])
        if t1 <= t0:
            continue
        swing_limb = _swinging_limb(states, k)
        swing_frame = None
        swing = None
        if swing_limb is not None:
            limb = character.limb(swing_limb)
            target = states[k + 1].contact(swing_limb)
            assert target is not None
            start = _last_placement(character, states, k, swing_limb, q)
            swing_frame = limb.effector_frame
            arc = swing_trajectory(
                start, target.placement, t0, t1, lift=lift, normal_in_frame=limb.normal
            )
            # A point foot only places its position: its recorded orientation is the root's,
            # which a three-joint leg cannot give its foot frame, and chasing it twists the body.
            swing = _positions(arc) if limb.contact == "point" else arc
        knots = keyframe_times(t0, t1, rate)  # the COM curve sampled once per phase
        track = track_com(
            model,
            q,
            (knots, np.asarray(curve(knots), dtype=np.float64)),
            stance=_stance_tasks(character, state.contacts),
            swing_frame=swing_frame,
            swing=swing,
            reference=states[min(k + 1, len(states) - 1)].q,
            t_start=t0,
            t_end=t1,
            rate=rate,
        )
        first = 0 if k == 0 or not keyframes else 1
        stance = _stance_tasks(character, state.contacts)
        configurations = []
        for t, qk, err in zip(track.times, track.configurations, track.contact_errors, strict=True):
            if err > _HOLD_REPAIR:
                qk, err = _hold_first(model, np.array(qk), stance, com_at(float(t)), state.q)
                repaired += 1
            contact_error = max(contact_error, float(err))
            configurations.append(qk)
        for t, qk in zip(track.times[first:], configurations[first:], strict=True):
            keyframes.append(Keyframe(t=float(t), q=np.array(qk), contacts=state.limbs))
        if len(track.com_errors):
            com_error = max(com_error, float(np.max(track.com_errors)))
        q = np.array(configurations[-1], dtype=np.float64)
        animated += 1

    report: dict[str, object] = {
        "phases_animated": animated,
        "com_method": method,
        "quasi_static_feasible": bool(com_trajectory.quasi_static_feasible),
        "transition_slack": [float(t.slack) for t in com_trajectory.transitions],
        "max_contact_error_m": contact_error,
        "keyframes_repaired": repaired,
        "max_com_error_m": com_error,
        "dynamic_validity": [
            {
                "fraction_valid": float(r.fraction_valid),
                "worst_violation": float(r.worst_violation),
            }
            for r in reports
        ],
    }
    return SequenceMotion(phases, segments, tuple(keyframes), report)
