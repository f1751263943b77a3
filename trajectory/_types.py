"""Array aliases and numeric tolerances shared by the trajectory package."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
from numpy.typing import NDArray

FloatArray: TypeAlias = NDArray[np.float64]
BoolArray: TypeAlias = NDArray[np.bool_]

GRAVITY: float = 9.81
"""Magnitude of gravity, m/s^2; the gravity vector is (0, 0, -GRAVITY)."""


@dataclass(frozen=True, slots=True)
class Tolerances:
    """Numeric tolerances used by the kernels (lengths in metres)."""

    membership: float = 1e-9
    """Slack allowed when testing ``A @ c <= b`` (metres, on normalised rows)."""
    polygon: float = 1e-7
    """Support-LP gap below which a polygon edge is accepted as exact (metres)."""
    force_bound: float = 100.0
    """Bound on the total contact force, in body weights, while projecting the region.
    Only regions needing larger internal forces are clipped (unbounded ones stay exact)."""
    slack: float = 1e-6
    """Transition slack below which a quasi-static solution is declared to exist."""


TOL = Tolerances()


def as_float_array(value: object, shape: tuple[int | None, ...], name: str) -> FloatArray:
    """Read-only float64 array of the given shape; ValueError naming ``name`` otherwise."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not convertible to a float array ({exc})") from exc
    if arr.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(arr.shape, shape, strict=True)
    ):
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: contains non-finite values")
    arr.flags.writeable = False
    return arr
