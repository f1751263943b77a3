"""A motion described as data: the input of :func:`planner.motion.build_motion`.

Plans, Twister steps and jumps all say what the body does in the same terms: phases, each
with the contacts it holds, the limb that swings from where to where (if any), the posture
and trunk orientation it heads for; and one COM curve over the whole motion. All poses are
world frame (4, 4), metres; times in seconds from the motion's start.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from planner.character import Character
from planner.motion import tuning

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import LimbContact
    from trajectory import PiecewiseBezier

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Swing:
    """``limb`` moves its effector from ``start`` (4, 4) to ``end`` (4, 4) over its phase,
    along an arc rising ``lift`` m along the contact normals (see ``swing_trajectory``).
    ``lift_off`` : s, when it leaves ``start`` if before its phase's start (an overlapping
    swing: the phases before, from then on, carry it as their ``early`` swing); None: at
    its phase's start."""

    limb: str
    start: FloatArray
    end: FloatArray
    lift: float
    lift_off: float | None = None


def swing_length(start: FloatArray, end: FloatArray, normals: Sequence[FloatArray]) -> float:
    """m, how far an effector travels from ``start`` (3,) to ``end`` (3,) as a swing's timing
    counts it: the straight distance plus ``SWING_RISE_WEIGHT`` times its rise along the
    contact ``normals`` (unit (3,), world frame: the largest) beyond ``SWING_RISE_FREE``, and
    ``SWING_DROP_WEIGHT`` times its drop (the largest) beyond ``SWING_DROP_FREE``. A foot
    stepping up a flight of stairs must first clear the tread between; one stepping down
    folds its knee to leave the tread and unfolds it to land; a hand moving along a wall
    neither rises nor drops."""
    delta = np.asarray(end, dtype=np.float64) - np.asarray(start, dtype=np.float64)
    along = [float(delta @ np.asarray(n)) for n in normals]  # signed: up, else down
    rise, drop = max(along, default=0.0), -min(along, default=0.0)
    extra = tuning.SWING_RISE_WEIGHT * max(0.0, rise - tuning.SWING_RISE_FREE)
    extra += tuning.SWING_DROP_WEIGHT * max(0.0, drop - tuning.SWING_DROP_FREE)
    return float(np.linalg.norm(delta)) + extra


@dataclass(frozen=True, slots=True)
class FlightLimb:
    """A limb carried through a flight: its effector goes from ``start`` (4, 4), its pose
    when the flight begins, to ``end`` (4, 4), its pose when the flight ends (world). In
    between it rides with the COM: at flight fraction s its position is the COM plus the
    start offset blended into the end offset (smoothstep), pulled toward ``tuck`` (3,) m,
    the effector's offset from the COM in a natural posture (world frame), by up to
    ``FLIGHT_TUCK`` mid-flight; its orientation turns from start to end (slerp)."""

    limb: str
    start: FloatArray
    end: FloatArray
    tuck: FloatArray


@dataclass(frozen=True, slots=True)
class MotionPhase:
    """[t0, t1] s with ``stance`` held throughout, at most one ``swing``.

    posture : (nq,) the configuration the free joints are pulled toward (the state the phase
    leads to); its root orientation is the trunk orientation aimed at: its roll and pitch
    with ``level_trunk`` False (a step ending in a validated state), else its yaw alone (the
    trunk upright; a character whose trunk may pitch keeps the pitch).

    flight : None for a phase on the ground; for a flight (``stance`` empty) the limbs it
    carries (possibly none): the COM follows its curve exactly (an equality of each control
    step's QP, the whole body translated onto it after the step), each carried limb along
    its ``FlightLimb`` path.
    fast_com : the COM moves fast (a jump's takeoff push or landing): its target is not
    saturated at ``COM_MAX_ERROR`` and the trunk height target moves with it (``posture``'s
    root position is then where the root is aimed at ``t0``). A flight implies it.
    rigid_stance : the stance contacts are equality constraints of the tracker's QP, not
    dominant costs (a takeoff push or a landing: the COM lags rather than drag them).
    turn_from : for a flight, (4,) root quaternion (x, y, z, w) it takes off with: the trunk
    and the carried limbs' offsets from the COM turn from it to ``posture``'s orientation
    as the flight goes on, so that legs turning with the body do not cross (None: the trunk
    is aimed at ``posture``'s orientation from the start).
    early : a swing of another limb that lifted off in this phase or before and lands at the
    end of a later phase (swings overlapping in time: a quadruped's diagonal legs); its
    effector follows that swing's arc (the same ``Swing``, whose ``lift_off`` says when it
    left) with the swing's cost.
    posture_from : for a ``fast_com`` phase on the ground, (nq,) the configuration pulled
    toward at its start (its root aimed, like ``posture``'s, at ``t0``): the target moves from
    it to ``posture`` (``pin.interpolate``) as the COM goes from the curve's point at ``t0``
    to its point at ``t1``, and the pull weighs ``JUMP_POSTURE_COST`` (a jump's push and
    landing led along the whole-body IK's crouch; None: ``posture`` throughout).
    """

    t0: float
    t1: float
    stance: tuple[LimbContact, ...]
    posture: FloatArray
    swing: Swing | None = None
    level_trunk: bool = True
    flight: tuple[FlightLimb, ...] | None = None
    fast_com: bool = False
    rigid_stance: bool = False
    turn_from: FloatArray | None = None
    posture_from: FloatArray | None = None
    early: Swing | None = None

    def __post_init__(self) -> None:
        if self.flight is not None and (
            self.stance or self.swing is not None or self.early is not None
        ):
            raise ValueError("a flight holds no stance and has no swing")
        if self.early is not None and (
            self.early.lift_off is None
            or self.early.lift_off > self.t0 + 1e-9
            or (self.swing is not None and self.swing.limb == self.early.limb)
            or any(c.limb == self.early.limb for c in self.stance)
        ):
            raise ValueError("early: another limb's swing, free here, lifted off by t0")
        if (
            self.swing is not None
            and self.swing.lift_off is not None
            and (self.swing.lift_off > self.t0 + 1e-9)
        ):
            raise ValueError("swing.lift_off: at its phase's start or before")
        if self.posture_from is not None and (self.flight is not None or not self.fast_com):
            raise ValueError("posture_from: only a fast_com phase on the ground")
        if self.turn_from is not None and self.flight is None:
            raise ValueError("turn_from: only a flight turns")


@dataclass(frozen=True, slots=True)
class MotionSpec:
    """What to animate: from ``q_start`` (nq,) through ``phases`` (contiguous, in time
    order), the COM following ``com`` over [phases[0].t0, phases[-1].t1], keyframes at
    ``rate`` per second; with ``q_end`` (nq,), the last keyframe is exactly ``q_end`` (the
    last ``END_BLEND_S`` seconds are blended into it). ``substeps`` : control steps per
    keyframe period outside fast phases (None: ``SUBSTEPS``). ``hold_stance`` : after its
    control steps, each keyframe's stance effectors are set back on their contacts."""

    q_start: FloatArray
    phases: tuple[MotionPhase, ...]
    com: PiecewiseBezier
    rate: float = 30.0
    q_end: FloatArray | None = None
    substeps: int | None = None
    hold_stance: bool = False

    def __post_init__(self) -> None:
        if not self.phases:
            raise ValueError("phases: at least one phase is needed")
        if not self.rate > 0:
            raise ValueError("rate must be positive")
        if self.substeps is not None and not 1 <= self.substeps <= tuning.FAST_SUBSTEPS:
            raise ValueError(f"substeps must be in [1, {tuning.FAST_SUBSTEPS}]")
        for a, b in zip(self.phases, self.phases[1:], strict=False):
            if abs(a.t1 - b.t0) > 1e-9 or b.t1 < b.t0:
                raise ValueError("phases must be contiguous and in time order")
            if a.early is not None and a.early is not b.swing and a.early is not b.early:
                raise ValueError("an early swing goes on in the next phase until it lands")


def torso_columns(character: Character, root_nv: int) -> list[int]:
    """Tangent indices (sorted) of the joints of no limb (a chest's, a head's), past the
    root's ``root_nv``."""
    used = {int(i) for limb in character.limbs for i in limb.idx_v}
    return [i for i in range(root_nv, character.model.nv) if i not in used]


def natural_posture(character: Character, q: FloatArray, keep: Sequence[str]) -> FloatArray:
    """(nq,) posture to head for: ``q`` (nq,) for the root and the limbs in ``keep`` (those
    in contact or swinging), the character's reference posture for every other joint (free
    arms hang, the torso and neck straighten)."""
    out = np.array(character.q_ref, dtype=np.float64)
    out[:7] = q[:7]
    for name in keep:
        idx = character.limb(name).idx_q
        out[idx] = q[idx]
    return out
