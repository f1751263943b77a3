"""Half-space polytopes ``A x <= b`` (any dimension, batch on axis 0)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trajectory._types import TOL, BoolArray, FloatArray, as_float_array


@dataclass(frozen=True, slots=True, eq=False)
class Halfspaces:
    """The set {x : A @ x <= b}. A (m, d), b (m,). m = 0 is the whole space."""

    A: FloatArray
    b: FloatArray

    def __post_init__(self) -> None:
        a = as_float_array(self.A, (None, None), "A")
        b = as_float_array(self.b, (a.shape[0],), "b")
        object.__setattr__(self, "A", a)
        object.__setattr__(self, "b", b)

    @property
    def dim(self) -> int:
        """Dimension d of the ambient space."""
        return int(self.A.shape[1])

    def violation(self, x: FloatArray) -> FloatArray:
        """Largest row violation max(A x - b) for x (d,) -> () or (n, d) -> (n,); <= 0 inside."""
        pts = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if self.A.shape[0] == 0:
            out = np.full(pts.shape[0], -np.inf)
        else:
            out = np.max(pts @ self.A.T - self.b, axis=1)
        return out if np.ndim(x) == 2 else out[0]

    def contains(self, x: FloatArray, tol: float = TOL.membership) -> BoolArray:
        """Membership mask: x (d,) -> bool array (), x (n, d) -> (n,)."""
        return np.asarray(self.violation(x) <= tol)


def stack(polytopes: Sequence[Halfspaces], dim: int = 3) -> Halfspaces:
    """Intersection of polytopes, as the stacked rows (Eq. 4)."""
    if not polytopes:
        return Halfspaces(np.zeros((0, dim)), np.zeros(0))
    return Halfspaces(np.vstack([p.A for p in polytopes]), np.concatenate([p.b for p in polytopes]))


def normalise_rows(A: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Scale rows to unit norm (zero rows kept) so violations are distances."""
    norms = np.linalg.norm(A, axis=1)
    scale = np.where(norms > 0.0, 1.0 / np.where(norms > 0.0, norms, 1.0), 1.0)
    return A * scale[:, None], b * scale
