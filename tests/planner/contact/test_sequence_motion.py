"""Keyframes of a contact sequence: stance contacts held, point-foot swings by position."""

from __future__ import annotations

from functools import cache

import numpy as np

from planner.contact.checks import hold_error, make_contact, within_limits
from planner.contact.context import ContactContext, make_context
from planner.contact.generation import hold_tasks, posture_task
from planner.contact.sequence_motion import _stance_tasks, sequence_motion
from planner.contact.state import ContactState
from planner.kinematics import (
    ComTask,
    FramePositionTask,
    Priority,
    com_position,
    solve_ik,
)
from tests.planner.contact.contact_helpers import character_and_data, scene


@cache
def _hexapod_steps() -> tuple[ContactContext, tuple[ContactState, ...]]:
    """Three hexapod steps of 12 cm (release then creation), the COM shifted 4 cm each."""
    character, data = character_and_data("hexapod")
    ctx = make_context(scene("flat"), character, data)
    model = character.model
    q = np.array(character.q_ref)
    contacts = [make_contact(ctx, limb.name, q, 0) for limb in character.limbs]
    states = [ContactState(q, tuple(contacts))]
    for limb in ("l1_foot", "r2_foot", "l3_foot"):
        rest = tuple(c for c in contacts if c.limb != limb)
        states.append(ContactState(q, rest))
        old = next(c for c in contacts if c.limb == limb)
        foot = FramePositionTask(
            character.limb(limb).frame_id,
            old.position + np.array([0.12, 0.0, 0.0]),
            np.zeros(3),
            Priority.CONTACT,
        )
        com = ComTask(com_position(model, q) + np.array([0.04, 0.0, 0.0]), (True, True, False))
        result = solve_ik(model, q, [*hold_tasks(rest, ctx), foot, com, posture_task(ctx)])
        assert result.success
        q = np.array(result.q)
        contacts = [*rest, make_contact(ctx, limb, q, 0)]
        states.append(ContactState(q, tuple(contacts)))
    return ctx, tuple(states)


def test_point_stance_contacts_are_in_the_contact_tier() -> None:
    ctx, states = _hexapod_steps()
    tasks = _stance_tasks(ctx.character, states[0].contacts)
    assert len(tasks) == 6
    assert all(isinstance(t, FramePositionTask) for t in tasks)
    assert all(t.priority is Priority.CONTACT for t in tasks)


def test_hexapod_keyframes_hold_stance_without_repair() -> None:
    ctx, states = _hexapod_steps()
    motion = sequence_motion(ctx.character, ctx.data, states)
    assert motion.report["phases_animated"] == len(states)
    # Every keyframe converges in the tracking pass (none slips and needs re-solving).
    assert motion.report["keyframes_repaired"] == 0
    assert float(motion.report["max_com_error_m"]) <= 1e-3  # type: ignore[arg-type]
    times = [k.t for k in motion.keyframes]
    assert times == sorted(times)
    for key in motion.keyframes:
        assert within_limits(ctx, np.asarray(key.q), tol=1e-6)
        phase = next(p for p in motion.phases if p.t0 - 1e-9 <= key.t <= p.t1 + 1e-9)
        held = [c for c in phase.contacts if c.limb in key.contacts]
        assert hold_error(ctx, np.asarray(key.q), held) <= 2e-3


def test_sequence_motion_is_deterministic() -> None:
    ctx, states = _hexapod_steps()
    a = sequence_motion(ctx.character, ctx.data, states)
    b = sequence_motion(ctx.character, ctx.data, states)
    assert len(a.keyframes) == len(b.keyframes)
    for ka, kb in zip(a.keyframes, b.keyframes, strict=True):
        assert ka.t == kb.t
        assert np.array_equal(ka.q, kb.q)
