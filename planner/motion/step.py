"""The motion of one contact change (a Twister step) as a :class:`MotionSpec`, animated by
the one builder.

Two phases. The COM moves rest-to-rest (quintic) while the larger contact set holds it,
from the COM of ``before`` to the COM of ``after`` (a 2PAC transition point: in equilibrium
of the smaller set and in both kinematic COM polytopes, Eq. 5-6), so every phase passes
the dynamic check of Eq. 1:

- a creation swings the limb during the first phase (``before``'s contacts hold the body
  while the COM shifts), then settles on ``after``'s contacts;
- a break first shifts the COM over ``before``'s contacts, then lifts the limb off during
  the second phase (``after``'s contacts hold).

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
from planner.motion.sequence import contact_phase, rest_to_rest
from planner.motion.spec import MotionPhase, MotionSpec, Swing
from planner.termination import Termination, never

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BuiltStep:
    """A one-step motion: ``motion`` the builder's answer (keyframes from ``before.q`` to
    exactly ``after.q``), ``validity`` Eq. 1 per phase, ``swing_phase`` the index (0 or 1)
    of the phase in which ``limb`` swings, ``transition`` (3,) the COM where the contact
    changes (world, m)."""

    motion: BuiltMotion
    validity: tuple[trajectory.PhaseReport, ...]
    swing_phase: int
    transition: FloatArray

    @property
    def lift(self) -> float:
        """The swing's arc height (m) as tracked (raised when a lower arc collided)."""
        return self.motion.swing_lifts[self.swing_phase]


def step_spec(
    character: Character,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
) -> MotionSpec:
    """The two phases and the COM curve taking ``before`` to ``after``, which differ by
    ``limb``'s contact (created when ``after`` holds it, broken otherwise)."""
    model = character.model
    c0, c1 = com_position(model, before.q), com_position(model, after.q)
    creating = after.contact(limb) is not None
    if creating:
        durations = (tuning.STEP_MIN_SWING_S, tuning.STEP_MIN_SHIFT_S)
    else:
        durations = (tuning.STEP_MIN_SHIFT_S, tuning.STEP_MIN_SWING_S)
    curve, times = rest_to_rest(
        np.stack([c0, c1, c1]),
        min_durations=durations,
        max_acceleration=tuning.STEP_MAX_ACCELERATION,
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
    return MotionSpec(np.asarray(before.q, dtype=np.float64), phases, curve, rate, q_end=posture)


def build_step(
    character: Character,
    scene_bvh: Any,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
    obstacles: Sequence[tuple[Any, Any]] = (),
    until: Termination = never,
) -> BuiltStep:
    """Keyframes, phases and COM curve taking ``before`` to ``after`` in the scene
    ``scene_bvh`` (coal BVH) among static ``obstacles`` ((coal geometry, coal.Transform3s)
    pairs), every keyframe checked (see :func:`build_motion`)."""
    spec = step_spec(character, before, after, limb, rate=rate)
    motion = build_motion(character, scene_bvh, spec, obstacles=obstacles, until=until)
    times = np.array([spec.phases[0].t0, spec.phases[0].t1, spec.phases[1].t1])
    validity = trajectory.validate_dynamics(
        spec.com, [contact_phase(character, before), contact_phase(character, after)], times, 5
    )
    swing_phase = 0 if spec.phases[0].swing is not None else 1
    transition = com_position(character.model, after.q)
    return BuiltStep(motion, tuple(validity), swing_phase, transition)
