"""Contact sequence along a root path (anchor section 5), one contact change per state.

Walking the path in steps of ``spacing``: contacts are kept while inverse kinematics can hold
them at the next root pose; a contact that cannot be held is broken (oldest first) before
the root moves on; a free limb gets a new contact, scored by a look-ahead target (its
reference effector position at the root pose ``lookahead`` metres further along the path).
At the end, the goal contacts are made one at a time. Every emitted state differs from the
previous one by exactly one contact added or removed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.contact.context import ContactContext, FailureReason
from planner.contact.generation import break_contact, create_contact, maintain
from planner.contact.state import ContactState
from planner.kinematics import frame_placement
from planner.result import PlanResult, PlanStatus
from planner.termination import Termination

FloatArray = NDArray[np.float64]
_STEP_FRACTIONS = (1.0, 0.66, 0.33, 0.0)


@dataclass(frozen=True, slots=True)
class SequenceParams:
    """spacing : m between root samples along the path (the anchor uses 0.01 s of guide time).
    lookahead : m ahead along the path that scores new contacts. goal_tolerance : m, a
    contact this close to the goal's counts as reached. max_states : cap on emitted states.
    max_stuck : consecutive root samples where nothing helps before giving up.
    stride : m a contact may fall behind its reference position (along the path) before its
    limb is lifted proactively. finish : m before the path end where the goal phase starts.
    goal_steps : rounds of half-way steps toward far goal contacts. widen : m a colliding
    foothold target is moved outward (away from the path) for a second try.
    """

    spacing: float = 0.05
    lookahead: float = 0.3
    goal_tolerance: float = 0.03
    max_states: int = 200
    max_stuck: int = 3
    stride: float = 0.12
    finish: float = 0.05
    goal_steps: int = 3
    widen: float = 0.06

    def __post_init__(self) -> None:
        if not 0 < self.spacing <= 0.5:
            raise ValueError("spacing must be in (0, 0.5] m")
        if not 0 < self.max_states <= 10_000:
            raise ValueError("max_states must be in [1, 10000]")


def _reference_offsets(ctx: ContactContext) -> dict[str, FloatArray]:
    """Each limb's effector position in the root frame at the reference posture."""
    q_ref = np.asarray(ctx.character.q_ref)
    root_inv = np.linalg.inv(frame_placement(ctx.model, q_ref, 1))
    out = {}
    for limb in ctx.character.limbs:
        placement = frame_placement(ctx.model, q_ref, limb.effector_frame)
        out[limb.name] = (root_inv @ placement)[:3, 3]
    return out


def _along(poses: FloatArray, lengths: FloatArray, s: float) -> FloatArray:
    """The root pose (4, 4) nearest to arc length ``s`` along the sampled path."""
    index = int(np.clip(np.searchsorted(lengths, s), 0, len(poses) - 1))
    return np.asarray(poses[index])


def _behind(
    state: ContactState, offsets: dict[str, FloatArray], pose: FloatArray, heading: FloatArray
) -> dict[str, float]:
    """Per contact limb, m its contact lies behind its reference position at root ``pose``
    (4, 4), measured along the unit path ``heading`` (3,)."""
    out = {}
    for c in state.contacts:
        ref = pose[:3, :3] @ offsets[c.limb] + pose[:3, 3]
        out[c.limb] = float(np.dot(ref - c.position, heading))
    return out


def _toward(q: FloatArray, pose: FloatArray, step: float) -> FloatArray:
    """Root pose (4, 4) with ``pose``'s orientation, moved from the root of ``q`` toward
    ``pose``'s position by at most ``1.5 * step`` m (no jump back onto a path the whole-body
    IK has drifted from)."""
    out = np.array(pose)
    delta = pose[:3, 3] - q[:3]
    n = float(np.linalg.norm(delta))
    if n > 1.5 * step:
        out[:3, 3] = q[:3] + delta * (1.5 * step / n)
    return out


def _heading(poses: FloatArray, index: int) -> FloatArray:
    """Unit horizontal direction (3,) of the path around sample ``index``."""
    a = poses[max(index - 2, 0), :3, 3]
    b = poses[min(index + 2, len(poses) - 1), :3, 3]
    d = np.array([b[0] - a[0], b[1] - a[1], 0.0])
    n = float(np.linalg.norm(d))
    if n < 1e-9:
        d = poses[index, :3, 0] * np.array([1.0, 1.0, 0.0])
        n = float(np.linalg.norm(d)) or 1.0
    return np.asarray(d / n, dtype=np.float64)


def contact_sequence(
    ctx: ContactContext,
    start: ContactState,
    poses: FloatArray,
    goal: ContactState | None,
    *,
    rng: np.random.Generator,
    until: Termination,
    params: SequenceParams | None = None,
) -> PlanResult[tuple[ContactState, ...]]:
    """States from ``start`` along root ``poses`` (n, 4, 4) (dense, <= spacing apart) to ``goal``.

    SOLVED when the goal contacts are all made; APPROXIMATE with the states found so far when
    stuck; TIMEOUT (with the partial states) when ``until`` fires.
    """
    p = params or SequenceParams()
    offsets = _reference_offsets(ctx)
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    lengths = np.concatenate([[0.0], np.cumsum(steps)])
    states: list[ContactState] = [start]
    current = start
    free_since = {limb: -1 for limb in ctx.limb_names() if start.contact(limb) is None}
    index = 0
    stats: dict[str, float | int | str] = {"breaks": 0, "creations": 0, "root_samples": 0}

    def emit(state: ContactState, kind: str) -> None:
        # Whole-body IK may carry the root along the path: walk on from the nearest path
        # sample ahead of us, never back.
        nonlocal current, index
        current = state
        states.append(state)
        stats[kind] = int(stats[kind]) + 1
        ahead = poses[index:, :3, 3]
        index += int(np.argmin(np.linalg.norm(ahead - state.q[:3], axis=1)))

    def try_create() -> bool:
        # The longest step first: the limb's reference position at the root pose `lookahead`
        # metres ahead, then shorter ones.
        for limb in sorted(free_since, key=free_since.__getitem__):
            for fraction in _STEP_FRACTIONS:
                ahead = _along(poses, lengths, float(lengths[index]) + fraction * p.lookahead)
                target = ahead[:3, :3] @ offsets[limb] + ahead[:3, 3]
                attempt = create_contact(ctx, current, limb, rng=rng, target=target)
                if attempt.reason is FailureReason.COLLISION:
                    # one candidate per surface: try the point a little further outward
                    side = ahead[:3, :3] @ np.array([0.0, offsets[limb][1], 0.0])
                    norm = float(np.linalg.norm(side))
                    if norm > 1e-6:
                        wider = target + side * (p.widen / norm)
                        attempt = create_contact(ctx, current, limb, rng=rng, target=wider)
                if attempt.ok and index + 1 < len(poses):
                    # a contact made at full stretch would be lost at the next root sample
                    nxt = _toward(attempt.state.q, poses[index + 1], p.spacing)
                    if limb in maintain(ctx, attempt.state, nxt)[1]:
                        continue
                if attempt.ok:
                    free_since.pop(limb)
                    emit(attempt.state, "creations")
                    return True
                if attempt.reason is FailureReason.NOTHING_REACHABLE and fraction == 1.0:
                    break  # no surface near this limb at all: shorter steps will not help
        return False

    def result(status: PlanStatus, message: str = "") -> PlanResult[tuple[ContactState, ...]]:
        stats["states"] = len(states)
        return PlanResult(status, tuple(states), dict(stats), message)

    def try_break(order: Sequence[str]) -> bool:
        for limb in order:
            attempt = break_contact(ctx, current, limb)
            if attempt.ok:
                free_since[limb] = index
                emit(attempt.state, "breaks")
                return True
        return False

    stuck = 0
    last_reason = ""
    while index < len(poses) - 1:
        if until():
            return result(PlanStatus.TIMEOUT, "time budget spent while walking the path")
        if len(states) >= p.max_states:
            return result(PlanStatus.APPROXIMATE, f"stopped at {p.max_states} states")
        if lengths[-1] - lengths[index] <= p.finish:
            break  # close to the end: make the goal contacts from here
        if free_since and try_create():
            stuck = 0
            continue
        moved, lost = maintain(ctx, current, _toward(current.q, poses[index + 1], p.spacing))
        stats["root_samples"] = int(stats["root_samples"]) + 1
        heading = _heading(poses, index)
        behind = _behind(current, offsets, poses[index + 1], heading)
        lagging = [limb for limb, b in behind.items() if b > p.stride]
        if not lost and not (lagging and not free_since):
            current = moved
            index += 1
            continue
        if not free_since:
            # proactive gait: lift the limb furthest behind that can be released
            pool = lost if lost else lagging
            if try_break(sorted(pool, key=lambda x: -behind[x])):
                stuck = 0
                continue
            if not lost:  # nothing can be lifted yet: let the body move on over its feet
                current = moved
                index += 1
                continue
            if try_break(sorted((x for x in behind if x not in lost), key=lambda x: -behind[x])):
                continue
        elif lost:
            victim = sorted(lost, key=lambda x: -behind[x])
            if try_create():
                continue
            if try_break(victim):
                continue
        else:
            current = moved
            index += 1
            continue
        last_reason = f"cannot release any of {sorted(behind)}"
        stuck += 1
        if stuck > p.max_stuck:
            return result(
                PlanStatus.APPROXIMATE,
                f"stuck at {lengths[index]:.2f} m of {lengths[-1]:.2f} m: {last_reason}",
            )
        index += 1  # the anchor skips a sample once; the next pose may be easier

    return _reach_goal(ctx, current, goal, states, free_since, stats, rng, until, p)


def _reach_goal(
    ctx: ContactContext,
    current: ContactState,
    goal: ContactState | None,
    states: list[ContactState],
    free_since: dict[str, int],
    stats: dict[str, float | int | str],
    rng: np.random.Generator,
    until: Termination,
    p: SequenceParams,
) -> PlanResult[tuple[ContactState, ...]]:
    """Make the goal's contacts one change at a time (break misplaced ones, then create)."""
    if goal is None:
        wanted: Sequence[str] = [limb for limb in ctx.limb_names() if limb in free_since]
        targets: dict[str, FloatArray | None] = dict.fromkeys(wanted)
        surfaces: dict[str, int | None] = dict.fromkeys(wanted)
    else:
        targets = {c.limb: c.position for c in goal.contacts}
        surfaces = {c.limb: (c.surface if c.surface >= 0 else None) for c in goal.contacts}
    for _ in range(p.goal_steps):  # limbs out of reach of their goal walk halfway first
        for limb, target in targets.items():
            existing = current.contact(limb)
            if until() or target is None:
                continue
            start = existing.position if existing is not None else current.q[:3]
            if np.linalg.norm(start[:2] - target[:2]) <= 0.25:
                continue
            partial = np.array(target)
            partial[:2] = 0.5 * (start[:2] + target[:2])
            released = break_contact(ctx, current, limb) if existing is not None else None
            if released is not None and not released.ok:
                continue
            base = released.state if released is not None else current
            made = create_contact(ctx, base, limb, rng=rng, target=target)
            if not made.ok:
                made = create_contact(ctx, base, limb, rng=rng, target=partial)
            if not made.ok:
                continue
            if released is not None:
                states.append(released.state)
                stats["breaks"] = int(stats["breaks"]) + 1
            current = made.state
            states.append(current)
            stats["creations"] = int(stats["creations"]) + 1
            free_since.pop(limb, None)
    failures: list[str] = []
    for limb, target in targets.items():
        if until():
            break
        existing = current.contact(limb)
        if existing is not None and (
            target is None or np.linalg.norm(existing.position - target) <= p.goal_tolerance
        ):
            continue
        if existing is not None:
            released = break_contact(ctx, current, limb)
            if not released.ok:
                failures.append(f"{limb}: cannot release ({released.message})")
                continue
            current = released.state
            states.append(current)
            stats["breaks"] = int(stats["breaks"]) + 1
        made = create_contact(ctx, current, limb, rng=rng, target=target, surface=surfaces[limb])
        if made.ok and (
            target is None
            or np.linalg.norm(made.state.contact(limb).position - target)  # type: ignore[union-attr]
            <= p.goal_tolerance
        ):
            current = made.state
            states.append(current)
            stats["creations"] = int(stats["creations"]) + 1
        else:
            failures.append(f"{limb}: goal contact not made ({made.message or 'too far'})")
    if goal is not None:
        for limb in [c for c in current.limbs if goal.contact(c) is None]:
            released = break_contact(ctx, current, limb)
            if released.ok:
                current = released.state
                states.append(current)
                stats["breaks"] = int(stats["breaks"]) + 1
            else:
                failures.append(f"{limb}: cannot release for the goal")
    stats["states"] = len(states)
    if until() and failures:
        return PlanResult(PlanStatus.TIMEOUT, tuple(states), dict(stats), "; ".join(failures))
    if failures:
        return PlanResult(PlanStatus.APPROXIMATE, tuple(states), dict(stats), "; ".join(failures))
    return PlanResult(PlanStatus.SOLVED, tuple(states), dict(stats))
