"""``WholeBodyTracker.hold_stance`` sets a keyframe's stance effectors back on their contacts
after its control step: from any configuration a few millimetres and degrees off, the feet
end on their placements, within the joint limits; where a contact is out of reach it never
leaves the stance farther off than it found it."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.motion.tracker import WholeBodyTracker, speed_limits
from tests.planner.contact.contact_helpers import character_and_data, scene

FEET = ("left_foot", "right_foot")


@cache
def _standing() -> tuple[Any, WholeBodyTracker, tuple[tuple[str, np.ndarray], ...]]:
    """The humanoid's reference posture on flat ground, its tracker and its feet's
    placements (limb, (4, 4))."""
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    q = np.array(character.q_ref)
    stance = tuple(
        (name, np.asarray(make_contact(ctx, name, q, 0).placement, dtype=np.float64))
        for name in FEET
    )
    return character, WholeBodyTracker(character, ctx.scene.collision.bvh), stance


def _errors(tracker: WholeBodyTracker, q: np.ndarray, stance: Any) -> list[float]:
    """Per stance effector, its distance (m) from its placement."""
    pin.framesForwardKinematics(tracker.model, tracker.data, q)
    return [
        float(
            np.linalg.norm(
                tracker.data.oMf[tracker.character.limb(limb).frame_id].translation - pose[:3, 3]
            )
        )
        for limb, pose in stance
    ]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), size=st.floats(0.001, 0.02))
def test_a_drifted_stance_is_set_back_on_its_contacts(seed: int, size: float) -> None:
    character, tracker, stance = _standing()
    rng = np.random.default_rng(seed)
    step = rng.uniform(-size, size, character.model.nv)  # m for the root, rad for joints
    q = np.asarray(pin.integrate(character.model, np.array(character.q_ref), step))
    assert max(_errors(tracker, q, stance)) > 1e-4  # the drift is real
    held = tracker.hold_stance(q, stance)
    assert max(_errors(tracker, held, stance)) < 1e-4
    lower, upper = character.model.lowerPositionLimit[7:], character.model.upperPositionLimit[7:]
    assert np.all(held[7:] >= lower - 1e-12) and np.all(held[7:] <= upper + 1e-12)


def test_an_unreachable_contact_leaves_the_stance_no_worse() -> None:
    character, tracker, stance = _standing()
    far = stance[0][1].copy()
    far[0, 3] += 1.5  # the left foot's placement 1.5 m ahead: no leg reaches it
    wanted = ((stance[0][0], far), stance[1])
    q = np.array(character.q_ref)
    before = _errors(tracker, q, wanted)
    held = tracker.hold_stance(q, wanted)
    after = _errors(tracker, held, wanted)
    assert sum(e * e for e in after) <= sum(e * e for e in before) + 1e-12
    assert after[1] < 0.05  # the right foot is not dragged far off its own contact


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dt=st.floats(0.001, 0.05))
def test_the_setting_back_keeps_every_joint_within_its_speed_from_the_previous_keyframe(
    seed: int, dt: float
) -> None:
    character, tracker, stance = _standing()
    model = character.model
    rng = np.random.default_rng(seed)
    q = np.asarray(
        pin.integrate(model, np.array(character.q_ref), rng.uniform(-0.02, 0.02, model.nv))
    )
    reference = np.array(q)  # the previous keyframe: the drift happened before it
    held = tracker.hold_stance(q, stance, reference, dt)
    speeds = speed_limits(model)[6:]
    moved = np.abs(held[7:] - reference[7:])
    assert np.all(moved <= speeds * dt + 1e-12)
    # within that bound the contacts are no farther off than they were
    before, after = _errors(tracker, q, stance), _errors(tracker, held, stance)
    assert sum(e * e for e in after) <= sum(e * e for e in before) + 1e-12
