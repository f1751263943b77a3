"""Contacts, contact phases, linearised friction cones and contact wrench generators.

Glossary: a contact has k points (1 for a point contact, 4 for a rectangular patch), all
sharing one unit normal n (world frame, pointing out of the surface, i.e. into the body)
and one friction coefficient mu. Each point contributes ``n_rays`` unit force rays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from trajectory._memo import Remembered
from trajectory._types import GRAVITY, FloatArray, as_float_array


@dataclass(frozen=True, slots=True, eq=False)
class Contact:
    """A contact with the environment.

    points : (k, 3) float, metres, world frame; k = 1 (3D contact) or the 4 patch corners.
    normal : (3,) float, unit, world frame, out of the surface.
    mu : friction coefficient, > 0.
    n_rays : number of rays of the linearised friction cone (>= 3).
    """

    points: FloatArray
    normal: FloatArray
    mu: float = 0.5
    n_rays: int = 4

    def __post_init__(self) -> None:
        pts = np.array(self.points, dtype=np.float64)
        if pts.ndim == 1 and pts.shape == (3,):
            pts = pts[None, :]
        pts = as_float_array(pts, (None, 3), "points")
        if pts.shape[0] < 1:
            raise ValueError("points: at least one contact point is needed")
        normal = as_float_array(self.normal, (3,), "normal")
        norm = float(np.linalg.norm(normal))
        if abs(norm - 1.0) > 1e-4:
            raise ValueError(f"normal: must have unit norm, got {norm:.6f}")
        normal = normal / norm
        normal.flags.writeable = False
        if not np.isfinite(self.mu) or self.mu <= 0.0:
            raise ValueError(f"mu: must be a positive finite number, got {self.mu}")
        if int(self.n_rays) != self.n_rays or self.n_rays < 3:
            raise ValueError(f"n_rays: must be an integer >= 3, got {self.n_rays}")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "mu", float(self.mu))
        object.__setattr__(self, "n_rays", int(self.n_rays))


@dataclass(frozen=True, slots=True, eq=False)
class ContactPhase:
    """A set of simultaneously active contacts and the character mass (kg)."""

    contacts: tuple[Contact, ...]
    mass: float = 70.0
    _generators: FloatArray = field(init=False, repr=False, compare=False)

    def __init__(self, contacts: Sequence[Contact], mass: float = 70.0) -> None:
        contacts_t = tuple(contacts)
        for i, c in enumerate(contacts_t):
            if not isinstance(c, Contact):
                raise ValueError(f"contacts[{i}]: expected a Contact, got {type(c).__name__}")
        if not np.isfinite(mass) or mass <= 0.0:
            raise ValueError(f"mass: must be a positive finite number, got {mass}")
        object.__setattr__(self, "contacts", contacts_t)
        object.__setattr__(self, "mass", float(mass))
        gens = _phase_generators(contacts_t)
        gens.flags.writeable = False
        object.__setattr__(self, "_generators", gens)

    @property
    def wrench_generators(self) -> FloatArray:
        """(m, 6) unit-force wrench generators [f, p x f] about the world origin."""
        return self._generators

    @property
    def n_points(self) -> int:
        """Total number of contact points."""
        return sum(c.points.shape[0] for c in self.contacts)


def tangent_basis(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Tangents (T1, T2) of a unit normal (3,), built as the reference library does."""
    t1 = np.cross(normal, np.array([0.0, 1.0, 0.0]))
    if np.linalg.norm(t1) < 1e-5:
        t1 = np.cross(normal, np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(normal, t1)
    return t1 / np.linalg.norm(t1), t2 / np.linalg.norm(t2)


def friction_rays(normal: FloatArray, mu: float, n_rays: int = 4) -> FloatArray:
    """(n_rays, 3) unit rays of the inscribed linearised friction cone.

    Ray j is normalise(n + mu sin(t_j) T1 + mu cos(t_j) T2), t_j = pi/4 + 2 pi j / n_rays.
    """
    t1, t2 = tangent_basis(normal)
    theta = np.pi / 4.0 + 2.0 * np.pi * np.arange(n_rays) / n_rays
    rays = normal[None, :] + mu * (np.sin(theta)[:, None] * t1 + np.cos(theta)[:, None] * t2)
    out: FloatArray = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    return out


def contact_generators(contact: Contact) -> FloatArray:
    """(k * n_rays, 6) wrench generators [f, p x f] of one contact (unit forces)."""
    rays = friction_rays(contact.normal, contact.mu, contact.n_rays)
    pts = contact.points
    forces = np.broadcast_to(rays[None, :, :], (pts.shape[0], *rays.shape)).reshape(-1, 3)
    origins = np.repeat(pts, rays.shape[0], axis=0)
    out: FloatArray = np.hstack([forces, np.cross(origins, forces)])
    return out


_GENERATORS: Remembered[FloatArray] = Remembered(4096)  # a contact lasts phases


def _remembered_generators(contact: Contact) -> FloatArray:
    """:func:`contact_generators` (read-only), remembered by the contact's content (its points,
    normal, friction and rays): a contact held over several phases, or a phase built again,
    reuses them."""
    key = b"".join(
        (
            contact.points.tobytes(),
            contact.normal.tobytes(),
            np.array([contact.mu, contact.n_rays], dtype=np.float64).tobytes(),
        )
    )
    return _GENERATORS.get(key, lambda: _read_only(contact_generators(contact)))


def _read_only(array: FloatArray) -> FloatArray:
    array.flags.writeable = False
    return array


def _phase_generators(contacts: tuple[Contact, ...]) -> FloatArray:
    if not contacts:
        return np.zeros((0, 6))
    return np.vstack([_remembered_generators(c) for c in contacts])


def gravity_wrench(mass: float, com: FloatArray, acc: FloatArray | None = None) -> FloatArray:
    """(n, 6) wrench the contacts must supply: [m (a - g), c x m (a - g)], com (n, 3).

    ``acc`` (n, 3) or None (static). Angular momentum rate is taken as zero.
    """
    com2 = np.atleast_2d(com)
    f = np.zeros_like(com2)
    f[:, 2] = mass * GRAVITY
    if acc is not None:
        f = f + mass * np.atleast_2d(acc)
    torque = np.stack(
        [
            com2[:, 1] * f[:, 2] - com2[:, 2] * f[:, 1],
            com2[:, 2] * f[:, 0] - com2[:, 0] * f[:, 2],
            com2[:, 0] * f[:, 1] - com2[:, 1] * f[:, 0],
        ],
        axis=1,
    )
    out: FloatArray = np.hstack([f, torque])
    return out
