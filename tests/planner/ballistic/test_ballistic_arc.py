"""Arc evaluation, bounded-gap sampling, SLERP and the collision-free search over t."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from planner.ballistic.arc import (
    apex,
    arc_length,
    arc_poses,
    arcs_collision_free,
    heights_at_fraction,
    jump_sample_times,
    position_at_distance,
    sample_arc,
    sample_times,
    search_collision_free,
    slerp,
)
from planner.ballistic.steering import jump_at, steer
from planner.ballistic.synthetic import BoxWorld, yaw_quaternions
from tests.planner.ballistic.ballistic_helpers import GAP, dense_collides

UP = np.array([[0.0, 0.0, 1.0]])


@settings(max_examples=60)
@given(
    d=st.floats(0.1, 10.0),
    z=st.floats(-5.0, 5.0),
    extra=st.floats(0.01, 3.0),
    gap=st.floats(0.005, 0.5),
)
def test_sampling_gap_is_bounded(d: float, z: float, extra: float, gap: float) -> None:
    p0, p1 = np.array([0.0, 0.0, 0.0]), np.array([d, 0.0, z])
    t = z / d + extra
    jump = jump_at(p0, p1, t)
    times = jump_sample_times(jump, gap)
    assert times[0] == 0.0
    assert times[-1] == jump.duration
    assert np.all(np.diff(times) > 0)
    pos = jump.position(times)
    assert np.allclose(pos[0], p0) and np.allclose(pos[-1], p1, atol=1e-9)
    chords = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    arcs = np.diff(arc_length(jump.xdot, jump.v0[2], times))
    assert np.all(arcs <= gap * (1 + 1e-9))
    assert np.all(chords <= gap * (1 + 1e-9))
    # Not wasteful: equal arc-length spacing close to the gap.
    total = float(arc_length(jump.xdot, jump.v0[2], jump.duration))
    assert len(times) - 1 == max(1, int(np.ceil(total / (0.999 * gap))))


def test_arc_length_matches_quadrature() -> None:
    jump = jump_at(np.zeros(3), np.array([3.0, 1.0, -0.5]), 1.3)
    tau = np.linspace(0.0, jump.duration, 200001)
    speed = np.linalg.norm(jump.velocity(tau), axis=1)
    numeric = np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(tau))
    assert float(arc_length(jump.xdot, jump.v0[2], jump.duration)) == pytest.approx(
        numeric, rel=1e-8
    )


def test_batched_sampling_equals_single() -> None:
    jumps = [
        jump_at(np.zeros(3), np.array([d, 0.5, z]), t)
        for d, z, t in [(1.0, 0.2, 1.0), (4.0, -1.0, 0.3), (0.3, 2.0, 9.0)]
    ]
    times, offsets = sample_times(
        np.array([j.xdot for j in jumps]),
        np.array([j.v0[2] for j in jumps]),
        np.array([j.duration for j in jumps]),
        0.04,
    )
    for k, j in enumerate(jumps):
        assert np.allclose(times[offsets[k] : offsets[k + 1]], jump_sample_times(j, 0.04))


def test_evaluation_helpers_agree() -> None:
    p0, p1 = np.array([1.0, 2.0, 0.5]), np.array([3.0, -1.0, 1.2])
    jump = jump_at(p0, p1, 1.1)
    d = np.hypot(2.0, 3.0)
    s = np.linspace(0, d, 11)
    by_distance = position_at_distance(jump, s)
    assert np.allclose(by_distance[:, 2], heights_at_fraction(p0, p1, s / d, 1.1))
    assert np.allclose(by_distance[-1], p1)
    top, when = apex(jump)
    dense = jump.position(np.linspace(0, jump.duration, 10001))
    assert top[2] >= dense[:, 2].max() - 1e-9
    assert np.allclose(top, jump.apex)
    assert np.allclose(jump.velocity(when)[2], 0.0, atol=1e-9)


def test_height_is_affine_and_increasing_in_t() -> None:
    p0, p1 = np.zeros(3), np.array([2.0, 0.0, 0.7])
    sigma = np.linspace(0, 1, 21)
    z1, z2, z3 = (heights_at_fraction(p0, p1, sigma, t) for t in (0.6, 1.0, 1.4))
    assert np.allclose(z2, 0.5 * (z1 + z3))
    assert np.all(z3 >= z2) and np.all(z2 >= z1)
    for t, z in ((0.6, z1), (1.4, z3)):
        jump = jump_at(p0, p1, t)
        assert np.allclose(jump.position(sigma * jump.duration)[:, 2], z)


def test_slerp_matches_scipy() -> None:
    rng = np.random.default_rng(0)
    q = Rotation.random(2, random_state=1).as_quat()
    frac = np.sort(rng.random(50))
    ours = Rotation.from_quat(slerp(q[0], q[1], frac))
    theirs = Slerp([0, 1], Rotation.from_quat(q))(frac)
    assert np.allclose((ours.inv() * theirs).magnitude(), 0.0, atol=1e-9)
    ends = slerp(q[0], -q[1], np.array([0.0, 1.0]))  # antipodal sign does not matter
    assert np.allclose(Rotation.from_quat(ends).as_matrix(), Rotation.from_quat(q).as_matrix())


def test_arc_poses_slerp_orientation() -> None:
    jump = jump_at(np.zeros(3), np.array([2.0, 0.0, 0.0]), 1.0)
    q = yaw_quaternions(np.array([0.0, np.pi / 2]))
    poses = arc_poses(jump, q[0], q[1], np.array([0.0, 0.5 * jump.duration, jump.duration]))
    yaw = np.arctan2(poses[:, 1, 0], poses[:, 0, 0])
    assert np.allclose(yaw, [0.0, np.pi / 4, np.pi / 2])
    assert np.allclose(poses[:, :3, 3], jump.position(np.array([0, 0.5, 1]) * jump.duration))


def wall_world(height: float, ceiling: float | None = None) -> BoxWorld:
    """Floor slabs at z <= 0 on x in [-1, 0.5] and [2.5, 4]; a wall at x in [1.4, 1.6]."""
    lo = [[-1, -1, -0.2], [2.5, -1, -0.2], [1.4, -1, -0.2]]
    hi = [[0.5, 1, 0.0], [4, 1, 0.0], [1.6, 1, height]]
    if ceiling is not None:
        lo.append([0.6, -1, ceiling])
        hi.append([2.4, 1, ceiling + 0.2])
    return BoxWorld(centres=[[-0.15, 0, 0], [0.15, 0, 0]], radius=0.1, box_lo=lo, box_hi=hi)


def steer_pair(p0: np.ndarray, p1: np.ndarray):  # type: ignore[no-untyped-def]
    return steer(p0[None], p1[None], UP, 2.0, UP, 2.0, v0max=12.0, vimpmax=14.0)


@pytest.mark.parametrize(("height", "ceiling"), [(0.9, None), (1.6, None), (0.3, 1.6)])
def test_search_finds_free_arcs(height: float, ceiling: float | None) -> None:
    world = wall_world(height, ceiling)
    planning = world.inflated(GAP)
    p0, p1 = np.array([0.0, 0.0, 0.4]), np.array([3.0, 0.0, 0.4])
    q0, q1 = yaw_quaternions(np.array([0.0, 0.8]))
    res = steer_pair(p0, p1)
    assert res.ok[0]
    lo, hi = res.t_interval[0]
    first = jump_at(p0, p1, float(res.t[0]))
    found = search_collision_free(p0, p1, q0, q1, (lo, hi), float(res.t[0]), planning, GAP)
    assert found.ok and found.jump is not None
    assert lo <= found.t <= hi
    assert not dense_collides(found.jump, q0, q1, world)
    if not dense_collides(first, q0, q1, planning):
        assert found.rounds == 1


def test_search_reports_impossible() -> None:
    world = wall_world(20.0)
    p0, p1 = np.array([0.0, 0.0, 0.4]), np.array([3.0, 0.0, 0.4])
    q = yaw_quaternions(np.array([0.0]))[0]
    res = steer_pair(p0, p1)
    lo, hi = res.t_interval[0]
    found = search_collision_free(p0, p1, q, q, (lo, hi), float(res.t[0]), world.inflated(GAP), GAP)
    assert not found.ok and found.jump is None and np.isnan(found.t)


def test_batched_arc_check_equals_single() -> None:
    world = wall_world(0.9)
    rng = np.random.default_rng(2)
    n = 30
    p0 = np.column_stack([rng.uniform(-0.8, 0.4, n), rng.uniform(-0.5, 0.5, n), np.full(n, 0.4)])
    p1 = np.column_stack([rng.uniform(2.6, 3.8, n), rng.uniform(-0.5, 0.5, n), np.full(n, 0.4)])
    res = steer(p0, p1, UP, 2.0, UP, 2.0, v0max=9.0, vimpmax=12.0)
    q0 = yaw_quaternions(rng.uniform(-3, 3, n))
    q1 = yaw_quaternions(rng.uniform(-3, 3, n))
    ok = res.ok
    assert ok.sum() > 10
    batched = arcs_collision_free(
        res.p0[ok], res.v0[ok], res.duration[ok], q0[ok], q1[ok], world, GAP, chunk=500
    )
    single = []
    for i in np.flatnonzero(ok):
        _, poses = sample_arc(res.jump(int(i)), q0[i], q1[i], GAP)
        single.append(not world(poses).any())
    assert np.array_equal(batched, np.array(single))
    assert 0 < batched.sum() < len(batched)
