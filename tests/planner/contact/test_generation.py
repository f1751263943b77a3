"""Contact primitives on the flat and twister scenes (humanoid, quadruped)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.contact import generation
from planner.contact.checks import (
    check_state,
    collision_free,
    com_of,
    contact_on_surface,
    effector_pose,
    hold_error,
    kinematics_of,
    scene_collisions,
    self_collides,
    shrunk_equilibrium,
)
from planner.contact.context import ContactContext, FailureReason
from planner.contact.generation import (
    balance_ik,
    break_contact,
    character_obstacles,
    create_contact,
    maintain,
    stand_state,
    stand_up,
    state_from_configuration,
)
from planner.contact.sequence import advance_body, kinematic_slack
from planner.contact.state import ContactState
from planner.shapes import Box
from tests.planner.contact.twister_game import context, discs, scene, start_state
from trajectory import Halfspaces, transition_point

QUAD_FEET = {
    "lf_foot": (0.525, 0.175),
    "rf_foot": (0.525, -0.175),
    "lh_foot": (-0.175, 0.175),
    "rh_foot": (-0.175, -0.175),
}
HUMANOID_FEET = {"left_foot": (0.175, 0.175), "right_foot": (0.175, -0.175)}


def _flat_state(character: str) -> tuple[ContactContext, ContactState]:
    ctx = context(character, "flat", twister=False)
    q0 = np.array(ctx.character.q_ref)
    limbs = [lb.name for lb in ctx.character.limbs]
    feet = limbs if character in ("quadruped", "hexapod") else limbs[:2]
    points = {}
    for limb in feet:
        p = effector_pose(ctx, limb, q0)[:3, 3].copy()
        p[2] = 0.0
        points[limb] = p
    attempt = stand_state(ctx, q0, dict.fromkeys(feet, 0), points)
    assert attempt.ok, attempt.message
    return ctx, attempt.state


@pytest.mark.parametrize("character", ["humanoid", "quadruped"])
def test_break_and_create_on_flat(character: str) -> None:
    ctx, state = _flat_state(character)
    rng = np.random.default_rng(0)
    for limb in state.limbs:
        released = break_contact(ctx, state, limb)
        assert released.ok, released.message
        assert released.state.differs_by_one(state)
        assert check_state(ctx, released.state).valid
        target = state.contact(limb).points.mean(axis=0) + np.array([0.08, 0.0, 0.0])
        placed = create_contact(ctx, released.state, limb, rng=rng, target=target)
        assert placed.ok, placed.message
        contact = placed.state.contact(limb)
        assert contact is not None and contact_on_surface(ctx, contact)
        assert np.linalg.norm(contact.points.mean(axis=0)[:2] - target[:2]) < 0.05
        assert placed.state.differs_by_one(released.state)
        assert check_state(ctx, placed.state).valid


def test_candidates_beyond_reach_skip_only_projections_that_fail(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A candidate further from the limb's root joint than the limb reaches is not projected
    from the database seeds, and that loses nothing: on points from right under the released
    foot to 1.2 m ahead, the projections found are those found with every seed tried, and
    candidates with seeds that are skipped occur (as do candidates that are not). The
    humanoid's feet: its database holds postures near the edge of its reach (the quadruped's
    flat-ground candidates beyond reach have no seeds)."""
    ctx, state = _flat_state("humanoid")
    limb = state.contacts[0].limb
    released = break_contact(ctx, state, limb)
    assert released.ok, released.message
    start = state.contact(limb).points.mean(axis=0)
    normal = ctx.scene.surfaces[0].normal
    beyond = []
    found: list[list[list[float]]] = [[], []]
    for distance in np.linspace(0.0, 1.2, 25):
        target = start + np.array([distance, 0.0, 0.0])
        for cand in generation._candidates(
            ctx, released.state, limb, np.random.default_rng(0), [0], target, None, 0.0
        ):
            far = generation._beyond_reach(ctx, released.state, limb, cand.point, normal)
            beyond.append(far and len(cand.seeds) > 0)
            for k, check in enumerate((True, False)):
                if not check:
                    monkeypatch.setattr(generation, "_beyond_reach", lambda *_: False)
                found[k] += [
                    q.tolist() for q in generation._projections(ctx, released.state, limb, cand)
                ]
                monkeypatch.undo()
    assert any(beyond) and not all(beyond)
    assert found[0] == found[1]


def test_a_release_asked_again_is_remembered_for_that_state_only() -> None:
    """break_contact on the same state object and limb answers the attempt it made, without
    checking a state again; an equal state that is another object is released anew, to the
    same answer."""
    ctx, state = _flat_state("quadruped")
    first = break_contact(ctx, state, "lf_foot")
    checked = ctx.work.states_checked
    assert first.ok and checked > 0
    assert break_contact(ctx, state, "lf_foot") is first
    assert ctx.work.states_checked == checked
    twin = ContactState(np.array(state.q), state.contacts)
    again = break_contact(ctx, twin, "lf_foot")
    assert again is not first and ctx.work.states_checked > checked
    np.testing.assert_array_equal(again.state.q, first.state.q)
    assert break_contact(ctx, state, "rf_foot") is not first


def test_an_advance_asked_again_is_remembered_for_that_state_only() -> None:
    """advance_body on the same state object toward the same root pose answers the state it
    found, without checking a state again; an equal state that is another object is moved
    anew, to the same configuration; another target is another advance."""
    ctx, state = _flat_state("quadruped")
    effector_pose(ctx, "lf_foot", state.q)  # the kinematics of the state, root pose read below
    target = np.array(ctx.pin_data.oMi[1].homogeneous)
    target[0, 3] += 0.05
    first = advance_body(ctx, state, target)
    checked = ctx.work.states_checked
    assert first is not None and checked > 0
    assert advance_body(ctx, state, target.copy()) is first
    assert ctx.work.states_checked == checked
    twin = ContactState(np.array(state.q), state.contacts)
    again = advance_body(ctx, twin, target)
    assert again is not None and again is not first and ctx.work.states_checked > checked
    np.testing.assert_array_equal(again.q, first.q)
    further = target.copy()
    further[0, 3] += 0.02
    assert advance_body(ctx, state, further) is not first


def test_a_configuration_checked_again_for_collisions_is_remembered() -> None:
    """collision_free answers a configuration and contact set it checked before from memory,
    the same answer as checking anew; another configuration, even by 1e-9, or contacts with
    another normal, is checked anew."""
    ctx, state = _flat_state("quadruped")
    sunk = np.array(state.q)
    sunk[2] -= 0.3  # the body through the ground
    nudged = np.array(state.q)
    nudged[0] += 1e-9
    for q, free in ((sunk, False), (nudged, True), (np.array(state.q), True)):
        direct = not self_collides(ctx, q) and not scene_collisions(ctx, q, contacts=state.contacts)
        assert direct == free
        assert collision_free(ctx, q, state.contacts) == free
        count = len(ctx.by_configuration)
        assert collision_free(ctx, np.array(q), state.contacts) == free
        assert len(ctx.by_configuration) == count  # remembered, not checked again
    assert len(ctx.by_configuration) >= 3
    count = len(ctx.by_configuration)
    tilted = [replace(c, normal=np.array([0.1, 0.0, 1.0])) for c in state.contacts[:1]]
    collision_free(ctx, np.array(state.q), tilted)
    assert len(ctx.by_configuration) == count + 1


def test_a_release_whose_com_serves_both_sets_keeps_it_where_it_is(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Releasing one foot of a hexapod standing on flat ground leaves its COM over the other
    five: the release's transition point is the COM itself (what the QP finds too), and the
    body does not move to shift it."""
    ctx, state = _flat_state("hexapod")
    com = com_of(ctx, state.q)
    for limb in state.limbs:
        after = tuple(c for c in state.contacts if c.limb != limb)
        sets = (
            shrunk_equilibrium(ctx, after),
            kinematics_of(ctx, state.contacts),
            kinematics_of(ctx, after),
        )
        if not all(p.violation(com) <= 0.0 for p in sets):
            continue
        found = transition_point(
            sets[0],
            Halfspaces(np.zeros((0, 3)), np.zeros(0)),
            com,
            kin_prev=sets[1],
            kin_next=sets[2],
        )
        assert found.feasible
        np.testing.assert_allclose(found.point, com, atol=1e-6)

        def unasked(*args: object, **kwargs: object) -> None:
            raise AssertionError("the transition QP was solved")

        monkeypatch.setattr(generation, "transition_point", unasked)
        shifted = generation._shift_com(ctx, state, after)
        assert not isinstance(shifted, generation.ContactAttempt)
        np.testing.assert_allclose(shifted[1], com, atol=1e-4)
        break
    else:
        pytest.fail("no foot of the stance leaves the COM inside the five others")


def test_an_advance_leaving_the_com_too_shallow_is_refused_before_its_checks() -> None:
    """advance_body with a slack floor answers None, without checking the state, when the
    advance leaves the COM shallower than the floor in its kinematic polytope, and the same
    state as without a floor when it leaves it deeper."""
    ctx, state = _flat_state("quadruped")
    effector_pose(ctx, "lf_foot", state.q)
    target = np.array(ctx.pin_data.oMi[1].homogeneous)
    target[0, 3] += 0.05
    free = advance_body(ctx, state, target)
    assert free is not None
    depth = kinematic_slack(ctx, free)
    checked = ctx.work.states_checked
    assert advance_body(ctx, state, target, depth + 1e-3) is None
    assert ctx.work.states_checked == checked
    kept = advance_body(ctx, state, target, depth - 1e-3)
    assert kept is not None and ctx.work.states_checked == checked + 1
    np.testing.assert_array_equal(kept.q, free.q)


@pytest.mark.parametrize(
    ("character", "feet"), [("humanoid", HUMANOID_FEET), ("quadruped", QUAD_FEET)]
)
def test_twister_primitives(character: str, feet: dict) -> None:
    ctx = context(character, "twister")
    state = start_state(ctx, (0.175, 0.0), feet)
    rng = np.random.default_rng(3)
    limb = next(iter(feet))
    released = break_contact(ctx, state, limb)
    assert released.ok
    placed = create_contact(ctx, released.state, limb, rng=rng)
    assert placed.ok and placed.surface in discs(ctx.scene).values()
    assert check_state(ctx, placed.state).valid
    # a disc out of reach
    far = discs(ctx.scene)[(-0.875, -0.525)]
    miss = create_contact(ctx, released.state, limb, rng=rng, surface=far)
    assert not miss.ok and miss.reason is FailureReason.NOTHING_REACHABLE
    assert miss.state is released.state


def test_obstacle_on_the_only_disc_blocks_it() -> None:
    ctx = context("quadruped", "twister")
    state = start_state(ctx, (0.175, 0.0), QUAD_FEET)
    rng = np.random.default_rng(0)
    released = break_contact(ctx, state, "lf_foot")
    assert released.ok
    sid = discs(ctx.scene)[(0.525, 0.175)]
    free = create_contact(ctx, released.state, "lf_foot", rng=rng, surface=sid)
    assert free.ok
    pose = np.eye(4)
    pose[:3, 3] = (0.525, 0.175, 0.1)
    blocked_ctx = ctx.with_obstacles([(Box(np.array([0.15, 0.15, 0.1])), pose)])
    blocked = create_contact(blocked_ctx, released.state, "lf_foot", rng=rng, surface=sid)
    assert not blocked.ok
    assert blocked.reason in (FailureReason.COLLISION, FailureReason.NOTHING_REACHABLE)


def test_primitive_failures_are_structured() -> None:
    ctx = context("humanoid", "twister")
    state = start_state(ctx, (0.175, 0.0), HUMANOID_FEET)
    rng = np.random.default_rng(0)
    assert create_contact(ctx, state, "tail", rng=rng).reason is FailureReason.UNKNOWN_LIMB
    assert (
        create_contact(ctx, state, "left_foot", rng=rng).reason is FailureReason.ALREADY_IN_CONTACT
    )
    assert break_contact(ctx, state, "left_hand").reason is FailureReason.NOT_IN_CONTACT
    one = break_contact(ctx, state, "left_foot")
    assert one.ok
    assert break_contact(ctx, one.state, "right_foot").reason is FailureReason.NOT_BALANCED


def test_maintain() -> None:
    ctx = context("quadruped", "twister")
    state = start_state(ctx, (0.175, 0.0), QUAD_FEET)
    root = np.eye(4)
    root[:3, :3] = np.array(
        [[np.cos(0.02), -np.sin(0.02), 0], [np.sin(0.02), np.cos(0.02), 0], [0, 0, 1]]
    )
    root[:3, 3] = state.q[:3] + np.array([0.02, -0.01, -0.01])
    kept, lost = maintain(ctx, state, root)
    assert lost == () and kept.limbs == state.limbs
    assert hold_error(ctx, kept.q, kept.contacts) < 1e-3
    np.testing.assert_allclose(kept.q[:3], root[:3, 3])
    root[:3, 3] = state.q[:3] + np.array([0.0, 0.0, 1.0])
    gone, lost = maintain(ctx, state, root)
    assert set(lost) == set(state.limbs) and gone.contacts == ()


def test_character_obstacles_cover_the_body() -> None:
    ctx = context("humanoid", "twister")
    state = start_state(ctx, (0.175, 0.0), HUMANOID_FEET)
    shapes = character_obstacles(ctx.character, state.q)
    assert len(shapes) == ctx.character.geometry.ngeoms
    world = scene("twister").collision.with_obstacles(shapes)
    probe = np.eye(4)
    probe[:3, 3] = state.q[:3]
    assert world.collides(Box(np.array([0.02, 0.02, 0.02])), probe)


def test_state_from_configuration_round_trip() -> None:
    ctx = context("quadruped", "twister")
    state = start_state(ctx, (0.175, 0.0), QUAD_FEET)
    given = {c.limb: c.surface for c in state.contacts}
    again = state_from_configuration(ctx, state.q, given)
    assert again.ok, again.message
    inferred = state_from_configuration(ctx, state.q, dict.fromkeys(given))
    assert inferred.ok
    assert [c.surface for c in inferred.state.contacts] == list(given.values())
    for a, b in zip(again.state.contacts, state.contacts, strict=True):
        np.testing.assert_allclose(a.points, b.points, atol=1e-9)
    lifted = np.array(state.q)
    lifted[2] += 0.2
    bad = state_from_configuration(ctx, lifted, given)
    assert not bad.ok and bad.reason is FailureReason.INVALID_STATE
    wrong = state_from_configuration(ctx, state.q, {"tail": None})
    assert wrong.reason is FailureReason.UNKNOWN_LIMB


def test_a_bent_chest_stands_up_once_the_hands_are_free() -> None:
    """stand_up: a state on its feet whose chest is bent over and whose arms reach forward
    gets its chest and free arms back at the reference posture, the feet held, the COM where
    it was, still valid; a state already upright is returned as it is."""
    ctx, state = _flat_state("humanoid")
    model, reference = ctx.model, np.asarray(ctx.character.q_ref)
    chest = [int(model.idx_qs[model.getJointId(n)]) for n in ("torso_yaw", "torso_pitch")]
    arms = [i for n in ("left_hand", "right_hand") for i in ctx.character.limb(n).idx_q]
    assert stand_up(ctx, state) is state
    bent_q = np.array(state.q)
    bent_q[chest[1]] = 0.5
    shoulders = [ctx.character.limb(n).idx_q[0] for n in ("left_hand", "right_hand")]
    bent_q[shoulders] = reference[shoulders] - 0.3  # the arms reach forward
    bent = balance_ik(ctx, bent_q, state.contacts, com_of(ctx, state.q), chest_still=True)
    leaning = ContactState(np.array(bent.q), state.contacts)
    assert check_state(ctx, leaning).valid
    upright = stand_up(ctx, leaning)
    assert upright is not leaning
    np.testing.assert_allclose(upright.q[chest], reference[chest], atol=1e-12)
    np.testing.assert_allclose(upright.q[arms], reference[arms], atol=1e-12)
    assert hold_error(ctx, upright.q, upright.contacts) < 1e-3
    assert np.linalg.norm(com_of(ctx, upright.q) - com_of(ctx, leaning.q)) < 1e-3
    assert check_state(ctx, upright).valid
