"""Re-planning a contact change the whole-body motion could not make (2PAC 7.2's last
resort): contacts avoided near given points, and a walk resumed part-way along its guide."""

from __future__ import annotations

import itertools

import numpy as np

from planner.contact.context import make_context
from planner.contact.generation import AVOID_RADIUS, break_contact, create_contact
from planner.contact.sequence import contact_sequence
from planner.contact.state import ContactState
from planner.result import PlanStatus
from tests.planner.contact.contact_helpers import character_and_data, flat_walk, scene
from tests.planner.contact.test_generation import _flat_state


def test_a_contact_is_not_made_near_an_avoided_point() -> None:
    ctx, state = _flat_state("quadruped")
    for limb in state.limbs:
        released = break_contact(ctx, state, limb)
        assert released.ok, released.message
        target = state.contact(limb).position + np.array([0.08, 0.0, 0.0])
        rng = np.random.default_rng(3)
        first = create_contact(ctx, released.state, limb, rng=rng, target=target)
        assert first.ok, first.message
        banned = first.state.contact(limb).position
        rng = np.random.default_rng(3)
        other = create_contact(ctx, released.state, limb, rng=rng, target=target, avoid=[banned])
        assert other.ok, other.message
        placed = other.state.contact(limb).position
        # the candidate point was further than the radius; IK puts the foot within mm of it
        assert np.linalg.norm(placed - banned) > AVOID_RADIUS - 0.01
        assert other.state.differs_by_one(released.state)


def _walk_plan():  # type: ignore[no-untyped-def]
    character, data = character_and_data("humanoid")
    result = flat_walk("humanoid")
    assert result.status is PlanStatus.SOLVED, result.message
    return scene("flat"), character, data, result.value


def _made(a: ContactState, b: ContactState) -> str | None:
    created = set(b.limbs) - set(a.limbs)
    return next(iter(created)) if created else None


def test_a_walk_resumed_part_way_goes_on_to_the_goal_around_an_avoided_contact() -> None:
    scene, character, data, plan = _walk_plan()
    states = plan.states
    # the motion animates the states planned (no re-plan on a clean walk)
    assert plan.motion is not None and plan.motion.states == states
    assert plan.motion.report["contact_replans"] == []
    # a state holding both feet, two changes before a foot is put down again
    k = next(
        j
        for j in range(2, len(states) - 3)
        if len(states[j].contacts) == 2 and _made(states[j + 1], states[j + 2]) is not None
    )
    limb = _made(states[k + 1], states[k + 2])
    assert limb is not None
    banned = states[k + 2].contact(limb).position
    ctx = make_context(scene, character, data)
    again = contact_sequence(
        ctx,
        states[k],
        plan.root_path,
        states[-1],
        rng=np.random.default_rng(5),
        until=lambda: False,
        avoid=[(limb, banned)],
        resume=True,
    )
    assert again.status is PlanStatus.SOLVED, again.message
    walked = again.value
    assert walked[0] is states[k]
    for a, b in itertools.pairwise(walked):
        assert b.differs_by_one(a)
    for state in walked[1:]:
        contact = state.contact(limb)
        if contact is not None and contact is not states[k].contact(limb):
            assert np.linalg.norm(contact.position - banned) > AVOID_RADIUS - 0.01
    # the walk goes on from where the state stands, never back to the guide's start
    x0 = float(states[k].q[0])
    assert min(float(s.q[0]) for s in walked) > x0 - 0.15
    assert len(walked) < len(states)
