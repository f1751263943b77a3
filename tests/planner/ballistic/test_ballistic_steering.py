"""Closed-form steering against brute force, and the invariants of every returned jump."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.ballistic.steering import (
    GRAVITY,
    Choice,
    SteerFailure,
    jumps_at,
    min_launch_speed_sq,
    range_prefilter,
    steer,
    verify_jumps,
)

G = GRAVITY


def random_problem(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Random pairs, tilted cones (some pointing down), mixed bounds."""
    p0 = rng.uniform(-3, 3, (n, 3))
    p1 = rng.uniform(-3, 3, (n, 3))
    up = np.array([0.0, 0.0, 1.0])
    n0 = up + rng.normal(scale=0.6, size=(n, 3))
    n1 = up + rng.normal(scale=0.6, size=(n, 3))
    return {
        "p0": p0,
        "p1": p1,
        "n0": n0,
        "n1": n1,
        "mu0": rng.uniform(0.2, 2.0, n),
        "mu1": rng.uniform(0.2, 2.0, n),
        "v0max": rng.uniform(3.0, 10.0, n),
        "vimpmax": rng.uniform(3.0, 12.0, n),
    }


def direct_feasible(prob: dict[str, np.ndarray], t: np.ndarray) -> np.ndarray:
    """(N, S) feasibility of slopes t (N, S), straight from the V0 / Vimp vectors and angles."""
    n, s = t.shape
    rep = {k: np.repeat(v, s, axis=0) for k, v in prob.items()}
    v0, vimp, _, _ = jumps_at(rep["p0"], rep["p1"], t.reshape(-1), G)
    with np.errstate(invalid="ignore"):
        s0 = np.linalg.norm(v0, axis=1)
        s1 = np.linalg.norm(vimp, axis=1)
        a0 = rep["n0"] / np.linalg.norm(rep["n0"], axis=1, keepdims=True)
        a1 = rep["n1"] / np.linalg.norm(rep["n1"], axis=1, keepdims=True)
        ang0 = np.arccos(np.clip(np.einsum("ij,ij->i", v0, a0) / s0, -1, 1))
        ang1 = np.arccos(np.clip(-np.einsum("ij,ij->i", vimp, a1) / s1, -1, 1))
        ok = (s0 <= rep["v0max"]) & (s1 <= rep["vimpmax"])
        ok &= (ang0 <= np.arctan(rep["mu0"])) & (ang1 <= np.arctan(rep["mu1"]))
    return np.asarray(ok & np.isfinite(s0)).reshape(n, s)


def run(prob: dict[str, np.ndarray], choice: Choice = Choice.MIN_ENERGY):  # type: ignore[no-untyped-def]
    return steer(
        prob["p0"],
        prob["p1"],
        prob["n0"],
        prob["mu0"],
        prob["n1"],
        prob["mu1"],
        v0max=prob["v0max"],
        vimpmax=prob["vimpmax"],
        choice=choice,
    )


@settings(max_examples=10)
@given(seed=st.integers(0, 2**32 - 1))
def test_interval_matches_dense_scan(seed: int) -> None:
    rng = np.random.default_rng(seed)
    prob = random_problem(rng, 100)
    res = run(prob)
    # Scan the takeoff angle over (-pi/2, pi/2).
    alpha = np.linspace(-np.pi / 2, np.pi / 2, 6001)[1:-1]
    step = alpha[1] - alpha[0]
    scan = direct_feasible(prob, np.tile(np.tan(alpha), (len(res), 1)))
    lo_a = np.arctan(res.t_interval[:, 0])
    hi_a = np.arctan(res.t_interval[:, 1])
    for i in range(len(res)):
        found = alpha[scan[i]]
        if res.ok[i]:
            assert res.n_components[i] == 1
            if hi_a[i] - lo_a[i] > 3 * step:
                assert len(found) > 0
                assert abs(found.min() - lo_a[i]) <= 1.5 * step
                assert abs(found.max() - hi_a[i]) <= 1.5 * step
            assert np.all((found >= lo_a[i] - 1.5 * step) & (found <= hi_a[i] + 1.5 * step))
        else:
            # A missed interval can only be thinner than the scan resolution.
            assert len(found) <= 2, (i, SteerFailure(int(res.reason[i])).name, len(found))


@pytest.mark.parametrize("choice", list(Choice))
def test_returned_jumps_meet_every_bound(choice: Choice) -> None:
    rng = np.random.default_rng(7)
    prob = random_problem(rng, 4000)
    res = run(prob, choice)
    ok = res.ok
    assert ok.sum() > 200
    tau = res.duration[ok][:, None]
    landed = res.p0[ok] + res.v0[ok] * tau + 0.5 * np.array([0, 0, -G]) * tau**2
    assert np.all(np.linalg.norm(landed - res.p1[ok], axis=1) <= 1e-3)
    assert np.all(np.linalg.norm(res.v0[ok], axis=1) <= prob["v0max"][ok] * (1 + 1e-9))
    assert np.all(np.linalg.norm(res.vimp[ok], axis=1) <= prob["vimpmax"][ok] * (1 + 1e-9))
    a0 = prob["n0"][ok] / np.linalg.norm(prob["n0"][ok], axis=1, keepdims=True)
    a1 = prob["n1"][ok] / np.linalg.norm(prob["n1"][ok], axis=1, keepdims=True)
    v0, vimp = res.v0[ok], res.vimp[ok]
    cos0 = np.einsum("ij,ij->i", v0, a0) / np.linalg.norm(v0, axis=1)
    cos1 = -np.einsum("ij,ij->i", vimp, a1) / np.linalg.norm(vimp, axis=1)
    assert np.all(np.arccos(np.clip(cos0, -1, 1)) <= np.arctan(prob["mu0"][ok]) + 1e-7)
    assert np.all(np.arccos(np.clip(cos1, -1, 1)) <= np.arctan(prob["mu1"][ok]) + 1e-7)
    # The velocity at landing is the derivative of the parabola at T.
    assert np.allclose(res.vimp[ok], v0 + np.array([0, 0, -G]) * tau, atol=1e-9)
    lo, hi = res.t_interval[ok, 0], res.t_interval[ok, 1]
    assert np.all((res.t[ok] >= lo) & (res.t[ok] <= hi))
    assert np.all(
        verify_jumps(
            res.p0[ok],
            res.p1[ok],
            res.t[ok],
            prob["n0"][ok],
            prob["mu0"][ok],
            prob["n1"][ok],
            prob["mu1"][ok],
            v0max=prob["v0max"][ok],
            vimpmax=prob["vimpmax"][ok],
        )
    )
    # Failed rows are NaN, reasons are counted.
    assert np.all(np.isnan(res.t[~ok]))
    assert sum(res.counts().values()) == len(res)


def test_choices_are_ordered() -> None:
    prob = random_problem(np.random.default_rng(3), 2000)
    by = {c: run(prob, c) for c in Choice}
    ok = by[Choice.MIN_ENERGY].ok
    for c in Choice:
        assert np.array_equal(by[c].ok, ok)
    t_time, t_energy = by[Choice.MIN_TIME].t[ok], by[Choice.MIN_ENERGY].t[ok]
    t_clear, t_mid = by[Choice.MAX_CLEARANCE].t[ok], by[Choice.MID].t[ok]
    assert np.all(t_time <= t_energy + 1e-12)
    assert np.all(t_energy <= t_clear + 1e-12)
    assert np.all((t_time <= t_mid) & (t_mid <= t_clear))
    assert np.all(by[Choice.MIN_TIME].duration[ok] <= by[Choice.MAX_CLEARANCE].duration[ok])
    s_energy = np.linalg.norm(by[Choice.MIN_ENERGY].v0[ok], axis=1)
    for c in Choice:
        assert np.all(s_energy <= np.linalg.norm(by[c].v0[ok], axis=1) * (1 + 1e-9))


@settings(max_examples=40)
@given(
    d=st.floats(0.05, 8.0),
    z=st.floats(-4.0, 4.0),
    heading=st.floats(-np.pi, np.pi),
)
def test_minimum_launch_speed(d: float, z: float, heading: float) -> None:
    p0 = np.array([[0.3, -0.2, 1.0]])
    p1 = p0 + np.array([[d * np.cos(heading), d * np.sin(heading), z]])
    vmin = float(np.sqrt(min_launch_speed_sq(np.array(d), np.array(z))))
    up = np.array([[0.0, 0.0, 1.0]])
    kwargs = {"vimpmax": 100.0}
    above = steer(p0, p1, up, 1e4, up, 1e4, v0max=vmin * (1 + 1e-6), **kwargs)
    below = steer(p0, p1, up, 1e4, up, 1e4, v0max=vmin * (1 - 1e-6), **kwargs)
    assert above.ok[0]
    assert below.reason[0] == SteerFailure.TAKEOFF_SPEED
    assert np.linalg.norm(above.v0[0]) == pytest.approx(vmin, rel=1e-5)
    assert above.t[0] == pytest.approx((z + np.hypot(d, z)) / d, rel=1e-4, abs=1e-4)
    # Landing: the reverse minimum g (r - Z) bounds the landing speed from below.
    wmin = float(np.sqrt(G * (np.hypot(d, z) - z)))
    assert steer(p0, p1, up, 1e4, up, 1e4, v0max=100.0, vimpmax=wmin * (1 + 1e-6)).ok[0]
    late = steer(p0, p1, up, 1e4, up, 1e4, v0max=100.0, vimpmax=wmin * (1 - 1e-6))
    assert late.reason[0] == SteerFailure.LANDING_SPEED
    assert range_prefilter(p0, p1, vmin * (1 + 1e-6), 100.0)[0]
    assert not range_prefilter(p0, p1, vmin * (1 - 1e-6), 100.0)[0]


def test_prefilter_never_rejects_a_feasible_pair() -> None:
    prob = random_problem(np.random.default_rng(11), 5000)
    res = run(prob)
    keep = range_prefilter(prob["p0"], prob["p1"], prob["v0max"], prob["vimpmax"])
    assert np.all(keep[res.ok])
    speed_fail = np.isin(res.reason, [SteerFailure.TAKEOFF_SPEED, SteerFailure.LANDING_SPEED])
    assert np.array_equal(~keep, speed_fail)


def test_special_cases_have_reasons() -> None:
    up = np.array([[0.0, 0.0, 1.0]])
    p0 = np.zeros((1, 3))
    vertical = steer(p0, np.array([[0.0, 0.0, 1.0]]), up, 1.0, up, 1.0, v0max=9, vimpmax=9)
    assert vertical.reason[0] == SteerFailure.VERTICAL
    closure = steer(p0, np.array([[1.0, 0, 0]]), np.zeros((1, 3)), 1.0, up, 1.0, v0max=9, vimpmax=9)
    assert closure.reason[0] == SteerFailure.FORCE_CLOSURE
    # A horizontal cone pointing sideways, thin: no direction of the jump plane lies in it.
    side = np.array([[0.0, 1.0, 0.0]])
    miss = steer(p0, np.array([[1.0, 0, 0]]), side, 0.2, up, 1.0, v0max=9, vimpmax=9)
    assert miss.reason[0] == SteerFailure.TAKEOFF_CONE_MISSES_PLANE
    miss1 = steer(p0, np.array([[1.0, 0, 0]]), up, 1.0, side, 0.2, v0max=9, vimpmax=9)
    assert miss1.reason[0] == SteerFailure.LANDING_CONE_MISSES_PLANE
    # Takeoff cone leaning backwards, landing fine: each alone is satisfiable, not together.
    back = np.array([[-1.0, 0.0, 0.3]])
    empty = steer(p0, np.array([[1.0, 0, 0]]), back, 0.3, up, 1.0, v0max=9, vimpmax=9)
    assert (
        empty.reason[0] == SteerFailure.TAKEOFF_CONE_MISSES_PLANE
        or empty.reason[0] == SteerFailure.EMPTY_INTERVAL
    )
    with pytest.raises(ValueError, match="shape"):
        steer(np.zeros(3), np.ones(3), up, 1.0, up, 1.0, v0max=9, vimpmax=9)
    with pytest.raises(ValueError, match="non-negative"):
        steer(p0, np.ones((1, 3)), up, -1.0, up, 1.0, v0max=9, vimpmax=9)


def test_directed_pairs_differ_under_asymmetric_bounds() -> None:
    low, high = np.array([[0.0, 0.0, 0.0]]), np.array([[2.0, 0.0, 1.5]])
    up = np.array([[0.0, 0.0, 1.0]])
    upward = steer(low, high, up, 1.0, up, 1.0, v0max=5.0, vimpmax=9.0)
    downward = steer(high, low, up, 1.0, up, 1.0, v0max=5.0, vimpmax=9.0)
    assert upward.reason[0] == SteerFailure.TAKEOFF_SPEED
    assert downward.ok[0]
