"""Which shapes of a limb in stance the keyframe checker lets touch the scene: its effector's
(the foot), never the rest of the limb (a shin resting on a rock is a collision)."""

from __future__ import annotations

import numpy as np
import pytest

from planner.character import get_character
from planner.motion.checker import KeyframeChecker
from planner.motion.tracker import effector_geometries
from tests.planner.contact.test_generation import _flat_state

LEGGED = ("quadruped", "hexapod", "hyq", "humanoid", "talos")


@pytest.mark.parametrize("name", LEGGED)
def test_a_stance_limb_excuses_its_effector_shapes_only(name: str) -> None:
    character = get_character(name)
    model = character.model
    geometries = character.motion_geometry.geometryObjects
    shapes = effector_geometries(character)
    for limb in character.limbs:
        excused = shapes[limb.name]
        assert excused, limb.name
        joint = int(model.frames[limb.frame_id].parentJoint)
        # the effector's shapes ride on the effector frame's joint
        assert {int(geometries[i].parentJoint) for i in excused} == {joint}
        # the shape of a link a joint above it (a shin under a knee) is not excused
        above = {i for i, o in enumerate(geometries) if int(o.parentJoint) == joint} - excused
        frames = {int(geometries[i].parentFrame) for i in excused}
        assert all(int(geometries[i].parentFrame) not in frames for i in above)
    if name in ("quadruped", "hyq", "hexapod"):
        names = {geometries[i].name for limb in shapes.values() for i in limb}
        assert not any("shin" in n or "tibia" in n or "lowerleg" in n for n in names), names


def test_a_shin_pushed_into_the_floor_in_stance_is_refused() -> None:
    ctx, state = _flat_state("quadruped")
    checker = KeyframeChecker(ctx.character, ctx.scene.collision.bvh)
    standing = checker.check(np.asarray(state.q), state.contacts)
    assert standing.scene_depth <= 0.005
    sunk = np.array(state.q)
    sunk[2] -= 0.15  # the feet 15 cm under the floor (excused: in stance), the shins too
    check = checker.check(sunk, state.contacts)
    assert check.scene_depth > 0.05 and check.shape is not None
    assert "shin" in check.shape
