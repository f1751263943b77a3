"""The motion of one contact change (a Twister step) as a :class:`MotionSpec`, animated by
the one builder.

A step is a short plan of two phases, timed like a plan: the swing gets ``MIN_SWING_S`` or
its distance at ``SWING_SPEED``, ``Timing.speed`` divides the durations, and the user may
place the transition point (``Timing.attractors``, transition 0). The COM moves rest to
rest (quintic) through the transition point, from the COM of ``before`` to the COM of
``after`` (by default the transition point itself: in equilibrium of the smaller set and in
both kinematic COM polytopes, Eq. 5-6, as the contact planner validated), so every phase
passes the dynamic check of Eq. 1 (a 2PAC window through a single change, at rest at both
ends, measured slower and failing Eq. 1 on a quarter of the Twister moves):

- a creation swings the limb during the first phase (``before``'s contacts hold the body),
  then settles on ``after``'s contacts;
- a break shifts the COM during the first phase (``before``'s contacts hold), then lifts
  the limb off during the second (``after``'s contacts hold).

The motion ends exactly in ``after.q`` (the state the contact planner validated).
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
from planner.motion.builder import BuiltMotion, build_motion
from planner.motion.sequence import (
    Timing,
    contact_phase,
    phase_kinematics,
    rest_to_rest,
    user_transitions,
)
from planner.motion.spec import MotionPhase, MotionSpec, Swing, swing_length
from planner.offline import OfflineData
from planner.termination import Termination, never

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StepTiming:
    """How a step's COM was timed: ``method`` (rest to rest through one transition point:
    a single contact change starts and ends at rest), ``attractors`` per user attractor
    whether it was honoured and why not, ``brisk`` whether at a plan's brisk durations
    (:func:`brisk_step_durations`) rather than the slow fallback, ``validity`` Eq. 1 per
    phase at ``STEP_CHECKS`` times where already checked (empty otherwise)."""

    method: str
    attractors: tuple[dict[str, object], ...]
    brisk: bool = False
    validity: tuple[trajectory.PhaseReport, ...] = ()


@dataclass(frozen=True, slots=True)
class BuiltStep:
    """A one-step motion: ``motion`` the builder's answer (keyframes from ``before.q`` to
    exactly ``after.q``), ``validity`` Eq. 1 per phase, ``swing_phase`` the index (0 or 1)
    of the phase in which ``limb`` swings, ``transition`` (3,) the COM where the contact
    changes (world, m), ``timing`` how the COM was timed (:class:`StepTiming`)."""

    motion: BuiltMotion
    validity: tuple[trajectory.PhaseReport, ...]
    swing_phase: int
    transition: FloatArray
    timing: StepTiming

    @property
    def lift(self) -> float:
        """The swing's arc height (m) as tracked (raised when a lower arc collided)."""
        return self.motion.swing_lifts[self.swing_phase]


def _swing_reach(
    character: Character, before: ContactState, after: ContactState, limb: str
) -> float:
    """m, how far ``limb``'s effector travels from its pose in ``before`` to its pose in
    ``after`` (``spec.swing_length``)."""
    frame = character.limb(limb).effector_frame
    start = frame_placement(character.model, before.q, frame)[:3, 3]
    end = frame_placement(character.model, after.q, frame)[:3, 3]
    normals = [c.normal for c in (before.contact(limb), after.contact(limb)) if c is not None]
    return swing_length(start, end, normals)


def step_durations(
    character: Character, before: ContactState, after: ContactState, limb: str, speed: float
) -> tuple[float, float]:
    """The shortest each of the two phases may last (s), as in a plan: the swing
    ``MIN_SWING_S`` or its distance at ``SWING_SPEED`` (whichever is longer), divided by
    ``speed``; the other phase ``STEP_MIN_SHIFT_S`` divided by ``speed`` but no shorter
    than the blend into the validated state (``END_BLEND_S``)."""
    reach = _swing_reach(character, before, after, limb)
    swing = max(tuning.MIN_SWING_S, reach / tuning.SWING_SPEED)
    shift = max(tuning.STEP_MIN_SHIFT_S / speed, tuning.END_BLEND_S)
    if after.contact(limb) is not None:
        return swing / speed, shift
    return shift, swing / speed


def brisk_step_durations(
    character: Character, before: ContactState, after: ContactState, limb: str, speed: float
) -> tuple[float, float]:
    """The shortest each of the two phases may last (s) when the step is brisk, as a dynamic
    plan's phases (:func:`planner.motion.sequence.dynamic_durations`): the swing
    ``DYNAMIC_MIN_SWING_S`` or its distance at ``DYNAMIC_SWING_SPEED``, the other phase
    ``DYNAMIC_SHIFT_S``, both at least ``DYNAMIC_END_S`` (a step starts and ends at rest), all
    divided by ``speed``; the phase after the change at least ``END_BLEND_S`` (the blend into
    the validated state)."""
    reach = _swing_reach(character, before, after, limb)
    swing = max(tuning.DYNAMIC_MIN_SWING_S, reach / tuning.DYNAMIC_SWING_SPEED)
    shift = tuning.DYNAMIC_SHIFT_S
    first, second = (swing, shift) if after.contact(limb) is not None else (shift, swing)
    first, second = (max(d, tuning.DYNAMIC_END_S) / speed for d in (first, second))
    return first, max(second, tuning.END_BLEND_S)


def step_com(
    character: Character,
    data: OfflineData,
    before: ContactState,
    after: ContactState,
    limb: str,
    timing: Timing,
    brisk: bool = True,
) -> tuple[trajectory.PiecewiseBezier, FloatArray, StepTiming]:
    """The COM curve of a step, its (3,) phase times (s) and how it was timed: rest to rest
    from the COM of ``before`` through the transition point to the COM of ``after``.

    ``brisk``: each phase lasts :func:`brisk_step_durations` or longer so that the peak
    acceleration stays under the first of ``STEP_BRISK_ACCELERATIONS`` (times
    ``timing.speed`` squared) whose curve passes Eq. 1 at every time :func:`build_step`
    checks; when none does, or not ``brisk``, the slow fallback: :func:`step_durations`
    and ``STEP_MAX_ACCELERATION``. The transition point is the COM of ``after`` (the contact
    planner validated it), or the user's attractor for transition 0 when it is balanced and
    reachable for both phases."""
    c0 = com_position(character.model, before.q)
    c1 = com_position(character.model, after.q)
    placed: list[FloatArray | None] | None = None
    attractors: list[dict[str, object]] = []
    if timing.attractors:  # the polytopes are only needed to check the user's points
        placed, attractors = user_transitions(
            [contact_phase(character, before), contact_phase(character, after)],
            [phase_kinematics(data, before), phase_kinematics(data, after)],
            timing.attractors,
        )
    points = np.stack([c0, placed[0] if placed is not None and placed[0] is not None else c1, c1])
    squared = timing.speed**2
    if brisk:
        phases = [contact_phase(character, before), contact_phase(character, after)]
        durations = brisk_step_durations(character, before, after, limb, timing.speed)
        for acceleration in tuning.STEP_BRISK_ACCELERATIONS:
            curve, times = rest_to_rest(
                points, min_durations=durations, max_acceleration=acceleration * squared
            )
            checked = trajectory.validate_dynamics(curve, phases, times, tuning.STEP_CHECKS)
            if all(report.fraction_valid == 1.0 for report in checked):
                how = StepTiming("rest_to_rest", tuple(attractors), True, tuple(checked))
                return curve, times, how
    curve, times = rest_to_rest(
        points,
        min_durations=step_durations(character, before, after, limb, timing.speed),
        max_acceleration=tuning.STEP_MAX_ACCELERATION * squared,
    )
    return curve, times, StepTiming("rest_to_rest", tuple(attractors))


def step_spec(
    character: Character,
    data: OfflineData,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
    timing: Timing | None = None,
    brisk: bool = True,
) -> tuple[MotionSpec, StepTiming]:
    """The two phases and the COM curve taking ``before`` to ``after``, which differ by
    ``limb``'s contact (created when ``after`` holds it, broken otherwise); ``brisk`` as in
    :func:`step_com`."""
    model = character.model
    creating = after.contact(limb) is not None
    curve, times, how = step_com(
        character, data, before, after, limb, timing or Timing(), brisk=brisk
    )
    frame = character.limb(limb).effector_frame
    start = frame_placement(model, before.q, frame)
    end = frame_placement(model, after.q, frame)
    swing = Swing(limb, start, end, tuning.SWING_LIFTS[0])
    posture = np.asarray(after.q, dtype=np.float64)
    # the trunk heads for the state's own orientation: a step ends exactly there (a body on
    # hands and feet is pitched on purpose)
    swings = (swing, None) if creating else (None, swing)
    stances = (before.contacts, after.contacts)
    phases = tuple(
        MotionPhase(
            float(times[k]), float(times[k + 1]), stances[k], posture, swings[k], level_trunk=False
        )
        for k in range(2)
    )
    spec = MotionSpec(
        np.asarray(before.q, dtype=np.float64),
        phases,
        curve,
        rate,
        q_end=posture,
        substeps=tuning.STEP_SUBSTEPS,
        hold_stance=True,
    )
    return spec, how


def build_step(
    character: Character,
    data: OfflineData,
    scene_bvh: Any,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
    timing: Timing | None = None,
    obstacles: Sequence[tuple[Any, Any]] = (),
    until: Termination = never,
) -> BuiltStep:
    """Keyframes, phases and COM curve taking ``before`` to ``after`` in the scene
    ``scene_bvh`` (coal BVH) among static ``obstacles`` ((coal geometry, coal.Transform3s)
    pairs), every keyframe checked (see :func:`build_motion`). The step is brisk
    (:func:`step_com`); when that motion is not clean (a keyframe collides, a stance contact
    slips, a phase is missing), it is built again on the slow fallback timing, which is
    the answer then."""
    spec, how = step_spec(character, data, before, after, limb, rate=rate, timing=timing)
    motion = build_motion(character, scene_bvh, spec, obstacles=obstacles, until=until)
    if how.brisk and motion.report.shortfall() is not None and not motion.report.cut_short:
        spec, how = step_spec(
            character, data, before, after, limb, rate=rate, timing=timing, brisk=False
        )
        motion = build_motion(character, scene_bvh, spec, obstacles=obstacles, until=until)
    validity = how.validity
    if not validity:
        times = np.array([spec.phases[0].t0, spec.phases[0].t1, spec.phases[1].t1])
        phases = [contact_phase(character, before), contact_phase(character, after)]
        validity = tuple(trajectory.validate_dynamics(spec.com, phases, times, tuning.STEP_CHECKS))
    swing_phase = 0 if spec.phases[0].swing is not None else 1
    transition = com_position(character.model, after.q)
    return BuiltStep(motion, validity, swing_phase, transition, how)
