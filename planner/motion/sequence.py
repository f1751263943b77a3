"""The motion of a contact sequence (a plan): its COM curve and phases as a
:class:`MotionSpec`, animated by the one builder.

States differ by one contact each. Phase k holds the contacts of state k; the limb created at
the end of a phase swings during it, from its previous contact to its new one. The COM
follows a 2PAC trajectory through the phases' equilibrium and kinematic polytopes (or rests
at each transition point when 2PAC leaves a swing too little time), and the builder tracks
it with the whole body (2PAC section 7.2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import trajectory
from planner.character import Character
from planner.kinematics import com_position, frame_placement
from planner.motion import tuning
from planner.motion.builder import MotionReport, build_motion
from planner.motion.spec import MotionPhase, MotionSpec, Swing, natural_posture
from planner.motion.types import ComSegment, Keyframe, Phase
from planner.offline import OfflineData
from planner.termination import Termination, never

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState

FloatArray = NDArray[np.float64]
_QUINTIC_PEAK = 10.0 / np.sqrt(3.0)  # peak |c''| T^2 / L of the rest-to-rest quintic


@dataclass(frozen=True, slots=True)
class SequenceMotion:
    """Phases, COM segments and keyframes of a contact sequence; ``report`` as JSON-ready
    values (the builder's report, the COM method, transition slacks, dynamic validity per
    phase) and ``quality`` the builder's typed report."""

    phases: tuple[Phase, ...]
    com: tuple[ComSegment, ...]
    keyframes: tuple[Keyframe, ...]
    report: dict[str, object]
    quality: MotionReport


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


def sequence_motion(
    character: Character,
    data: OfflineData,
    scene_bvh: Any,
    states: Sequence[ContactState],
    *,
    rate: float = 30.0,
    lift: float = tuning.SWING_LIFTS[0],
    obstacles: Sequence[tuple[Any, Any]] = (),
    seconds_per_metre: float = 4.0,
    min_swing_s: float = 0.6,
    min_phase_s: float = 0.2,
    max_acceleration: float = 0.6,
    until: Termination = never,
) -> SequenceMotion:
    """COM trajectory and keyframes through ``states`` (at least one) in the scene
    ``scene_bvh`` (coal BVH), keyframes at ``rate`` Hz.

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
        # The waypoints are the planned states' own COMs: each is balanced on its state's
        # contacts, and the whole-body states (which the keyframes head for) agree with
        # them, where 2PAC's transition points sit anywhere in the learned kinematic sets
        # (on stairs 30 cm lower than any posture the legs can hold upright).
        waypoints = [com_position(model, s.q) for s in states] + [end_com]
        curve, times = rest_to_rest(
            np.asarray(waypoints, dtype=np.float64),
            min_durations=[
                min_swing_s if k in swing_phases else min_phase_s for k in range(len(states))
            ],
            max_acceleration=max_acceleration,
        )
        method = "rest_to_rest"
    reports = trajectory.validate_dynamics(curve, phases_tr, times)

    spec_phases = []
    for k, state in enumerate(states):
        swing = None
        swing_limb = _swinging_limb(states, k)
        if swing_limb is not None:
            target = states[k + 1].contact(swing_limb)
            assert target is not None
            start = _last_placement(character, states, k, swing_limb, states[k].q)
            swing = Swing(swing_limb, start, np.asarray(target.placement), lift)
        aim = states[min(k + 1, len(states) - 1)]
        posture = natural_posture(character, np.asarray(aim.q), aim.limbs)
        spec_phases.append(
            MotionPhase(float(times[k]), float(times[k + 1]), state.contacts, posture, swing)
        )
    spec = MotionSpec(np.asarray(states[0].q), tuple(spec_phases), curve, rate)
    built = build_motion(character, scene_bvh, spec, obstacles=obstacles, until=until)
    report: dict[str, object] = {
        **built.report.as_dict(),
        "com_method": method,
        "quasi_static_feasible": bool(com_trajectory.quasi_static_feasible),
        "transition_slack": [float(t.slack) for t in com_trajectory.transitions],
        "dynamic_validity": [
            {
                "fraction_valid": float(r.fraction_valid),
                "worst_violation": float(r.worst_violation),
            }
            for r in reports
        ],
    }
    return SequenceMotion(built.phases, built.com, built.keyframes, report, built.report)
