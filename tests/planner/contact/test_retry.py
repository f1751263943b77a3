"""A walk that stalls is retried from a little before where it stalled, its states up to
there kept (``planner.contact.planner``, ``sequence.resume_index``), instead of walking the
whole guide again; one stuck short of its guide's end with no foothold in reach is walked on
once more with the footholds that led it there avoided (walked on as it was, it would come
back to the same place), then the next walk starts over on a new guide."""

from __future__ import annotations

import itertools
from typing import Any, NamedTuple

import numpy as np
import pytest
from numpy.typing import NDArray

import planner.contact.planner as contact_planner
from planner.contact.generation import AVOID_RADIUS
from planner.contact.planner import (
    DETOUR_RADIUS,
    RESUME_BACK_M,
    Endpoint,
    PlanOptions,
    _detour_checker,
    plan_contact_motion,
)
from planner.contact.reachability import ReachabilityChecker
from planner.contact.sequence import SequenceParams, resume_index
from planner.contact.state import ContactState
from planner.result import PlanResult, PlanStatus
from planner.scene.builtin import GAPS_HEIGHTS, gaps_platform_ranges
from tests.planner.contact.contact_helpers import character_and_data, flat_walk, scene

FloatArray = NDArray[np.float64]


@pytest.mark.parametrize("back_m", [0.0, 0.2, RESUME_BACK_M, 0.7, 5.0])
def test_the_resume_point_is_the_last_state_with_every_leg_down_that_far_back(
    back_m: float,
) -> None:
    plan = flat_walk("quadruped")
    assert plan.value is not None
    states, poses = plan.value.states, plan.value.root_path
    k = resume_index(states, poses, back_m)
    x = np.array([float(s.q[0]) for s in states])  # the guide runs straight along +x
    spacing = float(np.linalg.norm(poses[1, :3, 3] - poses[0, :3, 3]))
    full = len(states[0].contacts)
    assert len(states[k].contacts) == full
    if k == 0:  # no state with every leg down stands that far back
        later = [j for j in range(1, len(states)) if len(states[j].contacts) == full]
        assert all(x[j] > x.max() - back_m - spacing for j in later)
        return
    assert x[k] <= x.max() - back_m + spacing
    for j in range(k + 1, len(states)):  # the last such state
        if len(states[j].contacts) == full:
            assert x[j] > x.max() - back_m - spacing


class Walk(NamedTuple):
    """One contact walk a plan made: where it started, its guide's root poses (n, 4, 4),
    whether it resumed a stalled one, and its result."""

    start: ContactState
    guide: FloatArray
    resumed: bool
    result: PlanResult[tuple[ContactState, ...]]
    avoid: tuple[tuple[str, FloatArray], ...]


def _plan_recording_walks(
    scene_id: str,
    start: FloatArray,
    goal: FloatArray,
    budget_s: float,
    options: PlanOptions | None = None,
) -> tuple[PlanResult[Any], list[Walk]]:
    """The humanoid's plan from ``start`` to ``goal`` (stand_at points (3,)) at seed 1, and
    the real contact walks it made, in order."""
    walks: list[Walk] = []
    real_walk = contact_planner.contact_sequence

    def recorded(ctx: Any, begin: ContactState, poses: Any, *args: Any, **kwargs: Any) -> Any:
        walk = real_walk(ctx, begin, poses, *args, **kwargs)
        avoid = tuple(kwargs.get("avoid", ()))
        walks.append(Walk(begin, np.asarray(poses), bool(kwargs.get("resume")), walk, avoid))
        return walk

    character, data = character_and_data("humanoid")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(contact_planner, "contact_sequence", recorded)
        result = plan_contact_motion(
            scene(scene_id),
            character,
            data,
            Endpoint(stand_at=start),
            Endpoint(stand_at=goal),
            rng=np.random.default_rng(1),
            time_budget_s=budget_s,
            cap_s=600.0,
            options=options,
        )
    return result, walks


def test_a_stalled_walk_is_walked_on_from_before_where_it_stalled() -> None:
    """Climbing the cube wall with one idle gait round allowed, the first walk stalls among
    the cubes, at 1.39 m, without getting further (it is not stuck for want of a foothold):
    the next walk goes on along the same guide from before where it stalled, its states up
    to there kept."""
    # the climbing wall scenario's plan (tests/scenarios/plans/climbing_wall_humanoid.json),
    # whose walks, with the default idle rounds, now get past the cubes the first time
    options = PlanOptions(
        limbs=("left_hand", "right_hand"),
        sequence=SequenceParams(max_states=400, idle_rounds=1),
    )
    result, walks = _plan_recording_walks(
        "climbing_wall", np.array([0.5, 0.0, 0.0]), np.array([3.3, 0.0, 1.4]), 60.0, options
    )
    assert len(walks) >= 2
    first, _, resumed, stalled, _ = walks[0]
    assert not resumed and stalled.status is PlanStatus.APPROXIMATE
    assert not stalled.stats.get("stranded") and not stalled.stats.get("blocked")
    start, _, resumed, _, _ = walks[1]
    assert resumed
    before = stalled.value
    assert before is not None
    # the retry starts from one of the stalled walk's states, every leg down, that far back
    k = next(j for j, state in enumerate(before) if state is start)
    assert len(start.contacts) >= len(first.contacts)  # every leg down
    assert float(start.q[0]) <= max(float(s.q[0]) for s in before) - RESUME_BACK_M + 0.05
    # whatever attempt won, the answer is one contact change at a time from the start
    assert result.value is not None
    answer = result.value.states
    assert answer[0] is first
    for a, b in itertools.pairwise(answer):
        assert b.differs_by_one(a)
    assert k >= 1
    # a resumed answer keeps the stalled walk's states before the point it resumed from
    kept = min(int(result.stats.get("resumed_at", 0)), k)
    assert all(a is b for a, b in zip(answer[:kept], before[:kept], strict=True))


def _assert_avoided(walk: Walk) -> None:
    """No contact ``walk`` made after its start lies within ``AVOID_RADIUS`` of a point its
    limb was to avoid."""
    states = walk.result.value or ()
    for before, after in itertools.pairwise((walk.start, *states)):
        for contact in after.contacts:
            if before.contact(contact.limb) is not None:
                continue
            for limb, point in walk.avoid:
                if limb == contact.limb:
                    gap = float(np.linalg.norm(np.asarray(contact.position) - point))
                    assert gap >= AVOID_RADIUS - 1e-9, (limb, gap)


def test_a_walk_blocked_short_of_its_guide_end_is_walked_on_once_then_starts_over() -> None:
    """The humanoid cannot step across the first gap at this seed: its first walk is stuck
    there, short of its guide's end, with no foothold within reach ahead
    (``stats["blocked"]``). The next walk goes on along the same guide from before where it
    stuck, every foothold the first took in its last ``RESUME_BACK_M`` of guide avoided; it
    is stuck at the gap again, and the walk after it starts over from the start."""
    ranges = gaps_platform_ranges()
    middle = [(x0 + x1) / 2 for x0, x1 in ranges]
    result, walks = _plan_recording_walks(
        "gaps",
        np.array([middle[0], 0.0, GAPS_HEIGHTS[0]]),
        np.array([middle[1], 0.0, GAPS_HEIGHTS[1]]),
        10.0,
    )
    assert result.status is not PlanStatus.SOLVED
    assert len(walks) >= 3
    first, poses, resumed, stalled, _ = walks[0]
    assert not resumed and stalled.status is PlanStatus.APPROXIMATE
    assert stalled.stats.get("blocked") == 1, stalled.message
    walked = stalled.value
    assert walked is not None
    k = resume_index(walked, poses, RESUME_BACK_M)
    again = walks[1]
    assert again.resumed and again.start is walked[k]
    taken = [
        (c.limb, c.position)
        for before, after in itertools.pairwise(walked[k:])
        for c in after.contacts
        if before.contact(c.limb) is None
    ]
    assert taken and len(again.avoid) == len(taken)
    for (limb, point), (avoided_limb, avoided) in zip(taken, again.avoid, strict=True):
        assert limb == avoided_limb
        np.testing.assert_array_equal(point, avoided)
    _assert_avoided(again)
    assert again.result.stats.get("blocked") == 1
    assert not walks[2].resumed and walks[2].start is first


def test_rubbles_blocked_straight_walk_gets_through_avoiding_its_dead_end() -> None:
    """Walking diagonally across the rubble's tilted slabs along the straight line, the
    first walk puts a foot on a slab from which no foothold ahead is in reach: blocked. Walked
    on from before, that foothold avoided, it gets to the goal along the same guide. Which
    slab a foot takes moves with millimetres of the start (a start 1 mm back walks straight
    through), so three starts a fraction of a millimetre apart are planned: every plan
    solves, every resumed walk avoids what it was given, and at least one goes through the
    dead end this way."""
    through_dead_end = 0
    for nudge in (0.0, 0.0005, 0.001):
        result, walks = _plan_recording_walks(
            "rubble", np.array([-0.3 + nudge, 0.5, 0.0]), np.array([2.8, 2.5, 0.0]), 30.0
        )
        assert result.status is PlanStatus.SOLVED, (nudge, result.message)
        for walk in walks:
            _assert_avoided(walk)
        if len(walks) >= 2 and walks[0].result.stats.get("blocked") == 1:
            first, again = walks[0], walks[1]
            assert again.resumed and again.avoid
            np.testing.assert_array_equal(again.guide, first.guide)
            through_dead_end += again.result.status is PlanStatus.SOLVED
    assert through_dead_end >= 1


def test_a_walk_started_over_after_stalls_follows_a_guide_round_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Walking diagonally across the rubble's tilted slabs, the first walk stalls among
    them (here not walked on again past its dead end: ``BLOCKED_RESUMES`` 0); a new search
    finds the same straight guide first (the trunk clears every slab), which would lead back
    to the same footholds, so a guide planned after stalls keeps the trunk
    ``DETOUR_RADIUS`` from where the walks stalled, and the plan gets through. Whether the
    straight walk stalls moves with millimetres of the start (a start 1 mm back walks
    straight through): three starts a fraction of a millimetre apart are planned, every new
    guide after a stall keeps its distance, and at least one plan needs such a guide."""
    monkeypatch.setattr(contact_planner, "BLOCKED_RESUMES", 0)
    detoured = 0
    for nudge in (0.0, 0.0005, 0.001):
        result, walks = _plan_recording_walks(
            "rubble", np.array([-0.3 + nudge, 0.5, 0.0]), np.array([2.8, 2.5, 0.0]), 30.0
        )
        assert result.status is PlanStatus.SOLVED, (nudge, result.message)
        stalls: list[FloatArray] = []
        new_guides = 0
        for _, poses, resumed, walk, _ in walks:
            if not resumed and stalls:
                new_guides += 1
                roots = poses[:, :2, 3]
                for stall in stalls:
                    gaps = np.linalg.norm(roots - stall[:2], axis=1)
                    assert float(gaps.min()) >= DETOUR_RADIUS, (stall, float(gaps.min()))
            if walk.status is not PlanStatus.SOLVED and walk.value:
                stalls.append(np.asarray(walk.value[-1].q[:3]))
        detoured += bool(stalls) and new_guides >= 1
    assert detoured >= 1


def test_a_stall_near_either_end_of_the_guide_is_not_avoided() -> None:
    """A stall within ``DETOUR_RADIUS`` and the trunk's reach of the start or the goal is
    not fenced off (the guide could not start or end); one farther is, and a root pose over
    it fails the condition that the start still meets."""
    character, data = character_and_data("humanoid")
    flat = scene("flat")
    checker = ReachabilityChecker(flat, character, data)
    start, goal = np.array([0.0, 0.0, 0.9]), np.array([3.0, 0.0, 0.9])
    near = start + np.array([DETOUR_RADIUS, 0.0, 0.0])
    assert _detour_checker(flat, character, data, checker, [near], (start, goal)) is None
    middle = np.array([1.5, 0.0, 0.9])
    detour = _detour_checker(flat, character, data, checker, [near, middle], (start, goal))
    assert detour is not None
    at_start = np.eye(4)
    at_start[:3, 3] = [0.0, 0.0, float(character.q_ref[2])]
    over = at_start.copy()
    over[:2, 3] = middle[:2]
    assert checker.is_valid(over) and not detour.is_valid(over)
    assert detour.is_valid(at_start)
