"""Invariants every successful one-step motion keeps, shared by the Twister and script tests."""

from __future__ import annotations

from math import comb

import numpy as np

from planner.contact.checks import (
    check_state,
    hold_error,
    kinematics_of,
    within_limits,
)
from planner.contact.context import ContactContext
from planner.contact.one_step import StepResult
from planner.contact.state import ContactState
from tests.motion_audit import audit_from_domain


def com_at(result: StepResult, t: float) -> np.ndarray:
    """(3,) COM of ``result``'s Bezier segments at time ``t`` (s)."""
    for seg in result.com:
        if seg.t0 - 1e-9 <= t <= seg.t1 + 1e-9:
            s = (t - seg.t0) / (seg.t1 - seg.t0)
            n = len(seg.control_points) - 1
            w = np.array([comb(n, k) * s**k * (1 - s) ** (n - k) for k in range(n + 1)])
            return np.asarray(w @ seg.control_points)
    raise AssertionError(f"no COM segment at t={t}")


def assert_valid_step(ctx: ContactContext, before: ContactState, result: StepResult) -> None:
    """The state reached is valid and one contact away from ``before``; keyframes start and
    end on the two states, hold their phase's contacts within 1 cm inside the joint limits and
    touch nothing; the COM stays in both phases' kinematic polytopes; the step is
    quasi-statically feasible."""
    report = check_state(ctx, result.state)
    assert report.valid, report
    assert result.state.differs_by_one(before)
    np.testing.assert_array_equal(result.keyframes[0].q, before.q)
    np.testing.assert_array_equal(result.keyframes[-1].q, result.state.q)
    for kf in result.keyframes:
        phase = result.phases[0] if kf.t < result.phases[0].t1 else result.phases[1]
        assert hold_error(ctx, kf.q, phase.contacts) <= 0.01
        assert within_limits(ctx, kf.q)
    for phase in result.phases:
        kin = kinematics_of(ctx, phase.contacts)
        for t in np.linspace(phase.t0, phase.t1, 7):
            assert kin.violation(com_at(result, float(t))) <= 1e-3
    assert result.report["colliding_keyframes"] == 0
    assert result.report["quasi_static_feasible"]
    assert_playable(ctx, result)


def assert_playable(ctx: ContactContext, result: StepResult) -> None:
    """The independent auditor (URDF collision geometry through Pinocchio and coal against
    the scene mesh) finds no link over 1 cm inside the scene but stance effectors at their
    contacts, no self-collision over 1 cm, no joint over its speed limit or 10 rad/s, no root
    jump, the keyframe COM within 2 cm of its curve and every phase animated."""
    audit = audit_from_domain(
        ctx.character.id, ctx.scene, result.keyframes, result.phases, result.com
    )
    assert audit.penetrating_frames == 0, audit.summary()
    assert audit.stance_contact_error_m <= 0.005, audit.summary()
    assert audit.self_collision_frames == 0, audit.summary()
    assert audit.pops == 0 and audit.root_jumps == 0, audit.summary()
    assert audit.com_error_max_m <= 0.02, audit.summary()
    assert audit.phases_animated == audit.phases == 2, audit.summary()
