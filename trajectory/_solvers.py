"""The one adapter to the QP/LP backend (daqp).

Canonical form: minimise 0.5 x' H x + f' x subject to lower <= A x <= upper, with optional
simple bounds on x and equality rows. A failure is a status, never an exception.
"""

from __future__ import annotations

from dataclasses import dataclass

import daqp
import numpy as np
from numpy.typing import NDArray

from trajectory._types import FloatArray

INF = 1e30
EQUALITY = 5  # daqp's sense flag of an equality row


@dataclass(frozen=True, slots=True, eq=False)
class QpResult:
    """x (n,) solution (nan when not solved), cost, status (1 optimal), dual (m,)."""

    x: FloatArray
    cost: float
    status: int
    dual: FloatArray

    @property
    def ok(self) -> bool:
        """True when an optimal solution was found."""
        return self.status in (1, 2)


def solve(
    H: FloatArray,
    f: FloatArray,
    A: FloatArray,
    upper: FloatArray,
    lower: FloatArray,
    equality: FloatArray | None = None,
    **settings: float,
) -> QpResult:
    """Solve a dense QP/LP with daqp.

    upper/lower have length n_bounds + m: the first n_bounds entries bound x[:n_bounds].
    ``equality`` is a boolean mask over all entries of upper marking equality rows.
    """
    n_rows = upper.shape[0]
    sense = np.zeros(n_rows, dtype=np.int32)
    if equality is not None:
        sense[np.asarray(equality, dtype=bool)] = EQUALITY
    x, fval, flag, info = daqp.solve(
        np.ascontiguousarray(H, dtype=np.float64),
        np.ascontiguousarray(f, dtype=np.float64),
        np.ascontiguousarray(A, dtype=np.float64),
        np.ascontiguousarray(upper, dtype=np.float64),
        np.ascontiguousarray(lower, dtype=np.float64),
        sense,
        **settings,
    )
    xs = np.asarray(x, dtype=np.float64)
    if flag not in (1, 2):
        xs = np.full(f.shape[0], np.nan)
    return QpResult(xs, float(fval), int(flag), np.asarray(info["lam"], dtype=np.float64))


def solve_raw(
    H: FloatArray,
    f: FloatArray,
    A: FloatArray,
    upper: FloatArray,
    lower: FloatArray,
    sense: NDArray[np.int32],
    **settings: float,
) -> tuple[FloatArray, float, int, FloatArray]:
    """Hot-path variant of ``solve``: contiguous float64 inputs prepared by the caller.

    Returns (x, cost, status, dual) straight from daqp (x is not reset on failure).
    """
    x, fval, flag, info = daqp.solve(H, f, A, upper, lower, sense, **settings)
    return x, float(fval), int(flag), info["lam"]
