"""Scenario builders shared by the trajectory tests and the benchmark."""

from __future__ import annotations

import numpy as np

from trajectory import Contact, ContactPhase, tangent_basis


def patch(center: np.ndarray, normal: np.ndarray, half: float = 0.1, mu: float = 0.5) -> Contact:
    """Square 4-point patch of half-width ``half`` around ``center`` (world frame)."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    t1, t2 = tangent_basis(n)
    c = np.asarray(center, dtype=float)
    pts = np.array([c + a * half * t1 + b * half * t2 for a in (-1, 1) for b in (-1, 1)])
    return Contact(points=pts, normal=n, mu=mu)


def random_contact(rng: np.random.Generator, mu: float = 0.5) -> Contact:
    """A patch on uneven ground (normal within ~40 deg of vertical) or on a wall."""
    if rng.uniform() < 0.7:
        n = np.array([*rng.normal(scale=0.4, size=2), 1.0])
        center = np.array([*rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.1, 0.3)])
    else:
        ang = rng.uniform(0, 2 * np.pi)
        n = np.array([np.cos(ang), np.sin(ang), rng.normal(scale=0.1)])
        center = np.array([*(-0.6 * n[:2] + rng.uniform(-0.2, 0.2, 2)), rng.uniform(0.3, 1.2)])
    return patch(center, n, half=rng.uniform(0.03, 0.12), mu=mu)


def random_phase(rng: np.random.Generator, k: int, mu: float = 0.5) -> ContactPhase:
    """k random patches sharing one friction coefficient."""
    return ContactPhase([random_contact(rng, mu) for _ in range(k)], mass=70.0)


def figure2_phases() -> list[ContactPhase]:
    """2PAC Figure 2: two feet and a right hand on a wall; lift the right foot; put it ahead."""
    lf = patch(np.array([0.0, 0.1, 0.0]), np.array([0.0, 0.0, 1.0]), half=0.08)
    rf = patch(np.array([0.0, -0.1, 0.0]), np.array([0.0, 0.0, 1.0]), half=0.08)
    rf_ahead = patch(np.array([0.3, -0.1, 0.05]), np.array([0.0, 0.0, 1.0]), half=0.08)
    hand = Contact(points=np.array([[0.2, -0.5, 1.0]]), normal=np.array([0.0, 1.0, 0.0]), mu=0.7)
    return [
        ContactPhase([lf, rf, hand]),
        ContactPhase([lf, hand]),
        ContactPhase([lf, rf_ahead, hand]),
    ]


def walking_phases(n_phases: int) -> list[ContactPhase]:
    """Alternating double/single support along x (n_phases phases, one contact change each)."""
    step = 0.15
    feet = {"l": 0.0, "r": 0.0}
    phases = []
    moving = "r"
    for i in range(n_phases):

        def foot(side: str) -> Contact:
            y = 0.1 if side == "l" else -0.1
            return patch(np.array([feet[side], y, 0.0]), np.array([0.0, 0.0, 1.0]), half=0.08)

        if i % 2 == 0:
            phases.append(ContactPhase([foot("l"), foot("r")]))
        else:
            other = "l" if moving == "r" else "r"
            phases.append(ContactPhase([foot(other)]))
            feet[moving] += 2 * step if feet[moving] > 0 or moving == "l" else step
            moving = other
    return phases
