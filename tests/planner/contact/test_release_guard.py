"""The walker's release guard (``SequenceParams.release_guard``): with it, no step or advance
leaves a leg behind the body where it could be released before and cannot be any more."""

from __future__ import annotations

import itertools

import numpy as np

from planner.contact.generation import break_contact
from planner.contact.sequence import SequenceParams, contact_sequence
from planner.result import PlanStatus
from tests.planner.contact.contact_helpers import solved_flat_walk


def test_a_guarded_walk_never_strands_a_leg_behind_the_body() -> None:
    plan, ctx = solved_flat_walk("quadruped")
    states = plan.states
    guarded = contact_sequence(
        ctx,
        states[0],
        plan.root_path,
        states[-1],
        rng=np.random.default_rng(4),
        until=lambda: False,
        params=SequenceParams(release_guard=True),
    )
    assert guarded.status is PlanStatus.SOLVED, guarded.message
    assert not guarded.stats.get("stranded")
    walked = guarded.value
    assert walked is not None
    for before, after in itertools.pairwise(walked):
        assert after.differs_by_one(before)
    # the guard compares the states a step goes between (a break and the make after it)
    settled = [s for s in walked if len(s.contacts) == len(walked[0].contacts)]
    assert len(settled) > 4
    for before, after in itertools.pairwise(settled):
        root_x = float(before.q[0])  # the guide runs along +x
        for contact in before.contacts:
            kept = after.contact(contact.limb)
            if kept is None or not np.allclose(kept.position, contact.position):
                continue  # the leg that stepped
            if contact.position[0] >= root_x:
                continue  # a leg ahead of the body
            if break_contact(ctx, before, contact.limb).ok:
                released = break_contact(ctx, after, contact.limb)
                assert released.ok, f"{contact.limb} stranded behind: {released.message}"
