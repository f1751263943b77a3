"""Overlapping swings (``planner.motion.overlap``): a quadruped walking on level ground lifts
its next leg before the last one lands, diagonal legs in the air together, one contact still
changing per phase; a biped never does; the support distance is plain geometry."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import trajectory
from planner.contact.state import ContactState
from planner.motion import tuning
from planner.motion.overlap import _support_distance, overlap_swings
from planner.motion.sequence import Timing, contact_phase, dynamic_durations, sequence_motion
from tests.planner.contact.contact_helpers import character_and_data, flat_walk, scene

DIAGONALS = ({"lf_foot", "rh_foot"}, {"rf_foot", "lh_foot"})


def _states(character_id: str) -> tuple[ContactState, ...]:
    result = flat_walk(character_id)
    assert result.value is not None
    return result.value.states


def test_a_quadruped_walk_overlaps_its_diagonal_legs_only() -> None:
    character, _ = character_and_data("quadruped")
    states = _states("quadruped")
    overlap = overlap_swings(character, states)
    assert overlap is not None and overlap.pairs
    assert len(overlap.states) == len(states)
    replaced = {first + 1 for first in overlap.pairs}
    for k, (given_state, played) in enumerate(zip(states, overlap.states, strict=True)):
        if k not in replaced:
            assert played is given_state
            continue
        # both legs in the air: the two left on the ground are a diagonal pair, and the
        # state is the one before the first leg lands, without the second
        assert set(played.limbs) in DIAGONALS
        assert set(played.limbs) < set(states[k - 1].limbs)
    for before, after in zip(overlap.states, overlap.states[1:], strict=False):
        assert before.differs_by_one(after)


def test_a_biped_walk_is_not_overlapped() -> None:
    character, _ = character_and_data("humanoid")
    assert overlap_swings(character, _states("humanoid")) is None


def test_overlapped_durations_share_the_swings() -> None:
    character, _ = character_and_data("quadruped")
    overlap = overlap_swings(character, _states("quadruped"))
    assert overlap is not None
    alone = dynamic_durations(character, overlap.states)
    paired = dynamic_durations(character, overlap.states, pairs=overlap.pairs)
    lead = tuning.OVERLAP_LEAD_S
    for first in overlap.pairs:
        assert paired[first] == pytest.approx(lead)
        assert paired[first + 2] == pytest.approx(lead)
        # each leg is in the air as long as its swing alone would take, or longer
        longer = max(alone[first + 1], alone[first + 2])
        assert paired[first] + paired[first + 1] == pytest.approx(longer)
        assert paired[first + 1] + paired[first + 2] >= min(alone[first + 1], alone[first + 2])


def _motion(overlap: bool):  # type: ignore[no-untyped-def]
    character, data = character_and_data("quadruped")
    return sequence_motion(
        character,
        data,
        scene("flat").collision.bvh,
        _states("quadruped"),
        timing=Timing(overlap=overlap),
    )


def test_an_overlapped_walk_has_two_legs_in_the_air_at_once() -> None:
    character, _ = character_and_data("quadruped")
    motion = _motion(overlap=True)
    assert motion.report["overlapped_swings"] > 0
    assert motion.quality.complete
    both_up = [k for k, p in enumerate(motion.phases) if len(p.contacts) == 2]
    assert motion.report["overlapped_phases"] == both_up
    assert motion.states == _states("quadruped")  # the balanced states, as planned
    assert len(motion.phases) == len(motion.states)
    for a, b in zip(motion.phases, motion.phases[1:], strict=False):
        assert len({c.limb for c in a.contacts} ^ {c.limb for c in b.contacts}) == 1
    # Eq. 1 holds (within trajectory.EQ1_TOLERANCE) at every collocation time of every phase,
    # two legs on the ground or more, and at nearly every time the report checks between them
    settings = trajectory.DynamicSettings(sample_spacing=tuning.OVERLAP_SAMPLE_SPACING)
    for phase, segment in zip(motion.phases, motion.com, strict=True):
        piece = trajectory.BezierCurve(segment.control_points, segment.t0, segment.t1)
        times = np.linspace(segment.t0, segment.t1, settings.phase_samples(piece.t1 - piece.t0))
        wrench_phase = contact_phase(character, ContactState(motion.states[0].q, phase.contacts))
        holds, _ = trajectory.holds_at(wrench_phase, piece(times), piece.derivative(2)(times))
        assert holds.all()
    validity = [r["fraction_valid"] for r in motion.report["dynamic_validity"]]
    assert float(np.mean(validity)) >= 0.97
    model = character.model
    data = model.createData()
    ground = float(_states("quadruped")[0].contacts[0].position[2])
    two_up = 0
    for phase in motion.phases:
        if len(phase.contacts) != 2:
            continue
        held = {c.limb for c in phase.contacts}
        free = [limb.name for limb in character.limbs if limb.name not in held]
        middle = min(motion.keyframes, key=lambda k: abs(k.t - 0.5 * (phase.t0 + phase.t1)))
        pin.framesForwardKinematics(model, data, middle.q)
        heights = [float(data.oMf[character.limb(name).frame_id].translation[2]) for name in free]
        two_up += all(h > ground + 0.01 for h in heights)
    assert two_up >= motion.report["overlapped_swings"] - 1


def test_overlap_off_swings_one_leg_at_a_time() -> None:
    motion = _motion(overlap=False)
    assert motion.report["overlapped_swings"] == 0
    assert min(len(p.contacts) for p in motion.phases) == 3


def test_overlap_makes_the_walk_faster() -> None:
    overlapped, alone = _motion(overlap=True), _motion(overlap=False)
    assert overlapped.keyframes[-1].t < 0.8 * alone.keyframes[-1].t


coordinate = st.floats(-2.0, 2.0, allow_nan=False)
point2 = st.tuples(coordinate, coordinate).map(np.array)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(point2, min_size=3, max_size=8), st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8)
)
def test_a_point_inside_the_support_is_at_distance_zero(points: list, weights: list) -> None:  # type: ignore[type-arg]
    hull = np.array(points)
    w = np.array(weights[: len(points)]) + 1e-3
    inside = (w / w.sum()) @ hull  # a convex combination
    assert _support_distance(hull, inside) <= 1e-7


@settings(max_examples=200, deadline=None)
@given(point2, point2, point2)
def test_the_support_distance_of_a_segment_is_to_its_nearest_point(a, b, p) -> None:  # type: ignore[no-untyped-def]
    if np.linalg.norm(b - a) < 1e-6:
        return
    d = _support_distance(np.array([a, b]), p)
    samples = a + np.linspace(0.0, 1.0, 2001)[:, None] * (b - a)
    assert d == pytest.approx(float(np.min(np.linalg.norm(samples - p, axis=1))), abs=2e-3)
    assert d <= min(np.linalg.norm(p - a), np.linalg.norm(p - b)) + 1e-9


@settings(max_examples=200, deadline=None)
@given(st.lists(point2, min_size=3, max_size=8), point2)
def test_the_support_distance_is_no_more_than_to_any_corner(points: list, p) -> None:  # type: ignore[no-untyped-def,type-arg]
    hull = np.array(points)
    assert _support_distance(hull, p) <= float(np.min(np.linalg.norm(hull - p, axis=1))) + 1e-9
