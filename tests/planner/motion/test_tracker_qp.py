"""The tracker assembles its QP itself (kinematics once per control step, task rows stacked
with numpy); pink's ``build_ik`` on the same tasks and limits must give the same problem,
H, c, G, h, A, b to 1e-9, step after step of a real motion (a swing, a squat, rigid
contacts). ``bench/tracker.py`` times both."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers

from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.kinematics import com_position
from planner.motion import tuning
from planner.motion.builder import _Targets
from planner.motion.checker import KeyframeChecker
from planner.motion.spec import MotionPhase, MotionSpec, Swing
from planner.motion.tracker import WholeBodyTracker
from tests.planner.contact.contact_helpers import character_and_data, scene
from tests.planner.motion.pink_reference import PinkReference
from trajectory import BezierCurve, PiecewiseBezier


def _spec(rigid: bool) -> tuple[Any, MotionSpec]:
    """A humanoid squatting 0.15 m while its left foot lifts and lands 0.2 m ahead."""
    character, data = character_and_data("humanoid")
    ctx = make_context(scene("flat"), character, data)
    q = np.array(character.q_ref)
    feet = {name: make_contact(ctx, name, q, 0) for name in ("left_foot", "right_foot")}
    c0 = com_position(character.model, q)
    c1 = c0 - np.array([0.0, 0.0, 0.15])
    curve = PiecewiseBezier((BezierCurve(np.stack([c0, c0, c0, c1, c1, c1]), 0.0, 0.8),))
    start = np.asarray(feet["left_foot"].placement)
    end = start.copy()
    end[0, 3] += 0.2
    swing = Swing("left_foot", start, end, 0.08)
    phase = MotionPhase(0.0, 0.8, (feet["right_foot"],), q, swing=swing, rigid_stance=rigid)
    return ctx, MotionSpec(q, (phase,), curve, 30.0)


def _same(a: Any, b: Any, what: str) -> None:
    if a is None or b is None:
        assert a is None and b is None, what
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    assert np.max(np.abs(a - b), initial=0.0) <= 1e-9, (what, np.max(np.abs(a - b)))


@pytest.mark.parametrize("rigid", [False, True])
def test_the_assembled_qp_is_pinks_build_ik(rigid: bool) -> None:
    ctx, spec = _spec(rigid)
    bvh = ctx.scene.collision.bvh
    tracker = WholeBodyTracker(ctx.character, bvh)
    twin = WholeBodyTracker(ctx.character, bvh)  # its dampers, read by pink
    reference = PinkReference(tracker, (twin.scene, twin.self_clearance))
    targets = _Targets(ctx.character, spec)
    q = np.array(spec.q_start)
    dt = 1.0 / 90.0
    damper_rows = 0
    for k in range(1, 72):
        aim = targets.at(k * dt)
        rigid_limbs = [limb for limb, _ in aim.stance] if aim.rigid_stance else []
        qp = tracker.objective(q, aim)
        twin.objective(q, aim)
        ours = tracker.problem(qp, dt, True, aim.root_bounded, rigid_limbs)
        pinks = reference.problem(q, aim, dt, dampers=True, rigid=rigid_limbs)
        for name in ("P", "q", "G", "h", "A", "b"):
            _same(getattr(ours, name), getattr(pinks, name), f"step {k}: {name}")
        damper_rows += tracker.scene.rows + tracker.self_clearance.rows
        result = qpsolvers.solve_problem(ours, solver=tuning.QP_SOLVER)
        assert result.found
        q = pin.integrate(tracker.model, q, result.x)
        tracker.velocity = result.x / dt  # the free arms' acceleration bound counts from it
    assert damper_rows > 0  # the dampers were compared too (the foot near the floor)


def test_a_flight_target_gives_the_same_qp() -> None:
    ctx, spec = _spec(False)
    bvh = ctx.scene.collision.bvh
    tracker = WholeBodyTracker(ctx.character, bvh)
    twin = WholeBodyTracker(ctx.character, bvh)
    reference = PinkReference(tracker, (twin.scene, twin.self_clearance))
    aim = _Targets(ctx.character, spec).at(0.3)
    aim = dataclasses.replace(
        aim, com_reach=np.inf, root_bounded=False, level_trunk=False, swing_guarded=False
    )
    q = np.array(spec.q_start)
    qp = tracker.objective(q, aim, share=0.5)
    twin.objective(q, aim, share=0.5)
    ours = tracker.problem(qp, 0.01, True, False, [])
    pinks = reference.problem(q, aim, 0.01, share=0.5)
    for name in ("P", "q", "G", "h", "A", "b"):
        _same(getattr(ours, name), getattr(pinks, name), name)


def test_a_checker_sharing_the_trackers_bounds_checks_as_one_of_its_own() -> None:
    ctx, spec = _spec(False)
    bvh = ctx.scene.collision.bvh
    tracker = WholeBodyTracker(ctx.character, bvh)
    shared = KeyframeChecker(ctx.character, bvh, tracker=tracker)
    alone = KeyframeChecker(ctx.character, bvh)
    targets = _Targets(ctx.character, spec)
    stance = spec.phases[0].stance
    q = np.array(spec.q_start)
    dt = 1.0 / 90.0
    for k in range(1, 72):
        q = tracker.step(q, targets.at(k * dt), dt)
        if k % 3 == 0:
            assert shared.check(q, stance) == alone.check(q, stance)


def test_a_settling_swing_is_weighted_as_the_contact_it_lands_on() -> None:
    """At its landing at the end of the settle, the swing task is the stance task it is
    about to become; SETTLE_REACH or further from it, the plain swing task."""
    ctx, spec = _spec(False)
    tracker = WholeBodyTracker(ctx.character, ctx.scene.collision.bvh)
    targets = _Targets(ctx.character, spec)
    q = np.array(spec.q_start)
    settling = targets.at(spec.phases[0].t1)
    assert settling.swing is not None and settling.swing_settle == pytest.approx(1.0)
    assert targets.at(0.5 * spec.phases[0].t1).swing_settle == 0.0
    limb = settling.swing[0]
    pin.framesForwardKinematics(tracker.model, tracker.data, q)
    here = tracker.data.oMf[ctx.character.limb(limb).frame_id].homogeneous
    landed = dataclasses.replace(settling, swing=(limb, here))
    held = dataclasses.replace(settling, swing=None, stance=(*settling.stance, (limb, here)))
    a, b = tracker.objective(q, landed), tracker.objective(q, held)
    _same(a.hessian, b.hessian, "H")
    _same(a.linear, b.linear, "c")
    far = here.copy()
    far[2, 3] += tuning.SETTLE_REACH
    c = tracker.objective(q, dataclasses.replace(settling, swing=(limb, far)))
    d = tracker.objective(q, dataclasses.replace(settling, swing=(limb, far), swing_settle=0.0))
    _same(c.hessian, d.hessian, "H far")
    _same(c.linear, d.linear, "c far")
    assert np.max(np.abs(a.hessian - d.hessian)) > 1.0  # the settle changed the weights
