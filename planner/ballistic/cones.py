"""Centroidal friction cone of a contact configuration (jump paper, section 3).

Glossary: ``n_i`` (3,) unit contact normals (pointing out of the surface, into the character),
``mu_i`` friction coefficients; the centroidal cone Kc has axis n_c = sum(n_i) / |sum(n_i)| and
coefficient mu_c = min(mu_i), half-angle atan(mu_c). Kc is a conservative approximation of the
Minkowski sum of the contact cones.

Force closure (|sum(n_i)| ~ 0): the paper declares such configurations invalid for Kc. We follow
it: ``force_closure`` is True and the axis is the zero vector, which ``steering.steer`` rejects
with ``SteerFailure.FORCE_CLOSURE`` (see the steering module docstring for the justification).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

CLOSURE_TOLERANCE = 1e-6
"""|mean of the unit normals| below this is force closure (the axis direction is meaningless)."""


@dataclass(frozen=True, slots=True)
class CentroidalCone:
    """axis : (3,) unit axis, or zeros under force closure. mu : min friction coefficient.

    centre : (3,) mean contact point (m, world frame). force_closure : the normals cancel out.
    """

    axis: FloatArray
    mu: float
    centre: FloatArray
    force_closure: bool

    def __post_init__(self) -> None:
        for name in ("axis", "centre"):
            value = np.array(getattr(self, name), dtype=np.float64)
            value.flags.writeable = False
            object.__setattr__(self, name, value)


def centroidal_cone(
    points: FloatArray,
    normals: FloatArray,
    mus: FloatArray,
    closure_tolerance: float = CLOSURE_TOLERANCE,
) -> CentroidalCone:
    """Centroidal cone of k >= 1 contacts: points (k, 3) m, normals (k, 3), mus (k,).

    Normals are normalised here. Raises ValueError on empty, misshaped, non-finite input, a
    zero normal or a negative mu.
    """
    p = np.asarray(points, dtype=np.float64)
    nrm = np.asarray(normals, dtype=np.float64)
    mu = np.asarray(mus, dtype=np.float64).reshape(-1)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError("points must have shape (k, 3) with k >= 1")
    if nrm.shape != p.shape or mu.shape != (p.shape[0],):
        raise ValueError("normals must be (k, 3) and mus (k,), matching points")
    axes, mu_c, closure = centroidal_cones(
        nrm[None], mu[None], np.ones((1, len(p)), bool), closure_tolerance
    )
    return CentroidalCone(
        axis=axes[0], mu=float(mu_c[0]), centre=p.mean(axis=0), force_closure=bool(closure[0])
    )


def centroidal_cones(
    normals: FloatArray,
    mus: FloatArray,
    mask: BoolArray,
    closure_tolerance: float = CLOSURE_TOLERANCE,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Batched cones for N configurations of up to k contacts.

    normals : (N, k, 3); mus : (N, k); mask : (N, k) which contacts exist. Returns axes (N, 3)
    (zero under force closure or without contacts), mu (N,) (0 without contacts) and the
    force-closure flags (N,) (True without contacts too: no cone exists).
    """
    nrm = np.asarray(normals, dtype=np.float64)
    mu = np.asarray(mus, dtype=np.float64)
    m = np.asarray(mask, dtype=bool)
    if nrm.ndim != 3 or nrm.shape[2] != 3 or mu.shape != nrm.shape[:2] or m.shape != mu.shape:
        raise ValueError("normals (N, k, 3), mus (N, k) and mask (N, k) must match")
    if not (np.all(np.isfinite(nrm[m])) and np.all(np.isfinite(mu[m]))) or np.any(mu[m] < 0):
        raise ValueError("contact normals and mus must be finite, mus non-negative")
    length = np.linalg.norm(nrm, axis=2)
    if np.any(length[m] < 1e-12):
        raise ValueError("contact normals must be non-zero")
    unit = nrm / np.where(length > 0, length, 1.0)[..., None]
    unit = np.where(m[..., None], unit, 0.0)
    count = m.sum(axis=1)
    total = unit.sum(axis=1)
    size = np.linalg.norm(total, axis=1)
    closure = (count == 0) | (size < closure_tolerance * np.maximum(count, 1))
    axes = np.where(closure[:, None], 0.0, total / np.where(size > 0, size, 1.0)[:, None])
    mu_c = np.where(count > 0, np.min(np.where(m, mu, np.inf), axis=1), 0.0)
    return np.asarray(axes, dtype=np.float64), np.asarray(mu_c, dtype=np.float64), closure
