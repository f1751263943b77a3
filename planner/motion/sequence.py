"""The motion of a contact sequence (a plan): its COM curve and phases as a
:class:`MotionSpec`, animated by the one builder.

States differ by one contact each. Phase k holds the contacts of state k; the limb created at
the end of a phase swings during it, from its previous contact to its new one. The COM
follows a 2PAC trajectory through the phases' equilibrium and kinematic polytopes (or rests
at each transition point when 2PAC leaves a swing too little time), and the builder tracks
it with the whole body (2PAC section 7.2).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

import trajectory
from planner.character import Character
from planner.kinematics import com_position, frame_placement
from planner.motion import tuning
from planner.motion.builder import BuiltMotion, MotionReport, build_motion
from planner.motion.overlap import Overlap, overlap_swings
from planner.motion.spec import (
    MotionPhase,
    MotionSpec,
    Swing,
    natural_posture,
    swing_length,
    torso_columns,
)
from planner.motion.types import ComSegment, Keyframe, Phase
from planner.offline import OfflineData
from planner.termination import Termination, never

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState, LimbContact

FloatArray = NDArray[np.float64]
_QUINTIC_PEAK = 10.0 / np.sqrt(3.0)  # peak |c''| T^2 / L of the rest-to-rest quintic


MIN_SPEED = 0.25
MAX_SPEED = 3.0


@dataclass(frozen=True, slots=True)
class Timing:
    """How a plan's COM is timed and shaped (2PAC sections 6.4, 7.3).

    speed : factor on the nominal pace and on the shortest swing and shift durations, in
    [MIN_SPEED, MAX_SPEED]. cost : the transition-point cost ("tired" by default).
    attractors : user-placed transition points, (phase change index, world point (3,) m);
    each is honoured when it is in static equilibrium and reachable for both phases it
    joins, refused otherwise (the report says which and why). overlap : a walker on four
    legs or more lifts its next leg before the last one lands where the ground and the
    dynamics allow (``planner.motion.overlap``); False swings one leg at a time.
    """

    speed: float = 1.0
    cost: trajectory.TransitionCost = field(
        default_factory=lambda: trajectory.TransitionCost("tired")
    )
    attractors: tuple[tuple[int, FloatArray], ...] = ()
    overlap: bool = True

    def __post_init__(self) -> None:
        if not MIN_SPEED <= self.speed <= MAX_SPEED:
            raise ValueError(f"speed must be in [{MIN_SPEED}, {MAX_SPEED}], got {self.speed}")


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
    states: tuple[ContactState, ...] = ()
    """The states animated: those given, or with a suffix re-planned (``replan``)."""


Replanner = Callable[[Sequence["ContactState"], int, float], "Sequence[ContactState] | None"]
"""(states, phase, reserve) -> states sharing a prefix with ``states`` and differing from the
phase before ``phase`` at the latest, whose contact changes avoid the one ``phase`` could
not make; None when there are none, or when re-planning would not leave the work of
``reserve`` seconds of animation (the fallback: 2PAC's curve through the states first
given, built whole)."""


_PER_STATE: dict[tuple[object, ...], tuple[Any, ...]] = {}
_PER_STATE_KEPT = 4096  # answers remembered; all forgotten past this


def _per_state(key: tuple[object, ...], inputs: tuple[Any, ...], make: Callable[[], Any]) -> Any:
    """``make()``, remembered under ``key`` (the ids of the immutable ``inputs`` it reads, and
    plain values) while the same objects are given: a plan's states are turned into phases
    again by every dynamic window, trial build and re-plan. Only the inputs themselves are
    kept (a state, an effector's polytope), not what holds them."""
    known = _PER_STATE.get(key)
    if known is not None and all(a is b for a, b in zip(known[:-1], inputs, strict=True)):
        return known[-1]
    value = make()
    if len(_PER_STATE) >= _PER_STATE_KEPT:
        _PER_STATE.clear()
    _PER_STATE[key] = (*inputs, value)
    return value


def contact_phase(character: Character, state: ContactState) -> trajectory.ContactPhase:
    """The trajectory-library phase of a state (its contact points, normals, frictions),
    remembered per state object."""
    mass = float(character.mass)
    phase: trajectory.ContactPhase = _per_state(
        ("phase", id(state), mass), (state,), lambda: _contact_phase(mass, state)
    )
    return phase


def _contact_phase(mass: float, state: ContactState) -> trajectory.ContactPhase:
    contacts = [
        trajectory.Contact(points=c.points, normal=c.normal, mu=c.mu) for c in state.contacts
    ]
    return trajectory.ContactPhase(contacts=contacts, mass=mass)


def phase_kinematics(data: OfflineData, state: ContactState) -> trajectory.Halfspaces | None:
    """K c <= k (world frame) from the COM polytopes of the state's effectors (2PAC Eq. 4),
    remembered per state object and polytopes."""
    polytopes = tuple(data.com_constraint(c.limb).polytope for c in state.contacts)
    kinematics: trajectory.Halfspaces | None = _per_state(
        ("kinematics", id(state), *map(id, polytopes)),
        (state, *polytopes),
        lambda: _phase_kinematics(state, polytopes),
    )
    return kinematics


def plan_kinematics(
    character: Character, data: OfflineData, states: Sequence[ContactState]
) -> list[trajectory.Halfspaces | None]:
    """Per state, K c <= k (world frame) that a plan's COM keeps to while its contacts are
    held: :func:`phase_kinematics`, the COM at most ``COM_BELOW_STATES`` below the lower of
    the state's own COM and the next state's, and for a state entered by a step down (a limb
    put ``STEP_DOWN`` or more below where it left) at most ``COM_ABOVE_STATE`` above the
    state's own COM (the heights their whole-body postures were found at)."""
    out: list[trajectory.Halfspaces | None] = []
    last: dict[str, float] = {}  # per limb, the height of its latest contact
    for k, state in enumerate(states):
        kinematics = phase_kinematics(data, state)
        stepped_down = any(
            c.limb in last and c.placement[2, 3] <= last[c.limb] - tuning.STEP_DOWN
            for c in state.contacts
        )
        following = states[min(k + 1, len(states) - 1)]
        if kinematics is not None:
            kinematics = _per_state(
                ("heights", id(state), id(following), id(kinematics), id(character.model)),
                (state, following, kinematics, character.model),
                partial(_state_heights, character, state, following, kinematics, stepped_down),
            )
        out.append(kinematics)
        last.update((c.limb, float(c.placement[2, 3])) for c in state.contacts)
    return out


def _state_heights(
    character: Character,
    state: ContactState,
    following: ContactState,
    kinematics: trajectory.Halfspaces,
    capped: bool,
) -> trajectory.Halfspaces:
    """``kinematics`` with the COM's floor below ``state``'s and ``following``'s COMs and,
    when ``capped``, its ceiling above ``state``'s (:func:`plan_kinematics`)."""
    height = float(com_position(character.model, state.q)[2])
    lowest = min(height, float(com_position(character.model, following.q)[2]))
    rows = [[0.0, 0.0, -1.0]]
    bounds = [tuning.COM_BELOW_STATES - lowest]
    if capped:
        rows.append([0.0, 0.0, 1.0])
        bounds.append(height + tuning.COM_ABOVE_STATE)
    return trajectory.Halfspaces(
        np.vstack([kinematics.A, rows]), np.concatenate([kinematics.b, bounds])
    )


def _phase_kinematics(
    state: ContactState, polytopes: Sequence[Any]
) -> trajectory.Halfspaces | None:
    constraints = []
    for contact, polytope in zip(state.contacts, polytopes, strict=True):
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


def _last_contact(states: Sequence[ContactState], k: int, limb: str) -> LimbContact | None:
    """``limb``'s last contact up to state k, None if it held none."""
    return next((c for s in reversed(states[: k + 1]) if (c := s.contact(limb))), None)


def _last_placement(
    character: Character, states: Sequence[ContactState], k: int, limb: str, q: FloatArray
) -> FloatArray:
    """Where ``limb`` was last in contact up to state k, else where ``q`` puts it."""
    contact = _last_contact(states, k, limb)
    if contact is not None:
        return np.asarray(contact.placement)
    return frame_placement(character.model, q, character.limb(limb).effector_frame)


def _swing_length(character: Character, states: Sequence[ContactState], k: int, limb: str) -> float:
    """m, the length (``spec.swing_length``) of the swing of phase k, which puts ``limb``
    on its contact of state k + 1, along the normals of that contact and of the limb's last
    one before."""
    target = states[k + 1].contact(limb)
    assert target is not None
    last = _last_contact(states, k, limb)
    if last is None:  # never held: where the state's configuration puts it
        frame = character.limb(limb).effector_frame
        start = frame_placement(character.model, states[k].q, frame)
        return swing_length(start[:3, 3], target.position, [target.normal])
    return swing_length(last.position, target.position, [target.normal, last.normal])


def user_transitions(
    phases: Sequence[trajectory.ContactPhase],
    kinematics: Sequence[trajectory.Halfspaces | None],
    attractors: Sequence[tuple[int, FloatArray]],
) -> tuple[list[FloatArray | None] | None, list[dict[str, object]]]:
    """The user's transition points that hold (one entry per phase change, None where the
    planner chooses) and, per attractor, whether it was honoured and why not."""
    if not attractors:
        return None, []
    count = len(phases) - 1
    placed: list[FloatArray | None] = [None] * count
    report: list[dict[str, object]] = []
    for index, point in attractors:
        entry: dict[str, object] = {"transition": int(index), "honoured": False}
        report.append(entry)
        if not 0 <= index < count:
            entry["reason"] = f"the plan has {count} phase changes (0 to {count - 1})"
            continue
        if placed[index] is not None:
            entry["reason"] = "another attractor already placed this transition"
            continue
        kins = [k for k in (kinematics[index], kinematics[index + 1]) if k is not None]
        check = trajectory.check_transition_point(
            np.asarray(point, dtype=np.float64),
            [trajectory.equilibrium_halfspaces(phases[i]) for i in (index, index + 1)],
            kins,
        )
        if not check.feasible:
            entry["reason"] = (
                f"not in static equilibrium for both phases (off by {check.slack:.3f} m)"
                if check.slack > 0
                else f"out of the limbs' reach (off by {check.kinematic_slack:.3f} m)"
            )
            continue
        placed[index] = np.asarray(point, dtype=np.float64)
        entry["honoured"] = True
    return placed, report


def _chest_turns_s(character: Character, states: Sequence[ContactState]) -> list[float]:
    """Per state, the s the chest takes at ``CHEST_SPEED`` to stand back up to the reference
    posture where that state or the next one has it there after a bent one (the contact
    planner stands the chest up once the hands let go: ``generation.stand_up``); it stands
    up in the phase before that state or the one after (while the hand lets go, or once it
    has). 0 elsewhere (the states' own chest sway is not followed by the tracker, which holds
    the chest near the reference) and for a character without a chest."""
    model = character.model
    columns = torso_columns(character, int(model.nvs[1]))
    out = [0.0] * len(states)
    if not columns:
        return out
    reference = np.asarray(character.q_ref)
    for b in range(1, len(states)):
        after = np.asarray(states[b].q)
        if np.abs(pin.difference(model, reference, after)[columns]).max() > 1e-9:
            continue
        step = pin.difference(model, np.asarray(states[b - 1].q), after)
        seconds = float(np.abs(step[columns]).max()) / tuning.CHEST_SPEED
        out[b - 1], out[b] = max(out[b - 1], seconds), max(out[b], seconds)
    return out


def swing_durations(
    character: Character, states: Sequence[ContactState], speed: float = 1.0
) -> list[float]:
    """Per state, the shortest its phase may last (s): a phase whose limb swings to the next
    state's contact gets ``MIN_SWING_S`` or the swing distance at ``SWING_SPEED``, whichever
    is longer, other phases ``MIN_SHIFT_S``; all divided by ``speed``; and at least the
    chest's standing up (:func:`_chest_turns_s`)."""
    out = []
    turns = _chest_turns_s(character, states)
    for k in range(len(states)):
        chest = turns[k]
        limb = _swinging_limb(states, k)
        if limb is None:
            out.append(max(tuning.MIN_SHIFT_S / speed, chest))
            continue
        reach = _swing_length(character, states, k, limb)
        out.append(max(max(tuning.MIN_SWING_S, reach / tuning.SWING_SPEED) / speed, chest))
    return out


def dynamic_durations(
    character: Character,
    states: Sequence[ContactState],
    speed: float = 1.0,
    pairs: Collection[int] = (),
) -> list[float]:
    """Per state, how long its phase lasts when the COM moves dynamically (s): a swing
    ``DYNAMIC_MIN_SWING_S`` or its distance at ``DYNAMIC_SWING_SPEED``, whichever is longer,
    a shift ``DYNAMIC_SHIFT_S``, all divided by ``speed``, and at least the chest's turn
    (:func:`_chest_turns_s`); the first and last phase at least ``DYNAMIC_END_S`` whatever
    the speed. ``pairs`` : the first phase of each pair of overlapped swings
    (``overlap.Overlap``, ``states`` its states): that phase and the third last
    ``OVERLAP_LEAD_S`` each, the second (both legs in the air) the longer of the two swings
    less that, the shift before the pair ``OVERLAP_SHIFT_S``."""
    out = []
    turns = _chest_turns_s(character, states)
    swings = []
    for k in range(len(states)):
        limb = _swinging_limb(states, k)
        duration = tuning.DYNAMIC_SHIFT_S
        if limb is not None:
            reach = _swing_length(character, states, k, limb)
            duration = max(tuning.DYNAMIC_MIN_SWING_S, reach / tuning.DYNAMIC_SWING_SPEED)
        swings.append(duration)
    lead = tuning.OVERLAP_LEAD_S
    for first in pairs:
        both = max(swings[first + 1], swings[first + 2])
        swings[first] = swings[first + 2] = lead
        swings[first + 1] = max(both - lead, lead)
        if first >= 2 and _swinging_limb(states, first - 1) is None:
            swings[first - 1] = tuning.OVERLAP_SHIFT_S  # the weight shift before the pair
    for k, duration in enumerate(swings):
        duration = max(duration / speed, turns[k])
        if k in (0, len(states) - 1):  # starting from rest and stopping take their time
            duration = max(duration, tuning.DYNAMIC_END_S)
        out.append(duration)
    return out


@dataclass(frozen=True, slots=True, eq=False)
class PlanCom:
    """What :func:`dynamic_com` found: ``curve`` (None when no curve passes), the
    ``factors`` on :func:`dynamic_durations` per phase (used, or the last tried),
    ``stretched`` True when they include the shifts' stretch (:func:`_shift_stretch`), the
    phases ``blamed`` by the certificates of the QPs found infeasible, the ``plain`` levels
    tried without the stretch (each plain try's slowest factor), in order, and whether the
    stretched levels were tried (``stretch_tried``)."""

    curve: trajectory.DynamicCom | None
    factors: list[float]
    stretched: bool
    blamed: set[int]
    plain: tuple[float, ...] = ()
    stretch_tried: bool = False

    def slowdown_note(self) -> str | None:
        """Why the durations are not the brisk ones (a ``dynamic_trials`` entry), or None."""
        if self.stretched or (self.curve is None and self.stretch_tried):
            return (
                f"no curve passes Eq. 1 at {_levels_text(self.plain)} times the brisk "
                "durations: tried again with the weight shifts lengthened to move the COM "
                f"between their states' at {tuning.DYNAMIC_SHIFT_SPEED:g} m/s"
            )
        if self.curve is not None and len(self.plain) > 1:
            return (
                f"no curve passes Eq. 1 at {_levels_text(self.plain[:-1])} times the brisk "
                "durations"
                + (", nor with the weight shifts stretched" if self.stretch_tried else "")
                + f": the whole plan slowed to {self.plain[-1]:g}"
            )
        return None

    def refusal(self) -> str:
        """Why no curve was kept (``dynamic_refused``), when ``curve`` is None."""
        return f"no curve passes Eq. 1 up to {max(self.plain):g} times the brisk durations" + (
            ", the weight shifts lengthened or not" if self.stretch_tried else ""
        )


def dynamic_com(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    speed: float = 1.0,
    factors: Sequence[float] | None = None,
    levels: Sequence[float] = tuning.DYNAMIC_SLOWDOWNS,
) -> PlanCom:
    """A COM through ``states`` whose wrench lies in each phase's contact cone (Eq. 1) at
    the collocation times of ``trajectory.dynamic_com``, near 2PAC's ``reference`` curve,
    phase j lasting :func:`dynamic_durations` times ``factors[j]`` (default: the first of
    ``levels`` for every phase). When no curve passes, the QP is solved again through
    ``levels`` with the weight shifts stretched to their COM's travel
    (:func:`_shift_stretch`), then with every phase slowed to each later level. The
    stretched shifts come before the slower plain levels: on rubble, where a double
    support moves the COM 0.4 m, a plan slowed as a whole still failed (three QPs lost) and
    one with its shifts stretched passed. The phases blamed are :func:`_blamed` of each
    infeasible QP's ``trajectory.DynamicOutcome.blame``."""
    n = len(states)
    plain: list[list[float]] = []
    trial: list[float] | None = list(factors) if factors is not None else [levels[0]] * n
    while trial is not None:
        plain.append(trial)
        trial = _slower(trial, 0, n, levels)
    blamed: set[int] = set()
    tried: list[float] = []  # the plain levels tried

    def attempt(used: list[float]) -> trajectory.DynamicCom | None:
        outcome = _dynamic_window(character, data, states, reference, speed, used, 0, n)
        if outcome.com is not None and outcome.com.valid:
            return outcome.com
        if outcome.blame is not None:
            blamed.update(_blamed(outcome.blame))
        return None

    tried.append(max(plain[0]))
    found = attempt(plain[0])
    if found is not None:
        return PlanCom(found, plain[0], False, set(), tuple(tried))
    stretch = _shift_stretch(character, states, speed)  # computed only once a level fails
    stretch_tried = max(stretch) > 1.0
    used = plain[0]
    for base in plain if stretch_tried else []:
        used = [f * s for f, s in zip(base, stretch, strict=True)]
        found = attempt(used)
        if found is not None:
            return PlanCom(found, used, True, set(), tuple(tried), True)
    for base in plain[1:]:
        tried.append(max(base))
        found = attempt(base)
        if found is not None:
            return PlanCom(found, base, False, set(), tuple(tried), stretch_tried)
        used = base
    return PlanCom(None, used, False, blamed, tuple(tried), stretch_tried)


def _levels_text(levels: Sequence[float]) -> str:
    """``levels`` as words: "0.75", "0.75 and 1", "0.75, 1 and 1.5"."""
    words = [f"{x:g}" for x in levels]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _shift_stretch(
    character: Character, states: Sequence[ContactState], speed: float
) -> list[float]:
    """Per phase, the factor (>= 1) on :func:`dynamic_durations` that gives a phase without a
    swing, other than the first and last, the time to move the COM from its state's COM to
    the next state's at ``DYNAMIC_SHIFT_SPEED`` times ``speed``."""
    brisk = dynamic_durations(character, states, speed)
    coms = [com_position(character.model, s.q) for s in states]
    out = [1.0] * len(states)
    for k in range(1, len(states) - 1):
        if _swinging_limb(states, k) is None:
            travel = float(np.linalg.norm(coms[k + 1] - coms[k]))
            out[k] = max(1.0, travel / (tuning.DYNAMIC_SHIFT_SPEED * speed) / brisk[k])
    return out


def redo_window(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    earlier: trajectory.DynamicCom,
    factors: Sequence[float],
    window: tuple[int, int],
    speed: float = 1.0,
) -> trajectory.DynamicCom | None:
    """``earlier``'s curve with the phases of ``window`` [lo, hi) found again, each lasting
    :func:`dynamic_durations` times ``factors[j]``, joined C2 to the phases before (kept as
    they are) and after (kept, shifted in time by what the window gained); None when no
    window curve passes Eq. 1. A window running to the end of ``states`` keeps nothing of
    ``earlier`` after it (``states`` may then differ from ``earlier``'s from ``lo`` on: a
    re-planned suffix)."""
    lo, hi = window
    found = _dynamic_window(
        character, data, states, reference, speed, factors, lo, hi, earlier.curve.segments
    ).com
    if found is None or not found.valid:
        return None
    old = earlier.phase_times
    segments = list(earlier.curve.segments[:lo])
    segments += [
        trajectory.BezierCurve(seg.control_points, seg.t0 + old[lo], seg.t1 + old[lo])
        for seg in found.curve.segments
    ]
    times = np.concatenate([old[: lo + 1], old[lo] + np.asarray(found.phase_times[1:])])
    if hi < len(states):
        shift = float(found.phase_times[-1]) - float(old[hi] - old[lo])
        segments += [
            trajectory.BezierCurve(seg.control_points, seg.t0 + shift, seg.t1 + shift)
            for seg in earlier.curve.segments[hi:]
        ]
        times = np.concatenate([times, old[hi + 1 :] + shift])
    return trajectory.DynamicCom(
        trajectory.PiecewiseBezier(tuple(segments)), times, found.iterations, True
    )


def _dynamic_window(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    speed: float,
    factors: Sequence[float],
    lo: int,
    hi: int,
    around: Sequence[trajectory.BezierCurve] | Mapping[int, trajectory.BezierCurve] = (),
) -> trajectory.DynamicOutcome:
    """The dynamic COM QP over phases [lo, hi) (times from 0), at rest at the plan's ends,
    joined C2 to ``around``'s segments lo - 1 and hi (an earlier curve, or the segments
    next to the window) elsewhere."""
    durations = np.asarray(dynamic_durations(character, states, speed)) * np.asarray(factors)
    before = around[lo - 1] if lo > 0 else None
    after = around[hi] if hi < len(states) else None
    start = (
        np.asarray(before.control_points[-1])
        if before is not None
        else com_position(character.model, states[0].q)
    )
    end = (
        np.asarray(after.control_points[0])
        if after is not None
        else com_position(character.model, states[-1].q)
    )
    return trajectory.solve_dynamic_com(
        [contact_phase(character, s) for s in states[lo:hi]],
        list(durations[lo:hi]),
        start,
        end,
        # from the first state (steps down before lo) to the one after the window (the floor
        # of its last phase)
        kinematics=plan_kinematics(character, data, states[: hi + 1])[lo:hi],
        reference=reference.curve,
        reference_times=list(reference.phase_times[lo : hi + 1]),
        settings=trajectory.DynamicSettings(sample_spacing=tuning.DYNAMIC_SAMPLE_SPACING),
        before=before,
        after=after,
    )


def _overlapped_com(
    character: Character,
    data: OfflineData,
    overlap: Overlap,
    reference: trajectory.ComTrajectory,
    durations: Sequence[float],
    factor: float,
    rate: float,
) -> trajectory.DynamicCom | None:
    """The dynamic COM QP through the states of ``overlap`` (at rest at both ends), phases
    lasting ``durations`` (s, :func:`dynamic_durations` with its pairs) times ``factor``, and
    at least ``OVERLAP_MIN_PERIODS`` keyframe periods at ``rate`` (1/s), near 2PAC's
    ``reference`` curve through the states first given (as many phases); None unless a
    curve passes Eq. 1 at every collocation time (``OVERLAP_ITERATIONS``, no margin)."""
    states = overlap.states
    shortest = tuning.OVERLAP_MIN_PERIODS / rate
    found = trajectory.dynamic_com(
        [contact_phase(character, s) for s in states],
        [max(d * factor, shortest) for d in durations],
        com_position(character.model, states[0].q),
        com_position(character.model, states[-1].q),
        kinematics=plan_kinematics(character, data, states),
        reference=reference.curve,
        reference_times=list(reference.phase_times),
        settings=trajectory.DynamicSettings(
            margin=0.0,
            iterations=tuning.OVERLAP_ITERATIONS,
            sample_spacing=tuning.OVERLAP_SAMPLE_SPACING,
        ),
    )
    return found if found is not None and found.valid else None


def _rest_point(model: Any, states: Sequence[ContactState], j: int) -> FloatArray:
    """(3,) m, where the COM may stop between phases j and j + 1 (j = -1: the start, j =
    n - 1: the end): the COM of state j + 1, which the contact planner balanced with a margin
    on both phases' contacts (a release shifts the COM over the contacts that stay; a
    creation is accepted only with the new COM over the contacts held before), and from
    which a limb just put down reaches its contact (its state's own posture). 2PAC's
    transition point lies on the edge of the smaller phase's support, where Eq. 1 with a
    margin has no solution."""
    n = len(states)
    if j < 0 or j >= n - 1:
        return com_position(model, states[0 if j < 0 else -1].q)
    return com_position(model, states[j + 1].q)


def _rest_window(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    earlier: trajectory.DynamicCom,
    factors: Sequence[float],
    window: tuple[int, int],
    speed: float = 1.0,
    resting: Collection[int] = (),
    levels: Sequence[float] = tuning.DYNAMIC_SLOWDOWNS,
) -> tuple[trajectory.DynamicCom, list[float], int] | None:
    """``earlier``'s curve with the phases of ``window`` [lo, hi) stopping between phases
    instead (a rest-to-rest quintic per phase from :func:`_rest_point` to the next, as
    2PAC's own fallback, each lasting at least :func:`swing_durations` and as long as in
    2PAC's ``reference``), and the dynamic phases on each side of the window found again,
    at rest at the window's ends and joined C2 to the rest: the phase next to the window,
    else ``REST_SIDE_BEFORE`` phases before it or every phase after it up to the next
    ``resting`` one, each slowed through ``levels`` until its QP passes Eq. 1 (a side
    already ``resting`` stops at the window's end too and is kept). The phases after the
    window are shifted in time. Returns the curve, the factors used and the first phase
    whose curve changed, or None when a side has no curve at any level.
    ``DynamicCom.valid`` then says only that the dynamic phases pass; the window's are
    quasi-static."""
    lo, hi = window
    n = len(states)
    degree = earlier.curve.segments[0].degree
    rested, rest_durations = _rest_run(character, states, reference, speed, window, degree)
    around = [*earlier.curve.segments[:lo], *rested, *earlier.curve.segments[hi:]]
    durations = np.diff(earlier.phase_times).tolist()
    durations[lo:hi] = rest_durations
    floor = max((j + 1 for j in resting if j < lo), default=0)
    ceiling = min((j for j in resting if j >= hi), default=n)
    sides = []
    if lo - 1 >= floor:
        sides.append(((lo - 1, lo), (max(floor, lo - tuning.REST_SIDE_BEFORE), lo)))
    if hi < ceiling:
        sides.append(((hi, hi + 1), (hi, ceiling)))
    used = list(factors)
    first = lo
    for options in sides:
        placed = False
        for a, b in dict.fromkeys(options):
            trial: list[float] | None = used
            while trial is not None and not placed:
                found = _dynamic_window(
                    character, data, states, reference, speed, trial, a, b, around
                ).com
                if found is not None and found.valid:
                    around[a:b] = found.curve.segments
                    durations[a:b] = np.diff(found.phase_times).tolist()
                    used, placed, first = trial, True, min(first, a)
                trial = _slower(trial, a, b, levels)
            if placed:
                break
        if not placed:
            return None
    start = float(earlier.phase_times[0])
    times = np.concatenate([[start], start + np.cumsum(durations)])
    segments = tuple(
        seg.retimed(float(times[j]), float(times[j + 1])) for j, seg in enumerate(around)
    )
    spliced = trajectory.DynamicCom(
        trajectory.PiecewiseBezier(segments), times, earlier.iterations, earlier.valid
    )
    return spliced, used, first


def _rest_run(
    character: Character,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    speed: float,
    window: tuple[int, int],
    degree: int,
) -> tuple[list[trajectory.BezierCurve], list[float]]:
    """The phases of ``window`` [lo, hi) stopping at rest between phases (2PAC's fallback):
    a rest-to-rest quintic per phase from :func:`_rest_point` to the next, raised to
    ``degree``, each lasting at least :func:`swing_durations` and as long as in 2PAC's
    ``reference``. Returns (the segments, their durations in s)."""
    lo, hi = window
    points = [_rest_point(character.model, states, j) for j in range(lo - 1, hi)]
    rest, rest_times = rest_to_rest(
        np.stack(points),
        min_durations=np.maximum(
            swing_durations(character, states, speed)[lo:hi],
            np.diff(reference.phase_times)[lo:hi],
        ).tolist(),
        max_acceleration=tuning.FALLBACK_MAX_ACCELERATION,
    )
    rested = [seg.elevate(degree - seg.degree) for seg in rest.segments]
    return rested, np.diff(rest_times).tolist()


def _runs(phases: Collection[int]) -> list[tuple[int, int]]:
    """The maximal runs [lo, hi) of consecutive integers in ``phases``, in order."""
    runs: list[tuple[int, int]] = []
    for j in sorted(phases):
        if runs and runs[-1][1] == j:
            runs[-1] = (runs[-1][0], j + 1)
        else:
            runs.append((j, j + 1))
    return runs


def _blamed(blame: FloatArray, offset: int = 0) -> set[int]:
    """The phases (indices plus ``offset``) carrying ``tuning.REST_BLAME_SHARE`` of
    ``blame`` (per phase, summing to 1), the largest first."""
    order = np.argsort(-blame, kind="stable")
    count = int(np.searchsorted(np.cumsum(blame[order]), tuning.REST_BLAME_SHARE)) + 1
    return {offset + int(j) for j in order[: min(count, blame.size)]}


def _gaps_filled(phases: Collection[int]) -> set[int]:
    """``phases`` with every gap of one phase between two of them filled (a lone dynamic
    phase between two stops at rest starts and ends at rest: nothing to gain)."""
    out = set(phases)
    return out | {j + 1 for j in out if j + 1 not in out and j + 2 in out}


def _resting_where_blamed(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    reference: trajectory.ComTrajectory,
    speed: float,
    blamed: Collection[int],
    levels: Sequence[float] = tuning.DYNAMIC_SLOWDOWNS,
) -> tuple[trajectory.DynamicCom, list[float], set[int]] | None:
    """A curve through ``states`` when the dynamic COM QP of the whole plan has no solution
    at any of ``levels``: the phases its certificates blame (``blamed``: :func:`_blamed` at
    each level) stop at rest between phases (:func:`_rest_run`), and each run of phases
    between them gets its own dynamic curve, at rest at its ends, slowed through ``levels``
    until its QP passes Eq. 1. A run with no curve at any level has the phases blamed at its
    levels stop too, ``REST_BLAME_ROUNDS`` times at most. Returns (the curve, whose ``valid``
    says only that its dynamic phases pass, the factors used, the phases stopping at rest),
    or None (also when every phase would stop: 2PAC's curve, through its own transition
    points, is then the better fallback)."""
    n = len(states)
    degree = trajectory.DynamicSettings().degree
    resting = _gaps_filled(blamed)
    for _ in range(tuning.REST_BLAME_ROUNDS):
        segments: dict[int, trajectory.BezierCurve] = {}
        durations: dict[int, float] = {}
        for lo, hi in _runs(resting):
            rested, rest_durations = _rest_run(
                character, states, reference, speed, (lo, hi), degree
            )
            segments.update(zip(range(lo, hi), rested, strict=True))
            durations.update(zip(range(lo, hi), rest_durations, strict=True))
        used = [levels[0]] * n
        iterations = 0
        more: set[int] = set()
        for lo, hi in _runs(set(range(n)) - resting):
            trial: list[float] | None = used
            blamed_here: set[int] = set()
            while trial is not None:
                outcome = _dynamic_window(
                    character, data, states, reference, speed, trial, lo, hi, segments
                )
                found = outcome.com
                if found is not None and found.valid:
                    segments.update(zip(range(lo, hi), found.curve.segments, strict=True))
                    durations.update(zip(range(lo, hi), np.diff(found.phase_times), strict=True))
                    used, iterations = trial, max(iterations, found.iterations)
                    break
                if outcome.blame is not None:
                    blamed_here |= _blamed(outcome.blame, lo)
                trial = _slower(trial, lo, hi, levels)
            else:  # no curve at any level
                if not blamed_here:
                    return None
                more |= blamed_here
        if not more:
            if len(resting) == n:  # no dynamic phase left: 2PAC's own curve does better
                return None
            times = np.concatenate([[0.0], np.cumsum([durations[j] for j in range(n)])])
            curve = trajectory.PiecewiseBezier(
                tuple(segments[j].retimed(float(times[j]), float(times[j + 1])) for j in range(n))
            )
            return trajectory.DynamicCom(curve, times, iterations, True), used, resting
        resting = _gaps_filled(resting | more)
    return None


def _slower(
    factors: Sequence[float], lo: int, hi: int, levels: Sequence[float]
) -> list[float] | None:
    """``factors`` with phases [lo, hi) slowed to at least the level after the fastest of
    them; None past the last of ``levels``."""
    above = [level for level in levels if level > min(factors[lo:hi]) + 1e-12]
    if not above:
        return None
    return [max(f, above[0]) if lo <= j < hi else f for j, f in enumerate(factors)]


def timed_com(
    character: Character,
    data: OfflineData,
    states: Sequence[ContactState],
    timing: Timing,
    min_durations: Sequence[float],
) -> tuple[trajectory.ComTrajectory, list[dict[str, object]]]:
    """2PAC's sliding window through ``states`` (one phase each, at least one) from the COM
    of the first to the COM of the last, at rest at both ends: ``timing.speed`` times the
    nominal pace (``tuning.SECONDS_PER_METRE``), phase k lasting at least
    ``min_durations[k]`` s, transition points by ``timing.cost`` aiming at the COM of the
    state after next, or the user's (``timing.attractors``). Returns the trajectory (no
    dynamic report: see ``trajectory.validate_dynamics``) and, per attractor, whether it was
    honoured and why not."""
    speed = timing.speed
    phases_tr = [contact_phase(character, s) for s in states]
    kinematics = plan_kinematics(character, data, states)
    coms = [com_position(character.model, s.q) for s in states]
    placed, attractor_report = user_transitions(phases_tr, kinematics, timing.attractors)
    com_trajectory = trajectory.plan_com_trajectory(
        phases_tr,
        coms[0],
        coms[-1],
        kinematics=kinematics,
        cost=timing.cost,
        user_transitions=placed,
        targets=[coms[min(j + 2, len(states) - 1)] for j in range(len(states) - 1)],
        min_durations=list(min_durations),
        seconds_per_metre=tuning.SECONDS_PER_METRE / speed,
        min_window=tuning.MIN_SHIFT_S / speed,
        max_stretch=tuning.MAX_WINDOW_STRETCH,
        max_speed=tuning.MAX_COM_SPEED * speed,
        max_acceleration=tuning.FALLBACK_MAX_ACCELERATION,
        n_checks=0,
    )
    return com_trajectory, attractor_report


def _com_method(methods: Sequence[str]) -> str:
    """The plan's COM method from its phases': "2pac+dynamic" (2PAC's transition points
    and curve refined under Eq. 1), "2pac+dynamic+rest_to_rest" when windows of that curve
    stop between phases, "2pac", or "2pac+rest_to_rest" when a window of 2PAC's fell back."""
    if all(m == "2pac+dynamic" for m in methods):
        return "2pac+dynamic"
    if "2pac+dynamic" in methods:
        return "2pac+dynamic+rest_to_rest"
    return "2pac" if all(m == "2pac" for m in methods) else "2pac+rest_to_rest"


@dataclass(frozen=True, slots=True)
class _Trial:
    """A trial build (abandoned at its first unclean phase) and what it animated: the
    dynamic curve, the factors on the brisk durations, the states, 2PAC's curve through
    them and the phases stopping at rest."""

    built: BuiltMotion
    dynamic: trajectory.DynamicCom
    factors: list[float]
    states: list[ContactState]
    reference: trajectory.ComTrajectory
    attractors: list[dict[str, object]]
    resting: set[int]


def sequence_motion(
    character: Character,
    data: OfflineData,
    scene_bvh: Any,
    states: Sequence[ContactState],
    *,
    rate: float = 30.0,
    lift: float = tuning.SWING_LIFTS[0],
    obstacles: Sequence[tuple[Any, Any]] = (),
    timing: Timing | None = None,
    until: Termination = never,
    replan: Replanner | None = None,
) -> SequenceMotion:
    """COM trajectory and keyframes through ``states`` (at least one) in the scene
    ``scene_bvh`` (coal BVH), keyframes at ``rate`` Hz.

    The COM follows 2PAC's sliding window at ``timing.speed`` times the nominal pace
    (``tuning.SECONDS_PER_METRE``), every phase lasting at least what its swing needs
    (:func:`swing_durations`); a window that cannot give its phases that time stops at its
    transition points instead (reported per phase). Transition points use ``timing.cost``
    (default "tired": between the previous point and the COM of the state after next, so
    the COM travels over the stance while a limb swings) unless the user placed them.
    If ``until`` (polled once per keyframe tracked) fires while keyframes are computed, the
    remaining phases keep their COM curve but get no keyframes; the report says how many
    phases were animated.

    A walker on four legs or more first tries its swings overlapped where ``timing.overlap``
    and the ground allow (:func:`planner.motion.overlap.overlap_swings`): the dynamic curve
    through the overlapped states at each of ``OVERLAP_PACES`` in turn, kept with the first
    trial build that comes clean (the answer's ``states`` stay the ones given, its phases
    hold the overlapped ones); otherwise the swings go one at a time as follows.

    Where a phase cannot be played cleanly even slowed and stopping at rest, ``replan``
    (when given) is asked for other contact changes from there on (2PAC 7.2's last
    resort): the dynamic curve is found again from the first changed phase, joined C2 to
    the curve before, whose keyframes are kept. When no dynamic curve comes clean, 2PAC's
    curve through the states first given is built whole (again with each keyframe's stance
    set back on its contacts when it is not clean as it is); where that is not clean either
    and contact changes were re-planned, 2PAC's curve through the re-planned states is built
    too and kept when it is clean (else the re-plans are undone). The report lists the
    re-plans (``contact_replans``) and the answer's ``states`` are the ones animated.
    """
    if not states:
        raise ValueError("states: at least one contact state is needed")
    states = list(states)
    timing = timing or Timing()
    speed = timing.speed
    phases_tr = [contact_phase(character, s) for s in states]
    com_trajectory, attractor_report = timed_com(
        character, data, states, timing, swing_durations(character, states, speed)
    )

    def build(
        curve: trajectory.PiecewiseBezier,
        times: FloatArray,
        trial: bool = False,
        resume: tuple[BuiltMotion, int] | None = None,
        overlap: Overlap | None = None,
        set_back: bool = False,
    ) -> BuiltMotion:
        """The whole-body motion along ``curve``; a ``trial`` (a dynamic curve) holds its
        stance contacts rigidly and is abandoned at its first unclean phase; with
        ``set_back``, each keyframe's stance is set back on its contacts
        (``MotionSpec.hold_stance``, :func:`last_resort`). ``resume`` keeps an earlier
        build's keyframes before a phase (``build_motion``); ``overlap``: the phases hold
        its states, its pairs of swings overlapping."""
        held = list(overlap.states) if overlap is not None else states
        # the second and third phase of an overlapped pair land swings that lifted off a
        # phase earlier
        late = {k for first in (overlap.pairs if overlap else ()) for k in (first + 1, first + 2)}
        swings: dict[int, Swing] = {}
        for k in range(len(held)):
            swing_limb = _swinging_limb(held, k)
            if swing_limb is not None:
                target = held[k + 1].contact(swing_limb)
                assert target is not None
                start = _last_placement(character, held, k, swing_limb, held[k].q)
                lift_off = float(times[k - 1]) if k in late else None
                swings[k] = Swing(swing_limb, start, np.asarray(target.placement), lift, lift_off)
        spec_phases = []
        for k, state in enumerate(held):
            aim = held[min(k + 1, len(held) - 1)]
            early = swings.get(k + 1) if k + 1 in late else None
            moving = [x.limb for x in (swings.get(k), early) if x is not None]
            posture = natural_posture(character, np.asarray(aim.q), [*aim.limbs, *moving])
            spec_phases.append(
                MotionPhase(
                    float(times[k]),
                    float(times[k + 1]),
                    state.contacts,
                    posture,
                    swings.get(k),
                    rigid_stance=trial,
                    early=early,
                )
            )
        spec = MotionSpec(
            np.asarray(states[0].q), tuple(spec_phases), curve, rate, hold_stance=set_back
        )
        return build_motion(
            character,
            scene_bvh,
            spec,
            obstacles=obstacles,
            until=until,
            abandon_unclean=trial,
            resume=resume,
        )

    def last_resort(curve: trajectory.PiecewiseBezier, times: FloatArray) -> BuiltMotion:
        """2PAC's ``curve`` built whole (phase ``times``); when that is not clean, built
        again with each keyframe's stance set back on its contacts, kept when that one is
        clean. On the climbing wall a start nudged 5 mm slipped a stance contact 5.7 mm on
        that curve, over the 5 mm tolerance (1.5 mm set back); on the quadruped's rubble,
        two nudged starts played cleanly as they were and collided set back."""
        plain = build(curve, times)
        if plain.report.complete or plain.report.cut_short:
            return plain
        set_back = build(curve, times, set_back=True)
        return set_back if set_back.report.complete else plain

    built: BuiltMotion | None = None
    factors: list[float] | None = None
    dynamic_refused: str | None = None
    # trial builds: a dynamic curve at brisk durations; where the body cannot follow it,
    # the failing phase and its neighbours are slowed to the next level and their curve found
    # again, joined to the rest, the keyframes before them kept (a fallback per window)
    levels = tuning.DYNAMIC_SLOWDOWNS
    trials: list[str] = []  # why each refused trial was refused
    n = len(states)
    dynamic: trajectory.DynamicCom | None = None
    factors_tried: list[float] = []
    overlapped: Overlap | None = None
    resting: set[int] = set()  # phases stopping at rest between phases (2PAC's fallback)
    # a walker's swings overlapped first where the ground allows (``overlap``): kept when
    # its curve passes Eq. 1 and its one trial build comes clean, else the plan goes on
    # with its swings one at a time
    overlap = overlap_swings(character, states) if timing.overlap else None
    brisk = (
        []
        if overlap is None
        else dynamic_durations(character, overlap.states, speed, overlap.pairs)
    )
    for factor in tuning.OVERLAP_PACES if overlap is not None else ():
        assert overlap is not None
        overlap_com = _overlapped_com(character, data, overlap, com_trajectory, brisk, factor, rate)
        if overlap_com is None:
            trials.append(f"overlapped swings at {factor:g}: no curve passes Eq. 1")
            continue
        times_o = np.asarray(overlap_com.phase_times, dtype=np.float64)
        candidate = build(overlap_com.curve, times_o, trial=True, overlap=overlap)
        why = candidate.report.shortfall()
        if why is not None and not candidate.report.cut_short:
            trials.append(f"overlapped swings at {factor:g}: {why}")
            continue
        built, factors = candidate, [factor] * n
        curve, times = overlap_com.curve, times_o
        methods = ("2pac+dynamic",) * n
        overlapped = overlap
        break
    if n >= 2 and built is None:
        whole = dynamic_com(character, data, states, com_trajectory, speed, None, levels)
        dynamic, factors_tried, blamed = whole.curve, whole.factors, whole.blamed
        note = whole.slowdown_note()
        if note is not None:
            trials.append(note)
        if dynamic is None:
            dynamic_refused = whole.refusal()
            trials.append(dynamic_refused)
            # the phases its infeasibility certificate blames stop at rest, the dynamic curve
            # found between them (a fallback per window)
            split = (
                _resting_where_blamed(
                    character, data, states, com_trajectory, speed, blamed, levels
                )
                if blamed
                else None
            )
            if split is not None:
                dynamic, factors_tried, at_rest = split
                resting.update(at_rest)
                runs = ", ".join(f"{lo} to {hi - 1}" for lo, hi in _runs(at_rest))
                trials.append(
                    f"phases {runs} stop at rest between phases (the phases Eq. 1's "
                    "infeasibility certificate weighs most), the dynamic curve found between"
                )
    keep: tuple[BuiltMotion, int] | None = None
    last: _Trial | None = None  # the last trial build, and what it was built from
    replans: list[str] = []
    original = (states, com_trajectory, attractor_report)

    def _replanned(bad: int) -> tuple[trajectory.DynamicCom, list[float], int] | None:
        # other contact changes from the phase that fails on: the new states, their 2PAC
        # curve, and the dynamic curve found again from the first changed phase on (slowed
        # through the levels as needed), joined C2 to the curve before it
        nonlocal states, n, phases_tr, com_trajectory, attractor_report
        assert dynamic is not None
        if replan is None:
            return None
        first_com = original[1]
        reserve = float(first_com.phase_times[-1] - first_com.phase_times[0])
        new_states = list(replan(states, bad, reserve) or ())
        if not new_states:
            trials.append(
                f"phase {bad}: not re-planned (no other contact changes found, "
                "or no walks or work left for them)"
            )
            return None
        same = next(
            (j for j, (a, b) in enumerate(zip(states, new_states, strict=False)) if a is not b),
            min(len(states), len(new_states)),
        )
        lo = max(0, same - 1)  # the phase before the first changed state heads elsewhere
        new_com, new_attractors = timed_com(
            character, data, new_states, timing, swing_durations(character, new_states, speed)
        )
        end = len(new_states)
        used: list[float] | None = [*factors_tried[:lo], *[levels[0]] * (end - lo)]
        spliced: trajectory.DynamicCom | None = None
        while used is not None and spliced is None:
            spliced = redo_window(
                character, data, new_states, new_com, dynamic, used, (lo, end), speed
            )
            if spliced is None:
                used = _slower(used, lo, end, levels)
        if spliced is None or used is None:
            trials.append(f"phases {same} on re-planned: no dynamic curve joins them")
            return None
        replans.append(
            f"phase {bad} could not be played: the contact changes from state {same} on "
            f"were planned again ({len(states) - same} states replaced by "
            f"{len(new_states) - same})"
        )
        states, n = new_states, len(new_states)
        phases_tr = [contact_phase(character, s) for s in states]
        com_trajectory, attractor_report = new_com, new_attractors
        resting.difference_update([j for j in resting if j >= lo])
        return spliced, used, lo

    builds = max(tuning.DYNAMIC_MAX_BUILDS, math.ceil(tuning.DYNAMIC_BUILDS_PER_PHASE * n))
    if built is not None:
        builds = 0
    tried = 0
    while tried < builds + tuning.DYNAMIC_MAX_BUILDS * len(replans):  # re-plans add builds
        tried += 1
        if dynamic is None:
            break
        times_d = np.asarray(dynamic.phase_times, dtype=np.float64)
        candidate = build(dynamic.curve, times_d, trial=True, resume=keep)
        unplayable = candidate.report.shortfall()  # says why a trial was abandoned
        last = _Trial(
            candidate,
            dynamic,
            list(factors_tried),
            list(states),
            com_trajectory,
            attractor_report,
            set(resting),
        )
        if unplayable is None or candidate.report.cut_short:
            if replans and unplayable is not None:
                break  # cut short after re-planning: 2PAC's curve, built whole, is kept
            built, factors = candidate, factors_tried
            curve, times = dynamic.curve, times_d
            methods = tuple("rest_to_rest" if j in resting else "2pac+dynamic" for j in range(n))
            break
        bad = candidate.report.abandoned_phase
        if bad is None:  # not abandoned (a shortfall only the whole motion shows)
            bad = max(0, candidate.report.phases_animated - 1)
        dynamic_refused = (
            f"phase {bad} at {factors_tried[bad]:g} times the brisk durations: {unplayable}"
        )
        trials.append(dynamic_refused)
        if bad in resting:
            trials.append(f"phase {bad} fails even stopping at rest")
            replanned = _replanned(bad)
            if replanned is None:
                break
            dynamic, factors_tried, keep = replanned[0], replanned[1], (candidate, replanned[2])
            continue
        # the window around the failing phase, short of the phases already stopping
        floor = max((j + 1 for j in resting if j < bad), default=0)
        ceiling = min((j for j in resting if j > bad), default=n)
        lo = max(floor, bad - tuning.DYNAMIC_WINDOW_BEFORE)
        near = min(ceiling, bad + 1 + tuning.DYNAMIC_WINDOW_AFTER)
        found: trajectory.DynamicCom | None = None
        why = f"phases {lo} on: no slower level left"
        for hi in dict.fromkeys((near, ceiling)):
            slower = _slower(factors_tried, lo, hi, levels)
            if slower is None:
                break
            found = redo_window(
                character, data, states, com_trajectory, dynamic, slower, (lo, hi), speed
            )
            if found is not None:
                factors_tried = slower
                break
            why = f"no curve passes Eq. 1 slower from phase {lo} on"
        if found is not None:
            dynamic, keep = found, (candidate, lo)
            continue
        # slowing cannot help: the window stops at rest between its phases (2PAC's fallback),
        # the dynamic curve kept on both sides of it
        stopped = _rest_window(
            character,
            data,
            states,
            com_trajectory,
            dynamic,
            factors_tried,
            (lo, near),
            speed,
            resting,
            levels,
        )
        if stopped is None:
            trials.append(f"{why}; no dynamic curve joins a stop at phases {lo} to {near - 1}")
            replanned = _replanned(bad)
            if replanned is None:
                break
            dynamic, factors_tried, keep = replanned[0], replanned[1], (candidate, replanned[2])
            continue
        trials.append(f"{why}: phases {lo} to {near - 1} stop at rest between phases")
        resting.update(range(lo, near))
        dynamic, factors_tried, first = stopped
        keep = (candidate, first)
    else:
        if dynamic is not None and n >= 2:
            trials.append(f"no clean curve after {tried} trial builds")
    if built is None and trials:
        dynamic_refused = trials[-1]
    if built is None:
        # 2PAC's curve through the states first given (contact changes re-planned for a
        # dynamic curve that did not come clean are undone, unless those states do not
        # play cleanly on it and the re-planned ones do)
        after_replans = (states, com_trajectory, attractor_report)
        states, com_trajectory, attractor_report = original
        n, phases_tr = len(states), [contact_phase(character, s) for s in states]
        curve = com_trajectory.curve
        times = np.asarray(com_trajectory.phase_times, dtype=np.float64)
        methods = com_trajectory.phase_methods
        built = last_resort(curve, times)
        kept_replans = False
        if replans and not built.report.complete and not built.report.cut_short:
            # the states first given are not played cleanly even on 2PAC's curve, and a
            # phase the trials could not play was planned again: 2PAC's curve through the
            # re-planned states, kept if it is clean
            states, com_trajectory, attractor_report = after_replans
            curve = com_trajectory.curve
            times = np.asarray(com_trajectory.phase_times, dtype=np.float64)
            other = last_resort(curve, times)
            kept_replans = other.report.complete
            if kept_replans:
                built, methods = other, com_trajectory.phase_methods
                n, phases_tr = len(states), [contact_phase(character, s) for s in states]
            else:
                states, com_trajectory, attractor_report = original
                curve = com_trajectory.curve
                times = np.asarray(com_trajectory.phase_times, dtype=np.float64)
        if kept_replans:
            replans.append(
                "no clean dynamic curve, and the states first given are not played cleanly "
                "on 2PAC's curve: the re-planned changes are kept, on 2PAC's curve"
            )
        elif last is not None and last.built.report.phases_animated > built.report.phases_animated:
            # the work ran out before 2PAC's curve got as far as the last trial: that trial
            # (clean up to the phase it was abandoned at) is the answer
            built, factors = last.built, last.factors
            states, com_trajectory, attractor_report = last.states, last.reference, last.attractors
            n, phases_tr = len(states), [contact_phase(character, s) for s in states]
            curve = last.dynamic.curve
            times = np.asarray(last.dynamic.phase_times, dtype=np.float64)
            methods = tuple(
                "rest_to_rest" if j in last.resting else "2pac+dynamic" for j in range(n)
            )
            trials.append(
                "the work ran out before 2PAC's curve was animated as far as the last trial: "
                f"that trial's {built.report.phases_animated} phases are kept"
            )
        elif replans:
            replans.append("no clean dynamic curve with the re-planned changes: all undone")
    if overlapped is not None:
        phases_tr = [contact_phase(character, s) for s in overlapped.states]
    reports = trajectory.validate_dynamics(curve, phases_tr, times)
    report: dict[str, object] = {
        **built.report.as_dict(),
        "com_method": _com_method(methods),
        "dynamic_slowdown": None if factors is None else max(factors),
        "dynamic_slowdowns": factors,
        "dynamic_trials": trials,
        "contact_replans": replans,
        "dynamic_refused": None if factors is not None else dynamic_refused,
        "quasi_static_feasible": bool(com_trajectory.quasi_static_feasible),
        "transition_slack": [float(t.slack) for t in com_trajectory.transitions],
        "phase_methods": list(methods),
        "overlapped_swings": 0 if overlapped is None else len(overlapped.pairs),
        # the phases with both legs of a pair up (their contacts are not their states')
        "overlapped_phases": [] if overlapped is None else [k + 1 for k in overlapped.pairs],
        "speed": speed,
        "transition_cost": timing.cost.kind,
        "attractors": attractor_report,
        "dynamic_validity": [
            {
                "fraction_valid": float(r.fraction_valid),
                "worst_violation": float(r.worst_violation),
            }
            for r in reports
        ],
    }
    return SequenceMotion(
        built.phases, built.com, built.keyframes, report, built.report, tuple(states)
    )
