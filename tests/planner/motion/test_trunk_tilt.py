"""The tracker's trunk and chest tilt bounds (``tuning.MAX_TILT``, ``MAX_CHEST_TILT``): a
trunk that aims upright never leans further from the vertical, nor does the chest above it,
however far the COM target pulls them, and the COM still gets there (the legs and the rest
of the body give way instead)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.kinematics import com_position
from planner.motion import tuning
from planner.motion.tracker import StepTargets, WholeBodyTracker, chest_joint
from tests.planner.contact.contact_helpers import character_and_data, scene

STEPS = 120  # control steps of 1/60 s: two seconds
DT = 1.0 / 60.0


def _tilt_deg(q: np.ndarray) -> float:
    rotation = pin.Quaternion(q[3:7]).toRotationMatrix()
    return math.degrees(math.acos(min(1.0, float(rotation[2, 2]))))


def _track(targets: StepTargets) -> tuple[float, float, float]:
    """Worst trunk tilt and worst chest tilt (deg) over the steps toward ``targets`` from
    the reference stance, and the COM's final distance (m) from its target."""
    character, _ = character_and_data("humanoid")
    tracker = WholeBodyTracker(character, scene("flat").collision.bvh)
    chest = chest_joint(character)
    assert chest is not None and character.model.names[chest] == "torso_pitch"
    data = character.model.createData()
    q = np.array(character.q_ref)
    worst = worst_chest = 0.0
    for _ in range(STEPS):
        q = tracker.step(q, targets, DT)
        worst = max(worst, _tilt_deg(q))
        pin.forwardKinematics(character.model, data, q)
        upright = min(1.0, float(data.oMi[chest].rotation[2, 2]))
        worst_chest = max(worst_chest, math.degrees(math.acos(upright)))
    com = com_position(character.model, q)
    return worst, worst_chest, float(np.linalg.norm(com - targets.com))


def _targets(com_offset: tuple[float, float, float]) -> StepTargets:
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    q = np.array(character.q_ref)
    feet = [make_contact(ctx, name, q, 0) for name in ("left_foot", "right_foot")]
    return StepTargets(
        stance=tuple((c.limb, np.asarray(c.placement)) for c in feet),
        com=com_position(character.model, q) + np.asarray(com_offset),
        swing=None,
        posture=q,  # upright
    )


@pytest.mark.parametrize(
    "com_offset",
    # forward, 15 cm ahead: 30 cm ahead and 25 cm down (14 cm past the toes, where no
    # plan's COM goes) is out of reach of a body whose trunk and chest keep their bounds
    [(-0.25, 0.0, -0.1), (-0.35, 0.0, -0.2), (0.15, 0.0, -0.3), (0.0, 0.0, -0.4)],
)
def test_an_upright_trunk_leans_no_further_than_the_bound(
    com_offset: tuple[float, float, float],
) -> None:
    targets = _targets(com_offset)
    worst, worst_chest, com_gap = _track(targets)
    assert worst <= math.degrees(tuning.MAX_TILT) + 0.2
    assert worst_chest <= math.degrees(tuning.MAX_CHEST_TILT) + 0.2
    assert com_gap < 0.005


@pytest.mark.parametrize("com_offset", [(-0.3, 0.0, -0.15), (-0.35, 0.0, -0.2), (0.3, 0.0, -0.3)])
def test_without_the_bound_the_com_target_tilts_the_trunk_past_it(
    com_offset: tuple[float, float, float],
) -> None:
    # the premise of the bound: the same targets with the trunk aimed at the posture's own
    # orientation (upright too, as a Twister step aims), so that only the trunk task's pull
    # holds it, and these COM targets tilt it past the bound
    free, free_chest, _ = _track(dataclasses.replace(_targets(com_offset), level_trunk=False))
    assert free > math.degrees(tuning.MAX_TILT) + 5.0
    assert free_chest > math.degrees(tuning.MAX_CHEST_TILT) + 5.0
