"""The one whole-body motion builder: a :class:`MotionSpec` in, keyframes and a report out.

The COM curve and the phases come from the caller (a plan, a Twister step, a jump); the
builder runs the QP tracker (``tracker``) at ``SUBSTEPS`` control steps per keyframe
(``FAST_SUBSTEPS`` in flights, pushes and landings: ``_Targets.substeps``), keeps
the keyframes on an even grid at ``spec.rate``, and checks every keyframe with the one
checker (``checker``). It never raises on a motion it cannot make clean: the report says
which keyframes collide or slip and whether its termination (the plan's work budget, or
its wall-clock cap) cut the motion short.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character
from planner.kinematics import (
    borrowed_data,
    borrowed_geometry_data,
    clearing_swing_trajectory,
    swing_trajectory,
)
from planner.motion import tuning
from planner.motion.checker import KeyframeCheck, KeyframeChecker
from planner.motion.spec import MotionPhase, MotionSpec
from planner.motion.tracker import StepTargets, WholeBodyTracker
from planner.motion.types import ComSegment, Keyframe, Phase, root_speed
from planner.termination import Termination, never

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class MotionReport:
    """How a motion came out.

    phases_animated / phases_total : phases whose whole span has keyframes. cut_short :
    the termination (a work budget spent, or a clock cap) stopped the tracking before the
    end. colliding_keyframes : keyframes the checker refuses (into the scene or into the
    body); worst_scene_depth (m) and
    worst_shape say where; worst_self_depth (m). max_hold_error : m, stance contacts.
    com_error_max / com_error_p99 : m, keyframe COM against its curve. qp_fallbacks :
    control steps solved without the collision dampers (their QP had no solution).
    swings_raised : swing phases tracked again with a higher arc (2PAC 7.2), and flights
    with their limbs tucked further. abandoned : the build stopped at the first phase that
    could not be played cleanly (``build_motion(abandon_unclean=True)``), abandoned_phase
    (its index) and abandoned_because (why, in words).
    """

    phases_animated: int
    phases_total: int
    cut_short: bool
    colliding_keyframes: int
    worst_scene_depth: float
    worst_shape: str | None
    worst_self_depth: float
    max_hold_error: float
    com_error_max: float
    com_error_p99: float
    qp_fallbacks: int
    swings_raised: int = 0
    colliding_times: tuple[float, ...] = field(default=())
    abandoned: bool = False
    abandoned_phase: int | None = None
    abandoned_because: str | None = None

    @property
    def complete(self) -> bool:
        """Every phase animated, no keyframe colliding, every contact held."""
        return (
            self.phases_animated == self.phases_total
            and self.colliding_keyframes == 0
            and self.max_hold_error <= tuning.HOLD_TOLERANCE
        )

    def shortfall(self) -> str | None:
        """What keeps the motion from being complete, in words; None when it is."""
        reasons = []
        if self.phases_animated < self.phases_total:
            why = ": the budget ran out" if self.cut_short else ""
            if self.abandoned:
                why = f": abandoned at the first unclean phase ({self.abandoned_because})"
            reasons.append(
                f"keyframes for {self.phases_animated} of {self.phases_total} phases{why}"
            )
        if self.colliding_keyframes:
            text = f"{self.colliding_keyframes} keyframes collide"
            if self.worst_scene_depth > tuning.PENETRATION_TOLERANCE:
                text += (
                    f" ({self.worst_shape} {self.worst_scene_depth * 1000:.0f} mm into the scene)"
                )
            if self.worst_self_depth > tuning.SELF_PENETRATION_TOLERANCE:
                text += f", body parts up to {self.worst_self_depth * 1000:.0f} mm into each other"
            reasons.append(text)
        if self.max_hold_error > tuning.HOLD_TOLERANCE:
            reasons.append(
                f"a stance contact slips {self.max_hold_error * 1000:.0f} mm "
                f"(tolerance {tuning.HOLD_TOLERANCE * 1000:.0f} mm)"
            )
        return "; ".join(reasons) or None

    def as_dict(self) -> dict[str, Any]:
        """The report as JSON-ready values."""
        return {
            "phases_animated": self.phases_animated,
            "phases_total": self.phases_total,
            "cut_short": self.cut_short,
            "colliding_keyframes": self.colliding_keyframes,
            "worst_scene_depth_m": self.worst_scene_depth,
            "worst_shape": self.worst_shape,
            "worst_self_depth_m": self.worst_self_depth,
            "max_hold_error_m": self.max_hold_error,
            "com_error_max_m": self.com_error_max,
            "com_error_p99_m": self.com_error_p99,
            "qp_fallbacks": self.qp_fallbacks,
            "swings_raised": self.swings_raised,
            "complete": self.complete,
        }


@dataclass(frozen=True, slots=True)
class BuiltMotion:
    """Phases, COM segments and keyframes of a motion, with its report. ``end`` is the
    configuration (nq,) the motion ends in; ``swing_lifts`` the arc height (m) each phase's
    swing was tracked with (0 without a swing); ``checks`` and ``com_errors`` (m) what the
    checker said of each keyframe (a later build may resume from this one's keyframes);
    ``swing_clearings`` the top (m) of each phase's clearing path when its swing was tracked
    along one (``CLEARING_HEIGHTS``), 0 otherwise."""

    phases: tuple[Phase, ...]
    com: tuple[ComSegment, ...]
    keyframes: tuple[Keyframe, ...]
    report: MotionReport
    end: FloatArray
    swing_lifts: tuple[float, ...] = ()
    checks: tuple[KeyframeCheck, ...] = ()
    com_errors: tuple[float, ...] = ()
    swing_clearings: tuple[float, ...] = ()


def keyframe_grid(t0: float, t1: float, rate: float) -> FloatArray:
    """Times (k,) from ``t0`` every ``1 / rate`` s to ``t1``: the last interval is between
    half a period and one and a half periods long (never a sliver), unless the whole span is
    shorter."""
    if not (math.isfinite(t0) and math.isfinite(t1)) or t1 < t0:
        raise ValueError("need finite t0 <= t1")
    period = 1.0 / rate
    count = max(1, round((t1 - t0) / period))
    if t1 - t0 < 0.5 * period:
        return np.array([t0, t1]) if t1 > t0 else np.array([t0])
    return np.asarray(t0 + (t1 - t0) * np.arange(count + 1) / count, dtype=np.float64)


def phase_keyframe_times(t0: float, t1: float, rate: float, breaks: Sequence[float]) -> FloatArray:
    """:func:`keyframe_grid` from ``t0`` to ``t1`` with every phase holding a time: a phase
    (between consecutive ``breaks``, the phases' ends, s; a time at a break is the later
    phase's) shorter than a period that no time falls in gets the nearer inner time moved
    into it, toward its middle, by at most ``KEYFRAME_SHIFT`` of a period, when the phase it
    leaves keeps another time. The gaps stay between half a period and one and a half."""
    grid = keyframe_grid(t0, t1, rate)
    period = 1.0 / rate
    ends = sorted(float(b) for b in breaks)

    def phase_of(t: float) -> int:
        return min(bisect.bisect_right(ends, t), len(ends) - 1)

    counts = Counter(phase_of(float(t)) for t in grid)
    starts = [-math.inf, *ends]
    for k in range(len(ends)):
        a, b = max(starts[k], t0), min(ends[k], t1)
        if b <= a or counts[k]:
            continue
        middle, reach = 0.5 * (a + b), KEYFRAME_SHIFT * period
        after = int(np.searchsorted(grid, a))  # the first time at or after the phase's start
        inner = [i for i in (after - 1, after) if 0 < i < len(grid) - 1]  # the ends stay
        for i in sorted(inner, key=lambda i: abs(float(grid[i]) - middle)):
            g = float(grid[i])
            target = min(max(middle, g - reach), g + reach)
            leaving = phase_of(g)
            if not a <= target < b or phase_of(target) != k or counts[leaving] < 2:
                continue
            if not 0.5 * period <= target - grid[i - 1] <= 1.5 * period:
                continue
            if not 0.5 * period <= grid[i + 1] - target <= 1.5 * period:
                continue
            grid[i] = target
            counts[leaving] -= 1
            counts[k] = 1
            break
    return grid


KEYFRAME_SHIFT = 0.45
"""Of a keyframe period, the farthest :func:`phase_keyframe_times` moves a time into a phase
that has none."""


def _slerp(a: FloatArray, b: FloatArray, u: float) -> FloatArray:
    """(3, 3) rotation a fraction ``u`` of the way from ``a`` (3, 3) to ``b`` (3, 3)."""
    step = pin.log3(a.T @ b)
    return np.asarray(a @ pin.exp3(u * step), dtype=np.float64)


class _Targets:
    """Per-time targets of a spec: the phase, its stance, the COM and the swing pose; the
    swing arc of a phase may be raised (``lifts``, per phase index) or replaced by a
    clearing path (``clearings``: its top, m, per phase index)."""

    def __init__(self, character: Character, spec: MotionSpec) -> None:
        self.character = character
        self.spec = spec
        self.breaks = np.array([p.t1 for p in spec.phases])
        self.break_list = [float(p.t1) for p in spec.phases]
        self.lifts: dict[int, float] = {}
        self.clearings: dict[int, float] = {}
        self.tucks: dict[int, tuple[float, float]] = {}
        self.unguarded: set[int] = set()
        self._arcs: dict[tuple[int, float, float], Any] = {}
        self._coms: dict[float, FloatArray] = {}
        # per phase, its stance as (limb, placement (4, 4)) pairs, made once
        self._stances: dict[int, tuple[tuple[str, FloatArray], ...]] = {}
        self._substeps: dict[int, int] = {}
        # per phase carrying an early swing, the phase that swing lands at the end of
        self._lands_in: dict[int, int] = {}
        for k, phase in enumerate(spec.phases):
            if phase.early is not None:
                self._lands_in[k] = next(
                    j for j in range(k + 1, len(spec.phases)) if spec.phases[j].swing is phase.early
                )

    def substeps(self, k: int) -> int:
        """Control steps per keyframe period in phase k: ``FAST_SUBSTEPS`` in a flight and in
        a fast-COM phase whose COM curve goes faster than ``FAST_COM_SPEED`` somewhere
        (a push, a landing), the spec's ``substeps`` or ``SUBSTEPS`` elsewhere (a jump's
        crouch and stand-up shifts too: their COM moves at walking pace)."""
        known = self._substeps.get(k)
        if known is not None:
            return known
        phase = self.spec.phases[k]
        fast = phase.flight is not None
        if not fast and phase.fast_com and phase.t1 > phase.t0:
            times = np.linspace(phase.t0, phase.t1, tuning.FAST_COM_SAMPLES)
            points = np.array([self.com(float(t)) for t in times])
            speeds = np.linalg.norm(np.diff(points, axis=0), axis=1) / np.diff(times)
            fast = bool(speeds.max() > tuning.FAST_COM_SPEED)
        count = tuning.FAST_SUBSTEPS if fast else (self.spec.substeps or tuning.SUBSTEPS)
        self._substeps[k] = count
        return count

    def progress(self, phase: MotionPhase, com: FloatArray) -> float:
        """How far (0 to 1) ``com`` (3,) lies along the chord from the COM curve's point at
        ``phase.t0`` to its point at ``phase.t1`` (projected on it; 1 for a still COM)."""
        a, b = self.com(phase.t0), self.com(phase.t1)
        chord = b - a
        length = float(chord @ chord)
        if length < 1e-12:
            return 1.0
        return min(1.0, max(0.0, float((com - a) @ chord) / length))

    def phase_index(self, t: float) -> int:
        """The phase running at ``t`` (the later one at a boundary)."""
        k = bisect.bisect_right(self.break_list, t)  # np.searchsorted's, in plain floats
        return min(k, len(self.spec.phases) - 1)

    def arc(self, k: int) -> Any:
        """The swing path of phase k (t -> pose (4, 4)), or None without a swing: its arc, or
        its clearing path when ``clearings`` has one (:meth:`clearing_path`)."""
        phase = self.spec.phases[k]
        swing = phase.swing
        if swing is None or phase.t1 <= phase.t0:
            return None
        clearing = self.clearings.get(k, 0.0)
        if clearing > 0.0:
            return self.clearing_path(k, clearing)
        lift = self.lifts.get(k, swing.lift)
        key = (k, lift, 0.0)
        if key not in self._arcs:
            normal = self.character.limb(swing.limb).normal
            # the arc lands a little before the phase ends: the effector, which lags its
            # target by a few control steps, settles on its contact before it must hold it
            self._arcs[key] = swing_trajectory(
                swing.start,
                swing.end,
                self.lift_off(phase),
                self.landing(phase),
                lift=lift,
                normal_in_frame=normal,
            )
        return self._arcs[key]

    def clearing_path(self, k: int, top: float) -> Any:
        """The box-shaped swing path of phase k (t -> pose (4, 4)): up, across and down, its
        crossing ``top`` m above the higher of its two ends along each end's normal, landing
        when :meth:`arc` does."""
        phase = self.spec.phases[k]
        swing = phase.swing
        assert swing is not None
        key = (k, 0.0, top)
        if key not in self._arcs:
            normal = np.asarray(self.character.limb(swing.limb).normal, dtype=np.float64)
            normal = normal / np.linalg.norm(normal)
            p0, p3 = swing.start[:3, 3], swing.end[:3, 3]
            n0, n3 = swing.start[:3, :3] @ normal, swing.end[:3, :3] @ normal
            self._arcs[key] = clearing_swing_trajectory(
                swing.start,
                swing.end,
                self.lift_off(phase),
                self.landing(phase),
                rise=top + max(0.0, float((p3 - p0) @ n0)),
                descend=top + max(0.0, float((p0 - p3) @ n3)),
                normal_in_frame=normal,
                rise_share=tuning.CLEARING_RISE_SHARE,
            )
        return self._arcs[key]

    @staticmethod
    def lift_off(phase: MotionPhase) -> float:
        """s, when the swing of ``phase`` leaves its start: its ``lift_off`` (an overlapping
        swing, carried as ``early`` by the phases before) or the phase's start."""
        swing = phase.swing
        return phase.t0 if swing is None or swing.lift_off is None else swing.lift_off

    def early(self, k: int, t: float) -> tuple[tuple[str, FloatArray], ...]:
        """(limb, pose (4, 4)) of phase k's early swing at ``t`` on the arc of the phase it
        lands in (none without one)."""
        phase = self.spec.phases[k]
        if phase.early is None:
            return ()
        arc = self.arc(self._lands_in[k])
        return ((phase.early.limb, np.asarray(arc(t), dtype=np.float64)),)

    @staticmethod
    def landing(phase: MotionPhase) -> float:
        """s, when the swing arc of ``phase`` reaches its landing: ``LANDING_SETTLE_S`` (at
        most ``LANDING_SETTLE_SHARE`` of the phase) before the phase ends."""
        settle = min(tuning.LANDING_SETTLE_S, tuning.LANDING_SETTLE_SHARE * (phase.t1 - phase.t0))
        return phase.t1 - settle

    def released(self, k: int) -> tuple[str, ...]:
        """The limbs of phase ``k - 1``'s stance that phase ``k`` no longer holds."""
        if k == 0:
            return ()
        held = {c.limb for c in self.spec.phases[k].stance}
        return tuple(c.limb for c in self.spec.phases[k - 1].stance if c.limb not in held)

    def com(self, t: float) -> FloatArray:
        """(3,) m, the COM curve at ``t`` (clamped to its span), read-only: memoised per
        time (a keyframe's time is often its last control step's, and the blend asks again)."""
        hit = self._coms.get(t)
        if hit is None:
            curve = self.spec.com
            hit = np.array(curve(min(max(t, curve.t0), curve.t1)), dtype=np.float64)
            hit.flags.writeable = False
            if len(self._coms) > 4096:
                self._coms.clear()
            self._coms[t] = hit
        return hit

    @staticmethod
    def flight_blend(phase: MotionPhase, t: float) -> tuple[float, float]:
        """(s, smoothstep(s)) at ``t`` of a flight ``phase``: s the fraction of the flight
        but its last ``FLIGHT_SETTLE_SHARE``, in which the limbs hold their landing offsets."""
        span = (phase.t1 - phase.t0) * (1.0 - tuning.FLIGHT_SETTLE_SHARE)
        s = 1.0 if span <= 0.0 else min(1.0, max(0.0, (t - phase.t0) / span))
        return s, s * s * (3.0 - 2.0 * s)

    @staticmethod
    def turn(phase: MotionPhase, blend: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(3, 3) rotations of a flight ``phase``'s root at takeoff, at landing and a
        fraction ``blend`` of the way between (slerp); the identity three times when the
        phase does not turn (``turn_from`` None)."""
        if phase.turn_from is None:
            return np.eye(3), np.eye(3), np.eye(3)
        start = pin.Quaternion(np.asarray(phase.turn_from, dtype=np.float64)).matrix()
        end = pin.Quaternion(np.asarray(phase.posture[3:7], dtype=np.float64)).matrix()
        return start, end, _slerp(start, end, blend)

    def carried(self, phase: MotionPhase, t: float, k: int) -> tuple[tuple[str, FloatArray], ...]:
        """(limb, pose (4, 4)) of the limbs a flight ``phase`` (index ``k``) carries at
        ``t``: the COM plus an offset blended from the start offset to the end offset
        (smoothstep of :meth:`flight_blend`), pulled toward the limb's tuck offset (raised by
        the phase's extra lift) by share sin^2(pi s) (share ``FLIGHT_TUCK`` unless the phase
        was retried with a stronger tuck, ``tucks``); offsets blended in the frame of the
        turning root (:meth:`turn`); the orientation slerped from start to end."""
        if not phase.flight:
            return ()
        s, blend = self.flight_blend(phase, t)
        share, lift = self.tucks.get(k, (tuning.FLIGHT_TUCK, 0.0))
        tuck = share * math.sin(math.pi * s) ** 2
        c0, c1, c = self.com(phase.t0), self.com(phase.t1), self.com(t)
        start, end, now = self.turn(phase, blend)
        out = []
        for limb in phase.flight:
            lerp = (1.0 - blend) * (start.T @ (limb.start[:3, 3] - c0)) + blend * (
                end.T @ (limb.end[:3, 3] - c1)
            )
            aim = end.T @ (np.asarray(limb.tuck, dtype=np.float64) + np.array([0.0, 0.0, lift]))
            pose = np.eye(4)
            pose[:3, 3] = c + now @ (lerp + tuck * (aim - lerp))
            pose[:3, :3] = _slerp(limb.start[:3, :3], limb.end[:3, :3], blend)
            out.append((limb.limb, pose))
        return tuple(out)

    def stance(self, k: int) -> tuple[tuple[str, FloatArray], ...]:
        """Phase ``k``'s stance as (limb, placement (4, 4)) pairs (:meth:`at`'s), made once."""
        stance = self._stances.get(k)
        if stance is None:
            stance = tuple((c.limb, np.asarray(c.placement)) for c in self.spec.phases[k].stance)
            self._stances[k] = stance
        return stance

    def at(self, t: float) -> StepTargets:
        k = self.phase_index(t)
        phase: MotionPhase = self.spec.phases[k]
        com = self.com(t)
        arc = self.arc(k)
        swing = None
        settle = 0.0
        if arc is not None and phase.swing is not None:
            swing = (phase.swing.limb, np.asarray(arc(t), dtype=np.float64))
            landing = self.landing(phase)
            if t > landing:
                settle = (t - landing) / max(phase.t1 - landing, 1e-9)
        stance = self.stance(k)
        if phase.flight is None and not phase.fast_com:
            return StepTargets(
                stance,
                com,
                swing,
                phase.posture,
                k not in self.unguarded,
                phase.level_trunk,
                carried=self.early(k, t),
                rigid_stance=phase.rigid_stance,
                swing_settle=settle,
            )
        # a fast COM: its target unsaturated, the trunk height aimed with it
        posture = np.array(phase.posture, dtype=np.float64)
        if phase.posture_from is not None:
            posture = np.asarray(
                pin.interpolate(
                    self.character.model,
                    np.asarray(phase.posture_from, dtype=np.float64),
                    posture,
                    self.progress(phase, com),
                ),
                dtype=np.float64,
            )
        posture[:3] += com - self.com(phase.t0)
        if phase.turn_from is not None:  # a turning flight: the trunk turns with its limbs
            posture[3:7] = pin.Quaternion(
                self.turn(phase, self.flight_blend(phase, t)[1])[2]
            ).coeffs()
        return StepTargets(
            stance,
            com,
            swing,
            posture,
            k not in self.unguarded,
            phase.level_trunk,
            carried=self.carried(phase, t, k),
            exact_com=phase.flight is not None,
            com_reach=math.inf,
            rigid_stance=phase.rigid_stance,
            root_bounded=False,
            posture_led=phase.posture_from is not None,
            swing_settle=settle,
        )


@dataclass(slots=True)
class _Segment:
    """Keyframes tracked over one phase, with what the checker said of them."""

    keyframes: list[Keyframe]
    checks: list[KeyframeCheck]
    com_errors: list[float]
    q: FloatArray
    landing_error: float
    cut_short: bool = False
    stopped: bool = False  # stopped at a keyframe its swing collides in (``_track_segment``)

    @property
    def score(self) -> tuple[int, int]:
        """Lower is better: colliding keyframes, then a missed landing."""
        missed = int(self.landing_error > tuning.LANDING_TOLERANCE)
        return sum(c.colliding for c in self.checks) + tuning.MISSED_LANDING_WEIGHT * missed, missed


def _clearing_top(targets: _Targets, checker: KeyframeChecker, k: int) -> float:
    """m, the lowest top of ``CLEARING_HEIGHTS`` whose clearing path for phase k
    (:meth:`_Targets.clearing_path`) keeps the swinging effector's shapes
    ``CLEARING_MARGIN`` off the scene at ``CLEARING_SAMPLES`` times, ``CLEARING_NORMAL_MARGIN``
    where it only rises or descends along the normal (samples within ``CLEARING_END_ZONE`` of
    either end, where it touches its surfaces, not measured); when none does, the one whose
    path comes nearest to it (the lowest of equals), not the highest: a foot stepping down
    beside the riser of the tread above passes its nosing as close at every top, and the
    highest folded the leg to its joint limits and leaned the chest 58 degrees."""
    phase = targets.spec.phases[k]
    swing = phase.swing
    assert swing is not None
    character = targets.character
    frame = character.model.frames[int(character.limb(swing.limb).frame_id)]
    objects = character.motion_geometry.geometryObjects
    # the effector's shapes in its frame (they ride the frame's joint: effector_geometries)
    shapes = [
        (objects[i].geometry, frame.placement.actInv(objects[i].placement))
        for i in sorted(checker.effectors[swing.limb])
        if int(objects[i].parentJoint) == int(frame.parentJoint)
    ]
    p0, p3 = swing.start[:3, 3], swing.end[:3, 3]
    times = np.linspace(targets.lift_off(phase), targets.landing(phase), tuning.CLEARING_SAMPLES)
    # along the normal only (the rise before the crossing starts, the descent after it ends)
    # the tracked effector lags along its own line: a smaller margin there
    share = (times - times[0]) / (times[-1] - times[0])
    straight = (share <= tuning.CLEARING_RISE_SHARE) | (share >= 1.0 - tuning.CLEARING_RISE_SHARE)
    margins = np.where(straight, tuning.CLEARING_NORMAL_MARGIN, tuning.CLEARING_MARGIN)
    best_top, best_gap = tuning.CLEARING_HEIGHTS[0], -math.inf
    for top in tuning.CLEARING_HEIGHTS:
        path = targets.clearing_path(k, top)
        gap = math.inf  # the smallest distance beyond its margin, measured until negative
        for t, margin in zip(times, margins, strict=True):
            pose = np.asarray(path(float(t)), dtype=np.float64)
            here = pose[:3, 3]
            if min(np.linalg.norm(here - p0), np.linalg.norm(here - p3)) < tuning.CLEARING_END_ZONE:
                continue
            placed = pin.SE3(pose[:3, :3], here)
            for geometry, local in shapes:
                gap = min(gap, checker.distances.nearest(geometry, placed * local) - margin)
            if gap < 0.0:
                break
        if gap >= 0.0:
            return top
        if gap > best_gap:
            best_top, best_gap = top, gap
    return best_top


def _aim_swing(targets: _Targets, k: int, lift: float, guarded: bool, top: float) -> None:
    """Set phase k's swing to an arc ``lift`` m high, or the clearing path ``top`` m high
    when ``top`` > 0, its effector ``guarded`` against the scene or not."""
    targets.lifts[k] = lift
    targets.clearings.pop(k, None)
    if top > 0.0:
        targets.clearings[k] = top
    if guarded:
        targets.unguarded.discard(k)
    else:
        targets.unguarded.add(k)


def _collides_at(check: KeyframeCheck, shapes: frozenset[str]) -> bool:
    """Whether ``check`` collides with one of ``shapes`` the deepest, in the scene or into
    another body part."""
    return check.colliding and (
        check.shape in shapes
        or (check.self_pair is not None and not shapes.isdisjoint(check.self_pair))
    )


def _swing_at_fault(segment: _Segment, shapes: frozenset[str]) -> bool:
    """Whether the swinging limb (its collision ``shapes``) is what went wrong in
    ``segment``: it missed its landing, or one of its shapes is the deepest in a colliding
    keyframe, in the scene or into another body part (a foot brushing the stance foot)."""
    missed = segment.landing_error > tuning.LANDING_TOLERANCE
    return missed or any(_collides_at(c, shapes) for c in segment.checks)


def lagging_allowed(keyframes: int) -> int:
    """How many of a plan's ``keyframes`` may lag their COM curve by more than
    ``TRIAL_COM_TOLERANCE`` while its 99th percentile lag (numpy's, interpolated) stays
    within it: ``TRIAL_COM_LAG_BUDGET`` of the keyframes less one, rounded down."""
    return max(0, math.floor(tuning.TRIAL_COM_LAG_BUDGET * (keyframes - 1) + 1e-9))


def _lagging(com_errors: Sequence[float]) -> int:
    """How many of ``com_errors`` (m, keyframe COM to curve) exceed ``TRIAL_COM_TOLERANCE``."""
    return sum(e > tuning.TRIAL_COM_TOLERANCE for e in com_errors)


def _unclean(segment: _Segment, before: Keyframe | None, lag_budget: int = 0) -> str | None:
    """Why ``segment`` cannot be played as is, None when it can: a keyframe collides, a
    stance contact slips beyond ``HOLD_TOLERANCE``, the COM lags its curve by more than
    ``TRIAL_COM_TOLERANCE`` in more than ``TRIAL_COM_LAG_SHARE`` of the keyframes (unless the
    segment's lagging keyframes are within ``lag_budget``, what the plan has left of
    ``TRIAL_COM_LAG_BUDGET``) or by more than ``TRIAL_COM_MAX_LAG`` in one, or the root moves
    faster than ``MAX_ROOT_SPEED`` between two keyframes (from ``before``, the keyframe
    preceding the segment, if any)."""
    if not all(c.valid for c in segment.checks):
        return "a keyframe collides or a contact slips"
    lags = np.asarray(segment.com_errors, dtype=np.float64)
    lagging = _lagging(segment.com_errors)
    if lags.size and (
        float(lags.max()) > tuning.TRIAL_COM_MAX_LAG
        or (lagging / lags.size > tuning.TRIAL_COM_LAG_SHARE and lagging > lag_budget)
    ):
        return f"the COM lags its curve by up to {float(lags.max()) * 1000:.0f} mm"
    keys = ([before] if before is not None else []) + segment.keyframes
    for a, b in itertools.pairwise(keys):
        speed = root_speed(a, b)
        if speed > tuning.MAX_ROOT_SPEED:
            return f"the root moves at {speed:.1f} m/s between two keyframes"
    return None


def _track_segment(
    tracker: WholeBodyTracker,
    checker: KeyframeChecker,
    targets: _Targets,
    q_start: FloatArray,
    times: Sequence[float],
    previous: float | None,
    until: Termination,
    stop_at: frozenset[str] | None = None,
) -> _Segment:
    """Track from ``q_start`` (nq,) at time ``previous`` through the keyframe ``times`` (of
    one phase); the effectors the phase lifts may stay as deep as they are at ``q_start``.
    With ``stop_at`` (the swinging limb's shapes), the track stops after the first keyframe
    colliding with one of them (``stopped``; its landing is not measured)."""
    spec = targets.spec
    model = tracker.model
    q = np.array(q_start, dtype=np.float64)
    out = _Segment([], [], [], q, 0.0)
    lifting = checker.depths(q, targets.released(targets.phase_index(times[0]))) if times else {}
    for t in times:
        if previous is not None:
            if until():
                out.cut_short = True
                break
            substeps = targets.substeps(targets.phase_index(t))
            dt = (t - previous) / substeps
            share = tuning.SUBSTEPS / substeps
            before = q
            for s in range(1, substeps + 1):
                q = tracker.step(q, targets.at(previous + s * dt), dt, share)
            if spec.hold_stance:
                stance = targets.stance(targets.phase_index(t))
                q = tracker.hold_stance(q, stance, before, t - previous)
        previous = t
        phase = spec.phases[targets.phase_index(t)]
        check = checker.check(q, phase.stance, lifting)
        com = np.asarray(pin.centerOfMass(model, checker.data, q), dtype=np.float64)
        out.checks.append(check)
        out.com_errors.append(float(np.linalg.norm(com - targets.com(t))))
        out.keyframes.append(
            Keyframe(t=t, q=q.copy(), contacts=tuple(c.limb for c in phase.stance))
        )
        if stop_at is not None and _collides_at(check, stop_at):
            out.stopped = True
            out.q = q
            return out
    out.q = q
    k = targets.phase_index(times[0]) if times else 0
    phase = spec.phases[k]
    if phase.flight and out.keyframes:
        # a flight lands when its carried effectors are where they will touch down
        pin.framesForwardKinematics(model, tracker.data, q)
        out.landing_error = max(
            float(
                np.linalg.norm(
                    tracker.data.oMf[tracker.character.limb(limb).frame_id].translation
                    - pose[:3, 3]
                )
            )
            for limb, pose in targets.carried(phase, out.keyframes[-1].t, k)
        )
    swing = phase.swing
    if swing is not None and out.keyframes:
        pin.framesForwardKinematics(model, tracker.data, q)
        frame = tracker.data.oMf[tracker.character.limb(swing.limb).frame_id]
        out.landing_error = float(
            np.linalg.norm(frame.translation - targets.arc(k)(out.keyframes[-1].t)[:3, 3])
        )
    return out


def _entry_velocity(model: Any, segments: Sequence[_Segment]) -> FloatArray | None:
    """(nv,) the motion's velocity at its last keyframe so far: the step between its last
    two keyframes over their interval (rad/s, m/s in the root's frame); None before two."""
    last: list[Keyframe] = []
    for segment in reversed(segments):
        last = list(segment.keyframes[-2:]) + last
        if len(last) >= 2:
            break
    if len(last) < 2:
        return None
    a, b = last[-2], last[-1]
    return np.asarray(pin.difference(model, a.q, b.q) / max(b.t - a.t, 1e-9), dtype=np.float64)


def _blend_into(
    checker: KeyframeChecker,
    targets: _Targets,
    keyframes: list[Keyframe],
    checks: list[KeyframeCheck],
    com_errors: list[float],
    q_end: FloatArray,
) -> FloatArray:
    """Blend the keyframes of the last ``END_BLEND_S`` seconds into ``q_end`` (nq,) in place
    (along the configuration manifold, smoothstep weight reaching 1 at the last keyframe),
    checking them again. Returns the last configuration (``q_end`` itself)."""
    model = checker.model
    t_end = keyframes[-1].t
    window = min(tuning.END_BLEND_S, t_end - keyframes[0].t)
    for i, key in enumerate(keyframes):
        u = 1.0 if window <= 0.0 else (key.t - (t_end - window)) / window
        if u <= 0.0:
            continue
        if i == len(keyframes) - 1:
            q = np.array(q_end, dtype=np.float64)
        else:
            w = u * u * (3.0 - 2.0 * u)
            q = np.asarray(pin.interpolate(model, key.q, q_end, w), dtype=np.float64)
        k = targets.phase_index(key.t)
        keyframes[i] = Keyframe(t=key.t, q=q, contacts=key.contacts)
        checks[i] = checker.check(q, targets.spec.phases[k].stance)
        com = np.asarray(pin.centerOfMass(model, checker.data, q), dtype=np.float64)
        com_errors[i] = float(np.linalg.norm(com - targets.com(key.t)))
    return np.array(keyframes[-1].q)


def build_motion(
    character: Character,
    scene_bvh: Any,
    spec: MotionSpec,
    *,
    obstacles: Sequence[tuple[Any, Any]] = (),
    until: Termination = never,
    abandon_unclean: bool = False,
    resume: tuple[BuiltMotion, int] | None = None,
) -> BuiltMotion:
    """Keyframes of ``spec`` for ``character`` in the scene ``scene_bvh`` (coal BVH), each
    checked. A swing phase whose keyframes collide, or whose effector does not reach its
    landing, is tracked again from its start with the next higher arc of ``SWING_LIFTS``
    (2PAC section 7.2), a flight whose keyframes collide with its limbs tucked further
    (``FLIGHT_TUCKS``), the best attempt kept. A swing attempt that is not the last stops at
    the first keyframe its limb collides in (the next is tried as it would be after the
    whole phase); only when no later attempt comes clean are the stopped ones tracked whole
    and the best of all kept. ``until`` is polled once per keyframe tracked
    (a retried swing or flight polls again; a plan's work budget charges each poll): when it
    fires, the keyframes so far are returned and the report says ``cut_short``. With
    ``spec.q_end``, a motion not cut short ends exactly there (its last ``END_BLEND_S``
    seconds blended into it, and checked again). With ``abandon_unclean`` (a trial build
    that a caller would refuse), the build stops after the first phase whose best attempt
    collides, lets a stance contact slip, lags the COM curve (``_unclean``) or moves the
    root faster than ``MAX_ROOT_SPEED`` between two keyframes; the report says
    ``abandoned``. With ``resume`` (an earlier build, a phase index p), the earlier build's
    keyframes of the phases before p are kept as they are (``spec``'s phases and COM before
    p must be the ones it was built with) and tracking goes on from the last of them, the
    rest of the keyframes spaced evenly from there; its QP fallbacks are counted in (at
    most)."""
    geometry = character.motion_geometry
    with (
        borrowed_data(character.model) as data,
        borrowed_geometry_data(geometry) as tracked,
        borrowed_geometry_data(geometry) as checked,
    ):
        return _build_motion(
            character,
            scene_bvh,
            spec,
            obstacles=obstacles,
            until=until,
            abandon_unclean=abandon_unclean,
            resume=resume,
            data=data,
            geometry_data=(tracked, checked),
        )


def _build_motion(
    character: Character,
    scene_bvh: Any,
    spec: MotionSpec,
    *,
    obstacles: Sequence[tuple[Any, Any]] = (),
    until: Termination = never,
    abandon_unclean: bool = False,
    resume: tuple[BuiltMotion, int] | None = None,
    data: Any = None,
    geometry_data: tuple[Any, Any] = (None, None),
) -> BuiltMotion:
    """:func:`build_motion` with its tracker's kinematics in ``data`` (a pin.Data) and its
    tracker's and checker's shape placements and distances in ``geometry_data`` (two
    pin.GeometryData of the motion geometry, distance requests signed; made when None)."""
    tracker = WholeBodyTracker(character, scene_bvh, obstacles, data, geometry_data[0])
    checker = KeyframeChecker(character, scene_bvh, obstacles, tracker, geometry_data[1])
    targets = _Targets(character, spec)
    kept = _Segment([], [], [], np.array(spec.q_start, dtype=np.float64), 0.0)
    if resume is not None:
        earlier, first = resume
        for key, check, error in zip(
            earlier.keyframes, earlier.checks, earlier.com_errors, strict=True
        ):
            if targets.phase_index(key.t) >= first:
                break
            kept.keyframes.append(key)
            kept.checks.append(check)
            kept.com_errors.append(error)
        for k in range(min(first, len(earlier.swing_lifts))):
            if spec.phases[k].swing is not None:
                targets.lifts[k] = earlier.swing_lifts[k]
        for k in range(min(first, len(earlier.swing_clearings))):
            if spec.phases[k].swing is not None and earlier.swing_clearings[k] > 0.0:
                targets.clearings[k] = earlier.swing_clearings[k]
        tracker.fallbacks = earlier.report.qp_fallbacks
    if kept.keyframes:
        kept.q = np.array(kept.keyframes[-1].q, dtype=np.float64)
        t_kept = kept.keyframes[-1].t
        grid = phase_keyframe_times(t_kept, spec.phases[-1].t1, spec.rate, targets.break_list)
        grid = grid.tolist()[1:]
    else:
        grid = phase_keyframe_times(
            spec.phases[0].t0, spec.phases[-1].t1, spec.rate, targets.break_list
        ).tolist()
    groups: list[list[float]] = []
    for t in grid:
        k = targets.phase_index(t)
        if groups and targets.phase_index(groups[-1][0]) == k:
            groups[-1].append(t)
        else:
            groups.append([t])
    objects = list(character.motion_geometry.geometryObjects)
    limb_shapes = {
        limb.name: frozenset(
            str(o.name) for o in objects if int(o.parentJoint) in set(limb.joint_ids.tolist())
        )
        for limb in character.limbs
    }
    q = kept.q
    segments: list[_Segment] = [kept] if kept.keyframes else []
    # lagging keyframes the plan may still have (``TRIAL_COM_LAG_BUDGET``)
    lag_budget = lagging_allowed(len(kept.keyframes) + len(grid)) - _lagging(kept.com_errors)
    previous: float | None = kept.keyframes[-1].t if kept.keyframes else None
    retried = sum(
        1
        for k, lift in targets.lifts.items()
        if (swing := spec.phases[k].swing) is not None and lift > swing.lift
    )
    abandoned: int | None = None
    abandoned_because: str | None = None
    for times in groups:
        k = targets.phase_index(times[0])
        swing = spec.phases[k].swing
        flight = spec.phases[k].flight
        # (lift or tuck level, guarded, clearing path): a clearing path's top is found
        # when it is tried (``_clearing_top``)
        attempts = [(0.0, True, False)]
        if flight:
            # a colliding flight is tracked again with its limbs tucked further
            attempts = [(float(n), True, False) for n in range(len(tuning.FLIGHT_TUCKS) + 1)]
        elif swing is not None and swing.lift_off is not None:
            # an overlapping swing: the phases before already followed its arc, which a
            # retry would move under them
            attempts = [(swing.lift, True, False)]
        elif swing is not None:
            lifts = [swing.lift, *(x for x in tuning.SWING_LIFTS if x > swing.lift)]
            # then a box-shaped path over what the arcs run into; last resort: the highest
            # arc with the swinging effector unguarded
            attempts = [
                *((x, True, False) for x in lifts),
                (lifts[-1], True, True),
                (lifts[-1], False, False),
            ]
        best: _Segment | None = None
        best_attempt = attempts[0]
        best_top = 0.0
        entry = _entry_velocity(tracker.model, segments)
        # per attempt made, its segment and its clearing path's top (0: none); an attempt
        # that is not the last stops where its swing collides (a higher one is tried next,
        # as it would be after the whole phase), and is tracked whole only if no later
        # attempt comes clean
        made: list[tuple[_Segment, float]] = []
        stop_at = (
            limb_shapes[swing.limb]
            if swing is not None and not flight and len(attempts) > 1
            else None
        )
        counted: dict[int, int] = {}  # QP fallbacks of each stopped attempt
        for n, (lift, guarded, clearing) in enumerate(attempts):
            if n and flight:
                retried += 1
                targets.tucks[k] = tuning.FLIGHT_TUCKS[n - 1]
            elif n:
                retried += 1
                _aim_swing(
                    targets,
                    k,
                    lift,
                    guarded,
                    _clearing_top(targets, checker, k) if clearing else 0.0,
                )
            tracker.reset(entry)
            fallbacks = tracker.fallbacks
            last_try = n == len(attempts) - 1
            segment = _track_segment(
                tracker, checker, targets, q, times, previous, until, None if last_try else stop_at
            )
            made.append((segment, targets.clearings.get(k, 0.0)))
            if segment.stopped:
                counted[n] = tracker.fallbacks - fallbacks
                continue
            if best is None or segment.score < best.score:
                best, best_attempt = segment, (lift, guarded, clearing)
                best_top = targets.clearings.get(k, 0.0)
            if best.score[0] == 0 or segment.cut_short:
                break
            if swing is not None and not _swing_at_fault(segment, limb_shapes[swing.limb]):
                break  # what collides is not the swinging limb: a higher arc cannot help
        if counted and (best is None or best.score[0] != 0):
            # no attempt came clean: the stopped ones are tracked whole, and the best of all
            # is kept as if each had been tracked whole in turn (the first of the lowest
            # score); one whose stopped part already collides as often as an earlier
            # attempt's whole score, or more often than a later one's, cannot be it
            for n, fallbacks in counted.items():
                floor = (sum(c.colliding for c in made[n][0].checks), 0)
                if any(
                    not made[m][0].stopped and made[m][0].score <= floor for m in range(n)
                ) or any(
                    not made[m][0].stopped and made[m][0].score < floor
                    for m in range(n + 1, len(made))
                ):
                    continue
                lift, guarded, clearing = attempts[n]
                _aim_swing(targets, k, lift, guarded, made[n][1])
                tracker.fallbacks -= fallbacks
                tracker.reset(entry)
                made[n] = (
                    _track_segment(tracker, checker, targets, q, times, previous, until),
                    made[n][1],
                )
            best = None
            for n, (segment, top) in enumerate(made):
                if not segment.stopped and (best is None or segment.score < best.score):
                    best, best_attempt, best_top = segment, attempts[n], top
        assert best is not None
        if flight:
            level = int(best_attempt[0])
            if level:
                targets.tucks[k] = tuning.FLIGHT_TUCKS[level - 1]
            else:
                targets.tucks.pop(k, None)
        elif swing is not None:
            lift, guarded, clearing = best_attempt
            _aim_swing(targets, k, lift, guarded, best_top if clearing else 0.0)
        last_key = segments[-1].keyframes[-1] if segments and segments[-1].keyframes else None
        segments.append(best)
        q = best.q
        previous = times[-1]
        if best.cut_short:
            break
        if abandon_unclean and (unclean := _unclean(best, last_key, lag_budget)) is not None:
            abandoned, abandoned_because = k, unclean
            break
        lag_budget -= _lagging(best.com_errors)
    keyframes = [key for s in segments for key in s.keyframes]
    checks = [c for s in segments for c in s.checks]
    com_errors = [e for s in segments for e in s.com_errors]
    cut_short = any(s.cut_short for s in segments)
    if spec.q_end is not None and not cut_short and abandoned is None:
        q = _blend_into(checker, targets, keyframes, checks, com_errors, spec.q_end)
    errors = np.asarray(com_errors)
    colliding = tuple(key.t for key, c in zip(keyframes, checks, strict=True) if c.colliding)
    deepest = max(checks, key=lambda c: c.scene_depth)
    last_t = keyframes[-1].t
    report = MotionReport(
        phases_animated=sum(1 for p in spec.phases if p.t1 <= last_t + 1e-9),
        phases_total=len(spec.phases),
        cut_short=cut_short,
        colliding_keyframes=len(colliding),
        worst_scene_depth=deepest.scene_depth,
        worst_shape=deepest.shape,
        worst_self_depth=max(c.self_depth for c in checks),
        max_hold_error=max(c.hold_error for c in checks),
        com_error_max=float(errors.max()),
        com_error_p99=float(np.percentile(errors, 99)),
        qp_fallbacks=tracker.fallbacks,
        swings_raised=retried,
        colliding_times=colliding,
        abandoned=abandoned is not None,
        abandoned_phase=abandoned,
        abandoned_because=abandoned_because,
    )
    phases = tuple(Phase(t0=p.t0, t1=p.t1, contacts=p.stance) for p in spec.phases)
    com_segments = tuple(
        ComSegment(t0=float(s.t0), t1=float(s.t1), control_points=s.control_points)
        for s in spec.com.segments
    )
    swing_lifts = tuple(
        0.0 if p.swing is None else targets.lifts.get(k, p.swing.lift)
        for k, p in enumerate(spec.phases)
    )
    swing_clearings = tuple(targets.clearings.get(k, 0.0) for k in range(len(spec.phases)))
    return BuiltMotion(
        phases,
        com_segments,
        tuple(keyframes),
        report,
        q,
        swing_lifts,
        tuple(checks),
        tuple(com_errors),
        swing_clearings,
    )
