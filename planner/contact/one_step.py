"""One-step mode (the Twister game, 2PAC section 7.3; anchor section 6).

From a state, create or break one limb's contact (or let ``auto`` pick like the game) and
return the new state with its COM curve and keyframes, or a structured failure.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from planner.contact.context import ContactContext, FailureReason
from planner.contact.generation import (
    ContactAttempt,
    break_contact,
    create_contact,
    state_from_configuration,
)
from planner.contact.state import ContactState
from planner.contact.step_motion import StepMotion, step_motion
from planner.motion import ComSegment, Keyframe, Phase, tuning
from planner.motion.sequence import Timing
from planner.motion.types import root_speed
from planner.termination import Termination, never

FloatArray = NDArray[np.float64]

_AUTO_RANDOMNESS = 0.3  # m, score jitter of 'auto' creations: the game's spinner


@dataclass(frozen=True, slots=True)
class StepAction:
    """kind : 'create', 'break' or 'auto'. limb : required for create/break, optional for
    auto (then only that limb is tried). surface : surface id for a creation. target : (3,)
    world point near which to create the contact."""

    kind: Literal["create", "break", "auto"]
    limb: str | None = None
    surface: int | None = None
    target: FloatArray | None = None


@dataclass(frozen=True, slots=True)
class StepFailure:
    """Why a step failed: reason, a human-readable message and the limb concerned."""

    reason: FailureReason
    message: str
    limb: str | None = None


@dataclass(frozen=True, slots=True)
class StepResult:
    """Outcome of :func:`twister_step`.

    ok : success. state : the new state (the input state on failure). action : the action
    performed ('create' or 'break'), limb : the limb moved (None on failure).
    phases, com, keyframes : the motion (empty on failure). failure : None on success.
    timings : seconds, ``contacts``, ``motion``, ``total``.
    report : ``attempts`` (list of {action, limb, ok, reason, candidates_tried, resampled})
    always; on success also ``phases`` (per phase {phase, t0, t1, fraction_valid,
    worst_violation [N]}: Eq. 1 at 5 points), ``transition`` ({point, margin [N],
    kinematic_violation [m]}), ``transition_slack`` [m], ``quasi_static_feasible``,
    ``max_hold_error`` [m], ``colliding_keyframes``, ``swing_lift`` [m], ``surface`` (created
    contact's surface id, -1 for a break) and ``collisions_fixed``; ``clock_cap_hit`` always
    (the wall-clock cap stopped ``auto`` with limbs left untried).
    """

    ok: bool
    state: ContactState
    phases: tuple[Phase, ...]
    com: tuple[ComSegment, ...]
    keyframes: tuple[Keyframe, ...]
    report: dict[str, Any]
    failure: StepFailure | None
    timings: dict[str, float] = field(default_factory=dict)
    action: str | None = None
    limb: str | None = None


def _attempt(
    ctx: ContactContext,
    state: ContactState,
    kind: str,
    limb: str,
    action: StepAction,
    rng: np.random.Generator,
) -> ContactAttempt:
    if kind == "break":
        return break_contact(ctx, state, limb)
    return create_contact(ctx, state, limb, rng=rng, surface=action.surface, target=action.target)


def twister_step(
    ctx: ContactContext,
    state: ContactState,
    action: StepAction,
    *,
    rng: np.random.Generator,
    cap: Termination = never,
    rate: float = 30.0,
    timing: Timing | None = None,
) -> StepResult:
    """Perform one contact change; never raises on an infeasible request.

    ``timing`` times the motion like a plan's (speed, the user's attractor for the one
    transition, index 0).

    ``auto`` draws the order of the limbs from ``rng`` (so from the seed) and tries each
    once at most, in that order: a limb in contact is released, a free one placed on a random
    nearby allowed surface; the first limb whose move is clean (no keyframe collides, no stance
    contact slips over ``HOLD_TOLERANCE``, the keyframe COM within ``STEP_COM_TOLERANCE`` of
    its curve, the root never faster than ``MAX_ROOT_SPEED`` between two keyframes) is used.
    A move none of whose motions is clean is refused (``COLLISION`` when the cleanest
    collides, else ``MOTION_FAILED``). What it tries depends on the seed alone, never on the
    time: ``cap`` (say a :class:`~planner.termination.Deadline`) is only a wall-clock cap,
    polled before each limb after the first; when it stops ``auto`` with limbs left untried,
    the report says ``clock_cap_hit`` (a replay may differ).
    """
    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    attempts: list[dict[str, Any]] = []
    cap_hit = False  # whether the wall-clock cap stopped 'auto' with limbs left

    def failed(reason: FailureReason, message: str, limb: str | None) -> StepResult:
        timings["total"] = time.perf_counter() - t_start
        report: dict[str, Any] = {"attempts": attempts, "clock_cap_hit": cap_hit}
        if cap_hit:
            message += "; the wall-clock cap stopped 'auto' with limbs left: a replay may differ"
        failure = StepFailure(reason, message, limb)
        return StepResult(False, state, (), (), (), report, failure, timings)

    if action.kind not in ("create", "break", "auto"):
        return failed(FailureReason.INVALID_ACTION, f"unknown action {action.kind!r}", None)
    if state.q.shape != (ctx.model.nq,):
        return failed(FailureReason.INVALID_STATE, f"q must be ({ctx.model.nq},)", None)
    for c in state.contacts:
        if not ctx.has_limb(c.limb):
            return failed(FailureReason.UNKNOWN_LIMB, f"unknown limb {c.limb!r}", c.limb)
    if action.kind == "auto":
        names = list(ctx.limb_names()) if action.limb is None else [action.limb]
        order = [names[i] for i in rng.permutation(len(names))]
        plan = [("break" if state.contact(n) is not None else "create", n) for n in order]
    else:
        if action.limb is None:
            return failed(FailureReason.INVALID_ACTION, "a limb is required", None)
        plan = [(action.kind, action.limb)]
    last: ContactAttempt | None = None
    best: tuple[str, ContactAttempt, StepMotion, _StepQuality] | None = None
    t_contacts = t_motion = 0.0
    for kind, limb in plan:
        if last is not None and cap():
            cap_hit = True  # the clock, not the plan of attempts, stopped here
            break
        t0 = time.perf_counter()
        attempt = _attempt(ctx, state, kind, limb, action, rng)
        t_contacts += time.perf_counter() - t0
        entry: dict[str, Any] = {
            "action": kind,
            "limb": limb,
            "ok": attempt.ok,
            "reason": None if attempt.reason is None else attempt.reason.value,
            "candidates_tried": attempt.candidates_tried,
            "resampled": attempt.resampled,
        }
        attempts.append(entry)
        last = attempt
        if not attempt.ok:
            continue
        canonical = _passed_back(ctx, attempt.state)
        if not canonical.ok:
            # the client would be refused this state as its next start: not an answer
            message = f"the state reached is not valid as a start: {canonical.message}"
            entry.update(ok=False, reason=FailureReason.INVALID_STATE.value, message=message)
            last = replace(attempt, ok=False, reason=FailureReason.INVALID_STATE, message=message)
            continue
        t0 = time.perf_counter()
        try:
            motion = step_motion(ctx, state, attempt.state, attempt.limb, rate=rate, timing=timing)
        except (ValueError, np.linalg.LinAlgError) as error:  # defensive: report, never raise
            t_motion += time.perf_counter() - t0
            entry.update(ok=False, reason=FailureReason.MOTION_FAILED.value, message=str(error))
            last = replace(attempt, ok=False, reason=FailureReason.MOTION_FAILED)
            continue
        t_motion += time.perf_counter() - t0
        quality = _StepQuality.of(motion)
        if best is None or quality.excess < best[3].excess:
            best = (kind, attempt, motion, quality)
        if quality.clean:
            break
        entry["colliding_keyframes"] = quality.colliding  # auto: try another limb
        entry["max_hold_error"] = quality.hold_error
        entry["com_error_max"] = quality.com_error
        entry["root_speed_max"] = quality.root_speed
    timings["contacts"] = t_contacts
    timings["motion"] = t_motion
    if best is None:
        assert last is not None
        reason = last.reason or FailureReason.NOTHING_REACHABLE
        return failed(reason, last.message, last.limb)
    kind, attempt, motion, quality = best
    if quality.colliding > 0:  # every motion found sweeps through something: refuse, say where
        return failed(
            FailureReason.COLLISION,
            f"every motion found collides ({quality.colliding} keyframes at best, {attempt.limb})",
            attempt.limb,
        )
    if not quality.clean:
        return failed(FailureReason.MOTION_FAILED, quality.fault(attempt.limb), attempt.limb)
    timings["total"] = time.perf_counter() - t_start
    report = dict(motion.report)
    report["attempts"] = attempts
    report["clock_cap_hit"] = cap_hit
    report["surface"] = attempt.surface
    report["collisions_fixed"] = (
        attempt.resampled
        + int(report.get("swing_lift", 0.0) > 0.1)
        + int(report.get("transition_shift", 0.0) > 0.0)
    )
    return StepResult(
        True,
        motion.state,
        motion.phases,
        motion.com,
        motion.keyframes,
        report,
        None,
        timings,
        kind,
        attempt.limb,
    )


def _passed_back(ctx: ContactContext, state: ContactState) -> ContactAttempt:
    """``state`` as a client passes it back for the next step: its configuration and each
    contact's limb and surface, the contacts placed again where the configuration puts them
    (:func:`state_from_configuration`). A contact held while the body moved keeps the
    placement it was made with; a point foot turns about it meanwhile, and the kinematic
    polytope of the foot's placement now (its frame turned with the shin) may leave the COM
    outside where the one it was made with did not (a hexapod's state 4.6 mm out, refused
    when sent back)."""
    contacts: dict[str, int | None] = {c.limb: c.surface for c in state.contacts}
    return state_from_configuration(ctx, state.q, contacts)


@dataclass(frozen=True, slots=True)
class _StepQuality:
    """What makes a step's motion clean or not: ``colliding`` keyframes, ``hold_error`` (m,
    its stance contacts' largest slip), ``com_error`` (m, its keyframe COM's largest distance
    from its curve), ``root_speed`` (m/s, the root's fastest move between two keyframes)."""

    colliding: int
    hold_error: float
    com_error: float
    root_speed: float

    @classmethod
    def of(cls, motion: StepMotion) -> _StepQuality:
        keys = motion.keyframes
        return cls(
            int(motion.report["colliding_keyframes"]),
            float(motion.report["max_hold_error"]),
            float(motion.report["motion"]["com_error_max_m"]),
            max((root_speed(a, b) for a, b in itertools.pairwise(keys)), default=0.0),
        )

    @property
    def excess(self) -> tuple[int, float, float, float]:
        """(colliding keyframes, m of slip beyond ``HOLD_TOLERANCE``, m of COM error beyond
        ``STEP_COM_TOLERANCE``, m/s beyond ``MAX_ROOT_SPEED``): all zero when clean, smaller
        is cleaner."""
        return (
            self.colliding,
            max(0.0, self.hold_error - tuning.HOLD_TOLERANCE),
            max(0.0, self.com_error - tuning.STEP_COM_TOLERANCE),
            max(0.0, self.root_speed - tuning.MAX_ROOT_SPEED),
        )

    @property
    def clean(self) -> bool:
        return self.excess == (0, 0.0, 0.0, 0.0)

    def fault(self, limb: str) -> str:
        """Why the cleanest motion found (of ``limb``), collision-free, is not clean."""
        _, slip, lag, jump = self.excess
        if slip > 0.0:  # every motion found lets a held contact slide
            return (
                f"every motion found lets a stance contact slip ({self.hold_error * 1000:.0f} "
                f"mm at best, tolerance {tuning.HOLD_TOLERANCE * 1000:.0f} mm, {limb})"
            )
        if lag > 0.0:  # the body is not where the balanced COM was planned
            return (
                f"in every motion found the body strays from its COM curve "
                f"({self.com_error * 1000:.0f} mm at best, tolerance "
                f"{tuning.STEP_COM_TOLERANCE * 1000:.0f} mm, {limb})"
            )
        assert jump > 0.0  # the body lags, then catches up in a jump
        return (
            f"in every motion found the root jumps between two keyframes "
            f"({self.root_speed:.1f} m/s at best, at most {tuning.MAX_ROOT_SPEED:g} m/s, {limb})"
        )
