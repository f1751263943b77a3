"""Bezier curves on a time interval [t0, t1]: batched evaluation, derivatives, split,
degree elevation, concatenation and arc length. Out-of-range times raise ValueError."""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from math import comb

import numpy as np
from numpy.typing import NDArray

from trajectory._types import FloatArray, as_float_array

IntArray = NDArray[np.int64]

_TIME_TOL = 1e-12


@lru_cache(maxsize=64)
def _binomials(n: int) -> FloatArray:
    out = np.array([comb(n, k) for k in range(n + 1)], dtype=np.float64)
    out.flags.writeable = False
    return out


@lru_cache(maxsize=64)
def _exponents(n: int) -> tuple[IntArray, IntArray]:
    """(n + 1,) exponents k and n - k of the Bernstein basis of degree n."""
    k = np.arange(n + 1)
    rest = n - k
    k.flags.writeable = False
    rest.flags.writeable = False
    return k, rest


def bernstein(n: int, s: FloatArray) -> FloatArray:
    """(len(s), n + 1) Bernstein basis of degree n at s in [0, 1]."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    k = np.arange(n + 1)[None, :]
    out: FloatArray = _binomials(n)[None, :] * s**k * (1.0 - s) ** (n - k)
    return out


@dataclass(frozen=True, slots=True, eq=False)
class BezierCurve:
    """c(t) = sum_k B_k^n((t - t0) / (t1 - t0)) P_k. control_points (n + 1, d); t0 < t1, s."""

    control_points: FloatArray
    t0: float = 0.0
    t1: float = 1.0

    def __post_init__(self) -> None:
        pts = as_float_array(self.control_points, (None, None), "control_points")
        if pts.shape[0] < 1:
            raise ValueError("control_points: at least one control point is needed")
        if not (np.isfinite(self.t0) and np.isfinite(self.t1)) or not self.t1 > self.t0:
            raise ValueError(f"t1: must be finite and greater than t0, got [{self.t0}, {self.t1}]")
        object.__setattr__(self, "control_points", pts)
        object.__setattr__(self, "t0", float(self.t0))
        object.__setattr__(self, "t1", float(self.t1))

    @property
    def degree(self) -> int:
        """Polynomial degree n."""
        return int(self.control_points.shape[0] - 1)

    @property
    def dim(self) -> int:
        """Dimension d of the points."""
        return int(self.control_points.shape[1])

    @property
    def duration(self) -> float:
        """t1 - t0, seconds."""
        return self.t1 - self.t0

    def _local(self, t: FloatArray) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64))
        span = self.t1 - self.t0
        slack = _TIME_TOL * max(1.0, span)
        if tt.min() < self.t0 - slack or tt.max() > self.t1 + slack:
            raise ValueError(f"t: out of range [{self.t0}, {self.t1}]")
        out: FloatArray = np.minimum(np.maximum((tt - self.t0) / span, 0.0), 1.0)
        return out

    def at(self, t: float) -> FloatArray:
        """The point (d,) at one time ``t`` in [t0, t1] (unchecked): ``self(t)`` with the same
        arithmetic, without the array bookkeeping (a tracker evaluates one time per step)."""
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        n = self.degree
        k, rest = _exponents(n)
        basis = _binomials(n) * s**k * (1.0 - s) ** rest
        out: FloatArray = (basis[None, :] @ self.control_points)[0]
        return out

    def __call__(self, t: float | FloatArray) -> FloatArray:
        """Points: t scalar -> (d,), t (n,) -> (n, d)."""
        s = self._local(np.asarray(t))
        out: FloatArray = bernstein(self.degree, s) @ self.control_points
        return out if np.ndim(t) else out[0]

    def derivative(self, order: int = 1) -> BezierCurve:
        """d^order c / dt^order as a Bezier curve on the same interval (real time units)."""
        curve = self
        for _ in range(order):
            n = curve.degree
            if n == 0:
                pts = np.zeros((1, curve.dim))
            else:
                pts = n * np.diff(curve.control_points, axis=0) / curve.duration
            curve = BezierCurve(pts, curve.t0, curve.t1)
        return curve

    def split(self, t: float) -> tuple[BezierCurve, BezierCurve]:
        """Two curves on [t0, t] and [t, t1] (de Casteljau); t strictly inside."""
        s = float(self._local(np.asarray(t))[0])
        if not 0.0 < s < 1.0:
            raise ValueError(f"t: split time must be strictly inside ({self.t0}, {self.t1})")
        pts = self.control_points.copy()
        left = [pts[0].copy()]
        right = [pts[-1].copy()]
        while pts.shape[0] > 1:
            pts = (1.0 - s) * pts[:-1] + s * pts[1:]
            left.append(pts[0].copy())
            right.append(pts[-1].copy())
        tm = self.t0 + s * self.duration
        first = BezierCurve(np.array(left), self.t0, tm)
        return first, BezierCurve(np.array(right[::-1]), tm, self.t1)

    def elevate(self, times: int = 1) -> BezierCurve:
        """The same curve with the degree raised by ``times``."""
        pts = self.control_points
        for _ in range(times):
            n = pts.shape[0] - 1
            k = np.arange(1, n + 1)[:, None] / (n + 1)
            inner = k * pts[:-1] + (1.0 - k) * pts[1:]
            pts = np.vstack([pts[:1], inner, pts[-1:]])
        return BezierCurve(pts, self.t0, self.t1)

    def arc_length(self, n_nodes: int = 32) -> float:
        """Length in metres by Gauss-Legendre quadrature of the speed."""
        x, wts = np.polynomial.legendre.leggauss(n_nodes)
        t = self.t0 + (x + 1.0) * 0.5 * self.duration
        speed = np.linalg.norm(self.derivative()(t), axis=1)
        return float(0.5 * self.duration * np.sum(wts * speed))

    def retimed(self, t0: float, t1: float) -> BezierCurve:
        """The same geometric curve on another interval."""
        return BezierCurve(self.control_points, t0, t1)


@dataclass(frozen=True, slots=True, eq=False)
class PiecewiseBezier:
    """Consecutive Bezier segments; segment i ends at the time segment i + 1 starts."""

    segments: tuple[BezierCurve, ...]
    _starts: tuple[float, ...] = field(init=False, repr=False, compare=False)
    _breaks: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        segs = tuple(self.segments)
        if not segs:
            raise ValueError("segments: at least one segment is needed")
        for a, b in itertools.pairwise(segs):
            if abs(a.t1 - b.t0) > 1e-9 * max(1.0, abs(a.t1)):
                raise ValueError("segments: time intervals must be contiguous")
        object.__setattr__(self, "segments", segs)
        breaks = np.array([segs[0].t0, *(s.t1 for s in segs)])
        breaks.flags.writeable = False
        object.__setattr__(self, "_breaks", breaks)
        object.__setattr__(self, "_starts", tuple(float(b) for b in breaks))

    @property
    def t0(self) -> float:
        """Start time, s."""
        return self.segments[0].t0

    @property
    def t1(self) -> float:
        """End time, s."""
        return self.segments[-1].t1

    @property
    def breaks(self) -> FloatArray:
        """(k + 1,) segment boundary times (a copy)."""
        return self._breaks.copy()

    def __call__(self, t: float | FloatArray) -> FloatArray:
        """Points: t scalar -> (d,), t (n,) -> (n, d); the later segment wins at a break."""
        if np.ndim(t) == 0:  # one time (a tracker's step): no masks, same arithmetic
            x = float(t)
            if not self.t0 - 1e-12 <= x <= self.t1 + 1e-12:
                raise ValueError(f"t: out of range [{self.t0}, {self.t1}]")
            i = min(max(bisect.bisect_right(self._starts, x) - 1, 0), len(self.segments) - 1)
            seg = self.segments[i]
            point = seg.at(min(max(x, seg.t0), seg.t1))
            return point
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if np.any(tt < self.t0 - 1e-12) or np.any(tt > self.t1 + 1e-12):
            raise ValueError(f"t: out of range [{self.t0}, {self.t1}]")
        idx = np.clip(
            np.searchsorted(self._breaks, tt, side="right") - 1, 0, len(self.segments) - 1
        )
        out = np.zeros((tt.shape[0], self.segments[0].dim))
        if tt.shape[0] > 1 and np.all(idx[1:] >= idx[:-1]):
            # increasing times: each segment's are a run (the same rows as a mask takes)
            cuts = [0, *(np.flatnonzero(idx[1:] != idx[:-1]) + 1).tolist(), tt.shape[0]]
            for a, b in itertools.pairwise(cuts):
                seg = self.segments[int(idx[a])]
                out[a:b] = seg(np.clip(tt[a:b], seg.t0, seg.t1))
            return out if np.ndim(t) else out[0]
        for i in np.unique(idx):
            mask = idx == i
            seg = self.segments[i]
            out[mask] = seg(np.clip(tt[mask], seg.t0, seg.t1))
        return out if np.ndim(t) else out[0]

    def derivative(self, order: int = 1) -> PiecewiseBezier:
        """Segment-wise derivative."""
        return PiecewiseBezier(tuple(s.derivative(order) for s in self.segments))

    def arc_length(self) -> float:
        """Total length, metres."""
        return float(sum(s.arc_length() for s in self.segments))


def concatenate(curves: Sequence[BezierCurve | PiecewiseBezier]) -> PiecewiseBezier:
    """Join curves end to start in time; positions must match at the joins (1e-9)."""
    segs: list[BezierCurve] = []
    for c in curves:
        segs.extend(c.segments if isinstance(c, PiecewiseBezier) else (c,))
    for a, b in itertools.pairwise(segs):
        if np.linalg.norm(a.control_points[-1] - b.control_points[0]) > 1e-9:
            raise ValueError("curves: consecutive curves must meet (end point = next start point)")
    return PiecewiseBezier(tuple(segs))
