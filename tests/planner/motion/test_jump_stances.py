"""A jump's takeoff push and landing stay within what the stance's legs reach: the COM
travels at most the stance's reach (a short-legged body pushes harder and shorter, it
never crouches below its feet), the contact force lies in the cone, a velocity the legs
cannot reach (or stop) within their reach is reported as such, and every push and landing
shows in a keyframe even when it is shorter than a keyframe period."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.character import Character
from planner.contact.checks import make_contact
from planner.contact.context import make_context
from planner.contact.state import ContactState
from planner.kinematics import com_position, frame_placements
from planner.motion import tuning
from planner.motion.builder import keyframe_grid
from planner.motion.jump import (
    JumpLeg,
    _chest_frames,
    _reach,
    com_speed,
    in_cone,
    jump_spec,
    stance_duration,
)
from planner.motion.tracker import speed_limits
from tests.planner.contact.contact_helpers import character_and_data, scene

G = np.array([0.0, 0.0, -9.81])
UP = np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("speed", [0.5, 1.5, 3.0, 5.5])
@pytest.mark.parametrize("reach", [0.04, 0.1, 0.3])
@pytest.mark.parametrize("landing", [False, True])
def test_a_stance_travels_within_reach_with_its_force_in_the_cone(
    speed: float, reach: float, landing: bool
) -> None:
    direction = np.array([0.5, 0.2, 1.0 if not landing else -1.0])
    velocity = speed * direction / np.linalg.norm(direction)
    stance = stance_duration(velocity, G, UP, 1.0, reach, landing=landing)
    assert stance.in_cone and stance.in_reach
    assert 0.5 * speed * stance.duration <= reach + 1e-9
    assert tuning.JUMP_MIN_STANCE_S <= stance.duration <= tuning.JUMP_MAX_STANCE_S
    # never harder than the legs' reach demands: the nominal acceleration when it fits
    nominal = speed / tuning.JUMP_ACCELERATION
    assert stance.duration == pytest.approx(min(nominal, 2.0 * reach / speed))
    force = (-1.0 if landing else 1.0) * velocity / stance.duration - G
    assert in_cone(force, UP, 1.0)


def test_a_velocity_beyond_the_legs_reach_is_reported() -> None:
    velocity = np.array([0.0, 0.0, 5.0])
    stance = stance_duration(velocity, G, UP, 1.0, 0.005, landing=False)
    assert not stance.in_reach
    assert stance.duration == pytest.approx(tuning.JUMP_MIN_STANCE_S)


def test_a_cone_refusing_every_push_within_reach_is_reported_without_leaving_reach() -> None:
    # a cone tilted 60 degrees off the vertical, mu 0.3, and a vertical takeoff
    axis = np.array([math.sin(math.radians(60.0)), 0.0, math.cos(math.radians(60.0))])
    velocity = np.array([0.0, 0.0, 3.0])
    stance = stance_duration(velocity, G, axis, 0.3, 0.05, landing=False)
    assert not stance.in_cone and stance.in_reach
    assert 0.5 * 3.0 * stance.duration <= 0.05 + 1e-9


def test_the_cone_may_lengthen_a_push_only_within_reach() -> None:
    # gravity alone lies outside this cone (axis 40 degrees off the vertical, mu 0.5): the
    # nominal push fails, a longer one would tilt the force further: shorter ones are tried
    axis = np.array([math.sin(math.radians(40.0)), 0.0, math.cos(math.radians(40.0))])
    velocity = 2.0 * axis
    stance = stance_duration(velocity, G, axis, 0.5, 0.2, landing=False)
    assert stance.in_cone and stance.in_reach
    assert 0.5 * 2.0 * stance.duration <= 0.2 + 1e-9
    assert in_cone(velocity / stance.duration - G, axis, 0.5)


def _hexapod_jump(
    rise: float, speed_scale: float, name: str = "hexapod"
) -> tuple[Character, list[ContactState], JumpLeg]:
    """The hexapod (or character ``name``) standing on flat ground and jumping forward onto
    the same ground translated by ``rise`` up (the landing contacts are the takeoff ones
    moved)."""
    character, data = character_and_data(name)
    ctx = make_context(scene("flat"), character, data)
    q0 = np.array(character.q_ref)
    names = [limb.name for limb in character.default_limbs]
    takeoff = ContactState(q0, tuple(make_contact(ctx, name, q0, 0) for name in names))
    q1 = q0.copy()
    q1[:3] += [0.6, 0.0, rise]
    shift = np.eye(4)
    shift[:3, 3] = [0.6, 0.0, rise]
    landed = []
    for contact in takeoff.contacts:
        placement = shift @ np.asarray(contact.placement)
        points = np.asarray(contact.points) + shift[:3, 3]
        landed.append(
            type(contact)(
                contact.limb, placement, points, contact.normal, contact.mu, contact.surface
            )
        )
    landing = ContactState(q1, tuple(landed))
    c0, c1 = com_position(character.model, q0), com_position(character.model, q1)
    duration = 0.5 * speed_scale
    v0 = (c1 - c0 - 0.5 * G * duration**2) / duration
    leg = JumpLeg(c0, v0, duration, 9.81, UP, 1.0, UP, 1.0)
    return character, [takeoff, landing], leg


def test_a_short_legged_jump_crouches_and_lands_within_reach() -> None:
    """The hexapod's COM stands 13 cm above its feet: a 3 m/s takeoff at the nominal 2 g
    would crouch 23 cm (below its feet); the push is shortened to the legs' reach."""
    character, stances, leg = _hexapod_jump(rise=0.0, speed_scale=1.0)
    assert float(np.linalg.norm(leg.v0)) ** 2 / (2 * tuning.JUMP_ACCELERATION) > 0.13
    spec, (timing,) = jump_spec(character, stances, [leg])
    push = timing.takeoff - timing.push
    landing = timing.rest - timing.touchdown
    crouch = spec.com(timing.push)
    rest = spec.com(timing.rest)
    reach0 = _reach(stances[0], leg.com0)
    reach1 = _reach(stances[1], com_position(character.model, stances[1].q))
    assert float(np.linalg.norm(crouch - leg.com0)) <= reach0 + 1e-9
    assert float(np.linalg.norm(rest - leg.com1)) <= reach1 + 1e-9
    feet = np.mean([c.points[:, 2].mean() for c in stances[0].contacts])
    assert crouch[2] > feet + 0.05  # well above the feet
    assert timing.push_in_reach and timing.landing_in_reach
    assert timing.push_in_cone and timing.landing_in_cone
    np.testing.assert_allclose(timing.push_acceleration * push, leg.v0, atol=1e-9)
    # the contacts are made on the jump's parabola, at or after its node (``_touchdown``)
    late = timing.touchdown - timing.takeoff - leg.duration
    assert late >= -1e-9
    flight = leg.duration + late
    np.testing.assert_allclose(timing.touchdown_velocity, leg.v0 + leg.gravity * flight, atol=1e-9)
    np.testing.assert_allclose(
        timing.touchdown_com, leg.com0 + leg.v0 * flight + 0.5 * leg.gravity * flight**2, atol=1e-9
    )
    np.testing.assert_allclose(
        -timing.landing_acceleration * landing, timing.touchdown_velocity, atol=1e-9
    )
    # the curve's velocity is the jump's at takeoff and touchdown (just inside the flight)
    velocity = spec.com.derivative(1)
    np.testing.assert_allclose(velocity(timing.takeoff + 1e-9), leg.v0, atol=1e-6)
    np.testing.assert_allclose(
        velocity(timing.touchdown - 1e-9), timing.touchdown_velocity, atol=1e-6
    )


@pytest.mark.parametrize("rate", [24.0, 30.0, 60.0])
@pytest.mark.parametrize(("rise", "speed_scale"), [(0.0, 1.0), (0.1, 0.6), (0.2, 1.3)])
def test_every_push_and_landing_holds_a_keyframe(
    rate: float, rise: float, speed_scale: float
) -> None:
    """A push or landing shorter than a keyframe period still holds a keyframe of the grid
    the builder will use (the motion lasts a whole number of periods)."""
    character, stances, leg = _hexapod_jump(rise, speed_scale)
    spec, (timing,) = jump_spec(character, stances, [leg], rate=rate)
    if speed_scale >= 1.0 and rate <= 30.0:  # the case this is about
        assert timing.takeoff - timing.push < 1.0 / rate
    t1 = spec.phases[-1].t1
    assert t1 * rate == pytest.approx(round(t1 * rate), abs=1e-6)
    grid = keyframe_grid(spec.phases[0].t0, t1, rate)
    for phase in spec.phases:
        inside = grid[(grid > phase.t0) & (grid < phase.t1)]
        assert len(inside) >= 1, (phase.t0, phase.t1)


def test_a_jump_too_fast_for_the_legs_is_reported_in_its_timing() -> None:
    """A 0.05 s flight 0.6 m away needs about 12 m/s: even the shortest push
    (``JUMP_MIN_STANCE_S``) travels beyond the hexapod's reach, and the timing says so."""
    character, stances, leg = _hexapod_jump(rise=0.0, speed_scale=0.1)
    spec, (timing,) = jump_spec(character, stances, [leg])
    assert not timing.push_in_reach and not timing.landing_in_reach
    assert timing.takeoff - timing.push == pytest.approx(tuning.JUMP_MIN_STANCE_S)
    travel = float(np.linalg.norm(spec.com(timing.push) - leg.com0))
    assert travel > _reach(stances[0], leg.com0)


def test_a_landing_touches_down_where_the_legs_follow_the_com_best() -> None:
    """The humanoid's standing stance (knees nearly straight) moves its COM along a drop's
    impact velocity at a fifth of its speed with its joints within their speed limits: the
    contacts are made later on the parabola, the legs drawn up, in a crouch that moves it
    faster relative to the touchdown speed, as far down as the landing's reach allows (no
    crouch within it keeps up with this drop: the tracker lags less, it still lags)."""
    character, stances, leg = _hexapod_jump(rise=-0.4, speed_scale=1.2, name="humanoid")
    model = character.model
    limits = speed_limits(model)
    impact = float(np.linalg.norm(leg.vimp))
    standing = com_speed(character, np.asarray(stances[1].q), stances[1], leg.vimp, limits)
    assert standing < 0.3 * impact  # the case this is about
    spec, (timing,) = jump_spec(character, stances, [leg])
    late = timing.touchdown - timing.takeoff - leg.duration
    assert late > 0.0
    speed = float(np.linalg.norm(timing.touchdown_velocity))
    # the COM falls below the node's at most a share of the landing's reach, and here as
    # far as that allows (one more step would go beyond it)
    reach = _reach(stances[1], com_position(model, np.asarray(stances[1].q)))

    def drop(t: float) -> float:
        at = leg.com0 + leg.v0 * t + 0.5 * leg.gravity * t * t
        return float(np.linalg.norm(at - leg.com1))

    flight = leg.duration + late
    assert drop(flight) <= tuning.JUMP_TOUCHDOWN_SHARE * reach + 1e-9
    assert drop(flight + tuning.JUMP_TOUCHDOWN_STEP_S) > tuning.JUMP_TOUCHDOWN_SHARE * reach
    # the landing's posture starts in the crouch the contacts are made in, its COM at the
    # touchdown COM, which moves the COM faster for its speed than the standing stance
    landing = spec.phases[3]
    assert landing.stance and landing.posture_from is not None
    crouch = np.asarray(landing.posture_from)
    np.testing.assert_allclose(com_position(model, crouch), timing.touchdown_com, atol=1e-9)
    crouched = com_speed(character, crouch, stances[1], timing.touchdown_velocity, limits)
    assert crouched / speed > 1.5 * standing / impact


@pytest.mark.parametrize("rise", [-0.4, 0.0, 0.3])
def test_a_humanoid_crouches_with_its_trunk_upright_over_its_feet(rise: float) -> None:
    """The crouches a jump's stance phases aim at (the push's start, the landing's start and
    end) keep the pelvis at the stance's tilt and the chest within 30 degrees of upright:
    the IK lowering the COM with the hips' angles kept pitched the humanoid's pelvis 22 to
    31 degrees backward (the tracked landing squat leaned back)."""
    character, stances, leg = _hexapod_jump(rise=rise, speed_scale=1.0, name="humanoid")
    model = character.model
    (chest,) = _chest_frames(character)
    spec, _ = jump_spec(character, stances, [leg])
    crouches = [
        np.asarray(q)
        for phase in spec.phases
        if phase.stance
        for q in (phase.posture, phase.posture_from)
        if q is not None
    ]
    assert len(crouches) >= 4
    for q in crouches:
        pelvis, torso = frame_placements(model, q, [1, chest])
        assert math.degrees(math.acos(min(1.0, pelvis[2, 2]))) <= 2.0
        assert math.degrees(math.acos(min(1.0, torso[2, 2]))) <= 30.0
    # the crouches do bend the legs: at the landing's end the COM is well nearer the feet
    feet = [character.limb(c.limb).frame_id for c in stances[1].contacts]

    def height(q: np.ndarray) -> float:
        soles = frame_placements(model, q, feet)[:, 2, 3]
        return float(com_position(model, q)[2] - soles.mean())

    assert height(np.asarray(spec.phases[3].posture)) < height(np.asarray(stances[1].q)) - 0.05
