"""Bezier algebra: evaluation, split/join, elevation, derivative, batching, arc length."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from trajectory import BezierCurve, PiecewiseBezier, concatenate

finite = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
controls = st.integers(1, 9).flatmap(lambda n: arrays(np.float64, (n + 1, 3), elements=finite))
interval = st.tuples(st.floats(-5, 5), st.floats(0.1, 5)).map(lambda a: (a[0], a[0] + a[1]))


@settings(max_examples=60, deadline=None)
@given(pts=controls, span=interval, s=st.floats(0.05, 0.95))
def test_split_then_join_is_the_same_curve(
    pts: np.ndarray, span: tuple[float, float], s: float
) -> None:
    curve = BezierCurve(pts, *span)
    t_split = span[0] + s * (span[1] - span[0])
    left, right = curve.split(t_split)
    joined = concatenate([left, right])
    ts = np.linspace(*span, 23)
    np.testing.assert_allclose(joined(ts), curve(ts), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(pts=controls, span=interval, k=st.integers(1, 3))
def test_elevation_keeps_the_curve(pts: np.ndarray, span: tuple[float, float], k: int) -> None:
    curve = BezierCurve(pts, *span)
    up = curve.elevate(k)
    assert up.degree == curve.degree + k
    ts = np.linspace(*span, 17)
    np.testing.assert_allclose(up(ts), curve(ts), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(pts=controls, span=interval)
def test_batched_equals_looped_and_endpoints(pts: np.ndarray, span: tuple[float, float]) -> None:
    curve = BezierCurve(pts, *span)
    ts = np.linspace(*span, 9)
    looped = np.array([curve(float(t)) for t in ts])
    np.testing.assert_allclose(curve(ts), looped, atol=1e-12)
    np.testing.assert_allclose(curve(span[0]), pts[0], atol=1e-9)
    np.testing.assert_allclose(curve(span[1]), pts[-1], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(pts=controls, span=interval, s=st.floats(0.1, 0.9))
def test_derivative_matches_finite_difference(
    pts: np.ndarray, span: tuple[float, float], s: float
) -> None:
    curve = BezierCurve(pts, *span)
    t = span[0] + s * (span[1] - span[0])
    h = 1e-6 * (span[1] - span[0])
    fd = (curve(t + h) - curve(t - h)) / (2 * h)
    np.testing.assert_allclose(curve.derivative()(t), fd, atol=1e-4 * (1 + np.abs(fd).max()))


def test_arc_length_of_a_straight_line() -> None:
    curve = BezierCurve(np.array([[0.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]]), 0.0, 2.0)
    assert curve.arc_length() == pytest.approx(3.0, rel=1e-9)
    assert concatenate(
        [curve, BezierCurve(np.array([[3.0, 0, 0], [3.0, 4, 0]]), 2.0, 3.0)]
    ).arc_length() == pytest.approx(7.0)


def test_out_of_range_raises() -> None:
    curve = BezierCurve(np.zeros((3, 2)), 0.0, 1.0)
    with pytest.raises(ValueError, match="t"):
        curve(1.5)
    with pytest.raises(ValueError, match="t"):
        curve.split(1.0)
    pw = PiecewiseBezier((curve, BezierCurve(np.zeros((2, 2)), 1.0, 2.0)))
    with pytest.raises(ValueError, match="t"):
        pw(np.array([0.5, 2.5]))
    with pytest.raises(ValueError, match="t1"):
        BezierCurve(np.zeros((2, 2)), 1.0, 1.0)
    with pytest.raises(ValueError, match="curves"):
        concatenate([curve, BezierCurve(np.ones((2, 2)), 1.0, 2.0)])


def test_piecewise_times_at_once_equal_group_by_group() -> None:
    """The dynamic COM evaluates every phase's samples in one call: the same points, to the
    bit, as one call per phase (a sample on a break is the later segment's either way)."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = int(rng.integers(1, 60))
        times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.1, 2.0, n))])
        curve = PiecewiseBezier(
            tuple(BezierCurve(rng.normal(size=(8, 3)), times[j], times[j + 1]) for j in range(n))
        )
        u = np.linspace(0.0, 1.0, 12)
        groups = [times[j] + u * (times[j + 1] - times[j]) for j in range(n)]
        for c in (curve, curve.derivative(2)):
            at_once = c(np.concatenate(groups))
            for j, ts in enumerate(groups):
                assert np.array_equal(at_once[12 * j : 12 * (j + 1)], c(ts))
        assert np.array_equal(curve.breaks, times)
