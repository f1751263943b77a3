"""A walk that strands a leg behind its body (the body cannot move on and a leg behind it
cannot be released, ``STRANDED_CYCLES`` gait cycles running) goes back to its last state that
can release that leg and walks on from there, that leg guarded until it has stepped
(``SequenceParams.backtracks``), instead of stepping its other legs to and fro until it
stalls and the planner walks again from the start."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planner.contact.generation import break_contact
from planner.contact.planner import Endpoint, plan_contact_motion
from planner.contact.sequence import release_point
from planner.result import PlanStatus
from tests.planner.contact.contact_helpers import character_and_data, scene, solved_flat_walk

# m: starts of the hexapod's 1 m flat walk near the origin; from about half of the starts
# within a few millimetres of it (the first two here), the walk strands its right rear leg
# 0.76 m along (measured with ``bench/motion.py --nudge``)
HEXAPOD_STARTS = ((-0.001, 0.0), (0.0, 0.001), (0.0, 0.0), (0.001, 0.0))


def test_the_release_point_is_the_latest_state_with_every_leg_down_that_releases_the_leg() -> None:
    plan, ctx = solved_flat_walk("quadruped")
    states = plan.states
    full = len(states[0].contacts)

    def releases(k: int, leg: str) -> bool:
        state = states[k]
        down = len(state.contacts) == full and state.contact(leg) is not None
        return down and break_contact(ctx, state, leg).ok

    for leg in states[0].limbs:
        k = release_point(ctx, states, leg, len(states))
        assert k is not None and k > 0
        assert releases(k, leg)
        assert not any(releases(j, leg) for j in range(k + 1, len(states)))
        # a window that ends short of that state finds none
        assert release_point(ctx, states, leg, len(states) - 1 - k) is None
    assert release_point(ctx, states, states[0].limbs[0], 0) is None


@pytest.mark.slow
def test_the_hexapod_walks_from_nearby_starts_in_one_walk_backtracking_where_it_strands() -> None:
    character, data = character_and_data("hexapod")
    backtracked = 0
    for dx, dy in HEXAPOD_STARTS:
        plan = plan_contact_motion(
            scene("flat"),
            character,
            data,
            Endpoint(stand_at=np.array([dx, dy, 0.0])),
            Endpoint(stand_at=np.array([1.0, 0.0, 0.0])),
            rng=np.random.default_rng(1),
            time_budget_s=20.0,
            cap_s=600.0,
        )
        assert plan.status is PlanStatus.SOLVED and plan.value is not None, (dx, dy, plan.message)
        assert plan.stats["attempts"] == 1, (dx, dy)  # no second walk from the start
        for before, after in itertools.pairwise(plan.value.states):
            assert after.differs_by_one(before)
        backtracked += int(plan.stats.get("backtracks", 0))
    assert backtracked >= 1, (
        "none of these starts strands a leg any more: pick starts that do (bench/motion.py "
        "--nudge shows them) to keep the backtrack exercised"
    )
