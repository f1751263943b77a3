"""The motion of one contact change, with the contact layer's part of 2PAC 7.2.

The phases, COM curve and keyframes come from the one motion builder
(:func:`planner.motion.step.build_step`). When keyframes still collide there (the builder has
already re-tracked the swing higher), the transition point (the COM of ``after``) is moved
along the obstacle normal, the state re-posed over the same contacts and the motion rebuilt
(2PAC section 7.2); colliding contact postures were re-sampled earlier, in
``generation.create_contact``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.contact.checks import (
    KINEMATIC_TOLERANCE,
    balance_margin,
    check_state,
    com_of,
    effector_pose,
    kinematics_of,
    obstacle_normal,
)
from planner.contact.context import ContactContext
from planner.contact.generation import balance_ik
from planner.contact.reachability import ground_limbs
from planner.contact.state import ContactState
from planner.kinematics import FramePlacementTask, Priority
from planner.motion import ComSegment, Keyframe, Phase
from planner.motion.sequence import Timing
from planner.motion.step import BuiltStep, build_step

FloatArray = NDArray[np.float64]

_TRANSITION_SHIFTS = (0.03, 0.06)  # m, moves of the transition point off an obstacle


@dataclass(frozen=True, slots=True)
class StepMotion:
    """Motion between two states differing by one contact.

    phases : (before, after). com : Bezier segments covering [0, duration] s.
    keyframes : at ``rate`` Hz, evenly spaced, the first at ``before.q`` and the last at
    ``state.q``. state : the state reached (``after``, or ``after`` re-posed when the
    transition point moved). report : per-phase dynamic validity, transition, hold errors,
    collisions (see :func:`step_motion`).
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
    timing: Timing | None = None,
) -> StepMotion:
    """Phases, COM curve and keyframes taking ``before`` to ``after`` (``limb`` changes),
    timed by ``timing`` (speed and the user's attractor; see
    :func:`planner.motion.step.step_com`).

    When keyframes still collide, the transition point is moved along the obstacle normal
    and the motion rebuilt (2PAC 7.2); the motion then ends in the re-posed state,
    ``StepMotion.state`` (same contacts). The report gives ``phases`` (Eq. 1 per phase:
    ``fraction_valid``, ``worst_violation`` N), ``transition`` (``point``, ``margin`` N,
    ``kinematic_violation`` m), ``transition_slack``, ``quasi_static_feasible``,
    ``max_hold_error`` (m), ``colliding_keyframes``, ``swing_lift`` (m),
    ``transition_shift`` (m, 0 when not moved), ``com_method``, ``speed``, ``attractors``
    (each honoured or refused with the reason) and ``motion`` (the builder's report).
    """
    timing = timing or Timing()
    motion = _motion(ctx, before, after, limb, rate, timing)
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
        motion = _shift_transition(ctx, before, after, limb, rate, timing, motion, normal)
    return motion


def _motion(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    rate: float,
    timing: Timing,
) -> StepMotion:
    """The builder's motion from ``before`` to ``after``, with the contact layer's report."""
    obstacles = [(geometry, transform) for geometry, transform, _, _ in ctx.obstacle_geometry]
    built: BuiltStep = build_step(
        ctx.character,
        ctx.data,
        ctx.scene.collision.bvh,
        before,
        after,
        limb,
        rate=rate,
        timing=timing,
        obstacles=obstacles,
    )
    quality = built.motion.report
    creating = after.contact(limb) is not None
    fewer = before.contacts if creating else after.contacts
    point = com_of(ctx, after.q)
    violation = float(
        max(
            kinematics_of(ctx, before.contacts).violation(point),
            kinematics_of(ctx, after.contacts).violation(point),
        )
    )
    margin = balance_margin(ctx, fewer, point)
    report: dict[str, Any] = {
        "phases": [
            {
                "phase": r.phase,
                "t0": r.t0,
                "t1": r.t1,
                "fraction_valid": r.fraction_valid,
                "worst_violation": r.worst_violation,
            }
            for r in built.validity
        ],
        "transition": {"point": point.tolist(), "margin": margin, "kinematic_violation": violation},
        "transition_slack": [max(0.0, violation)],
        "quasi_static_feasible": bool(
            margin >= ctx.params.margin and violation <= KINEMATIC_TOLERANCE
        ),
        "max_hold_error": quality.max_hold_error,
        "colliding_keyframes": quality.colliding_keyframes,
        "swing_lift": built.lift,
        "transition_shift": 0.0,
        "com_method": built.timing.method,
        "speed": timing.speed,
        "attractors": list(built.timing.attractors),
        "motion": quality.as_dict(),
    }
    return StepMotion(built.motion.phases, built.motion.com, built.motion.keyframes, report, after)


def _shift_transition(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    rate: float,
    timing: Timing,
    motion: StepMotion,
    normal: FloatArray,
) -> StepMotion:
    """``motion`` rebuilt with the transition point moved along the obstacle ``normal`` (3,)
    when that leaves fewer colliding keyframes (2PAC 7.2)."""
    creating = after.contact(limb) is not None
    fewer = before.contacts if creating else after.contacts
    kin_b, kin_a = kinematics_of(ctx, before.contacts), kinematics_of(ctx, after.contacts)
    c1 = com_of(ctx, after.q)
    # lifted legs keep their pose while the body moves (not dragged into the floor)
    legs: tuple[str, ...] = ctx.cached("ground_limbs", lambda: ground_limbs(ctx.character))
    lifted = [x for x in legs if after.contact(x) is None]
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
            or max(kin_b.violation(com), kin_a.violation(com)) > KINEMATIC_TOLERANCE
        ):
            continue
        again = _motion(ctx, before, moved, limb, rate, timing)
        again.report["transition_shift"] = shift
        if again.report["colliding_keyframes"] < motion.report["colliding_keyframes"]:
            motion = again
        if motion.report["colliding_keyframes"] == 0:
            break
    return motion


def _stance_of(motion: StepMotion, key: Keyframe) -> tuple[Any, ...]:
    """The contacts held at keyframe ``key`` (those of its phase that it lists)."""
    phase = motion.phases[0] if key.t < motion.phases[0].t1 else motion.phases[1]
    return tuple(c for c in phase.contacts if c.limb in key.contacts)
