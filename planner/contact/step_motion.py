"""The motion of one contact change: contact phases, a 2PAC COM curve and whole-body keyframes.

2PAC sections 6-7.2: two phases (before, after) with the kinematic COM polytopes of their
effectors; keyframes by IK following the COM curve while holding the stance contacts and
moving the swing effector along an arc. A keyframe colliding with the scene triggers one
retry with a higher swing arc (local collision handling within a small budget).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.contact.checks import (
    com_of,
    effector_pose,
    kinematics_of,
    phase_of,
    scene_collisions,
    self_collides,
)
from planner.contact.context import ContactContext
from planner.contact.generation import hold_tasks
from planner.contact.state import ContactState
from planner.kinematics import swing_trajectory, track_com
from planner.motion import ComSegment, Keyframe, Phase
from trajectory import plan_com_trajectory

FloatArray = NDArray[np.float64]

_LIFTS = (0.08, 0.18)  # m, swing arc heights tried in turn


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


def step_motion(
    ctx: ContactContext,
    before: ContactState,
    after: ContactState,
    limb: str,
    *,
    rate: float = 30.0,
) -> StepMotion:
    """Phases, COM curve and keyframes taking ``before`` to ``after`` (``limb`` changes)."""
    phase_b, phase_a = phase_of(ctx, before.contacts), phase_of(ctx, after.contacts)
    kin_b, kin_a = kinematics_of(ctx, before.contacts), kinematics_of(ctx, after.contacts)
    c0, c1 = com_of(ctx, before.q), com_of(ctx, after.q)
    traj = plan_com_trajectory(
        [phase_b, phase_a], c0, c1, kinematics=[kin_b, kin_a], n_checks=3, min_window=0.6
    )
    times = np.asarray(traj.phase_times, dtype=np.float64)
    curve = traj.curve
    t_end = float(curve.t1)

    def com_at(t: float) -> FloatArray:
        tt = min(max(t, float(curve.t0)), t_end)
        return np.asarray(curve(np.array([tt]))[0], dtype=np.float64)

    creating = after.contact(limb) is not None
    spec = ctx.character.limb(limb)
    start_pose = effector_pose(ctx, limb, before.q)
    end_pose = effector_pose(ctx, limb, after.q)
    swing_phase = 0 if creating else 1
    stances = (before.contacts, after.contacts)
    best: tuple[list[FloatArray], list[float], float, int] | None = None
    for lift in _LIFTS:
        qs: list[FloatArray] = []
        ts: list[float] = []
        q = np.array(before.q)
        worst_hold = 0.0
        for j in range(2):
            t0, t1 = float(times[j]), float(times[j + 1])
            if t1 - t0 < 1e-9:
                continue
            swing = None
            frame = None
            if j == swing_phase:
                arc = swing_trajectory(
                    start_pose, end_pose, t0, t1, lift=lift, normal_in_frame=spec.normal
                )
                if spec.contact == "point":

                    def swing(t: float, arc: Any = arc) -> FloatArray:
                        return np.asarray(arc(t)[:3, 3], dtype=np.float64)

                else:
                    swing = arc
                frame = spec.frame_id
            track = track_com(
                ctx.model,
                q,
                com_at,
                stance=hold_tasks(stances[j], ctx),
                swing_frame=frame,
                swing=swing,
                reference=after.q,
                t_start=t0,
                t_end=t1,
                rate=rate,
                data=ctx.pin_data,
                max_iterations=20,
            )
            start = 0 if not ts else 1
            qs.extend(np.array(c) for c in track.configurations[start:])
            ts.extend(float(t) for t in track.times[start:])
            if len(track.contact_errors):
                worst_hold = max(worst_hold, float(np.max(track.contact_errors)))
            q = np.array(track.configurations[-1])
        qs[0] = np.array(before.q)
        qs[-1] = np.array(after.q)
        hits = sum(
            1 for qq in qs[1:-1] if scene_collisions(ctx, qq) or self_collides(ctx, qq)
        )
        if best is None or hits < best[3]:
            best = (qs, ts, worst_hold, hits)
        if hits == 0:
            break
    assert best is not None
    qs, ts, worst_hold, hits = best
    keyframes = tuple(
        Keyframe(t, qq, tuple(c.limb for c in _stance_at(t, times, stances)))
        for t, qq in zip(ts, qs, strict=True)
    )
    phases = (
        Phase(float(times[0]), float(times[1]), before.contacts),
        Phase(float(times[1]), float(times[2]), after.contacts),
    )
    com = tuple(ComSegment(s.t0, s.t1, np.array(s.control_points)) for s in traj.segments)
    report: dict[str, Any] = {
        "phases": [
            {
                "phase": r.phase,
                "t0": r.t0,
                "t1": r.t1,
                "fraction_valid": r.fraction_valid,
                "worst_violation": r.worst_violation,
            }
            for r in traj.reports
        ],
        "transition_slack": [float(tp.slack) for tp in traj.transitions],
        "quasi_static_feasible": bool(traj.quasi_static_feasible),
        "max_hold_error": worst_hold,
        "colliding_keyframes": hits,
        "collisions_fixed": 0 if hits else int(best is not None and len(_LIFTS) > 0) * 0,
    }
    return StepMotion(phases, com, keyframes, report)


def _stance_at(t: float, times: FloatArray, stances: tuple[Any, Any]) -> Any:
    return stances[0] if t < float(times[1]) else stances[1]
