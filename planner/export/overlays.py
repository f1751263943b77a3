"""What a viewer draws beside the body, computed from a motion: COM polylines, jump
parabolas, contact phases with their contact points and static-equilibrium polygons. All in
Gecko's world (z up), metres."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

import trajectory
from planner.character import Character
from planner.export.gltf import PhaseMarks
from trajectory.bezier import BezierCurve

FloatArray = NDArray[np.float64]

GRAVITY = np.array([0.0, 0.0, -9.81])
SAMPLES_PER_SECOND = 60.0
MAX_SAMPLES_PER_CURVE = 2_000
EQUILIBRIUM_DRAW_RADIUS = 3.0  # m: unbounded equilibrium regions are drawn clipped to this
MIN_EQUILIBRIUM_WIDTH = 1e-4  # m: thinner regions (a point, a segment) are not drawn


def bezier_polyline(segments: Sequence[tuple[float, float, FloatArray]]) -> FloatArray:
    """Piecewise Bezier COM curve sampled as one (m, 3) polyline.

    segments : (t0, t1, control points (k, 3)) per piece, s and m; pieces with t1 <= t0 are
    skipped. About ``SAMPLES_PER_SECOND`` points per second, at least 8 per piece.
    """
    points: list[FloatArray] = []
    for t0, t1, control in segments:
        if not t1 > t0:
            continue
        count = int(min(MAX_SAMPLES_PER_CURVE, max(8, np.ceil((t1 - t0) * SAMPLES_PER_SECOND))))
        curve = BezierCurve(np.asarray(control, dtype=np.float64), t0, t1)
        samples = curve(np.linspace(t0, t1, count))
        points.append(samples if not points else samples[1:])
    return np.concatenate(points) if points else np.zeros((0, 3))


def parabola(position: FloatArray, velocity: FloatArray, duration: float) -> FloatArray:
    """A ballistic arc p(t) = p0 + v0 t + g t^2 / 2 over [0, duration] s, as (m, 3) points."""
    count = int(min(MAX_SAMPLES_PER_CURVE, max(8, np.ceil(duration * SAMPLES_PER_SECOND))))
    t = np.linspace(0.0, max(duration, 0.0), count)[:, None]
    return np.asarray(position[None, :] + velocity[None, :] * t + 0.5 * GRAVITY[None, :] * t**2)


def contact_points(character: Character, q: FloatArray, limbs: Sequence[str]) -> FloatArray:
    """(k, 3) world contact points of ``limbs`` (their patch corners or point) at q."""
    model = character.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=np.float64))
    out = []
    for name in limbs:
        limb = character.limb(name)
        placement = data.oMf[limb.frame_id]
        rotation = np.asarray(placement.rotation)
        local = limb.contact_points()
        out.append(local @ rotation.T + np.asarray(placement.translation)[None, :])
    return np.concatenate(out) if out else np.zeros((0, 3))


def phases_from_keyframes(
    character: Character,
    times: FloatArray,
    qs: FloatArray,
    contacts: Sequence[Sequence[str]],
) -> tuple[PhaseMarks, ...]:
    """Contact phases as runs of keyframes with the same limbs in contact.

    times : (n,) s; qs : (n, nq); contacts : limbs in contact per keyframe. Each phase's
    points are its limbs' contact points at the phase's first keyframe; a phase ends where
    the next one starts (the last at the last keyframe).
    """
    phases: list[PhaseMarks] = []
    start = 0
    for k in range(1, len(times) + 1):
        if k < len(times) and set(contacts[k]) == set(contacts[start]):
            continue
        limbs = tuple(sorted(contacts[start]))
        t1 = float(times[k]) if k < len(times) else float(times[-1])
        points = contact_points(character, qs[start], limbs)
        phases.append(PhaseMarks(float(times[start]), t1, limbs, points))
        start = k
    return tuple(phases)


def equilibrium_outline(
    contacts: Sequence[tuple[FloatArray, FloatArray, float]], mass: float, height: float
) -> FloatArray:
    """The static-equilibrium COM region of a contact phase as a closed outline (m, 3).

    contacts : (points (k, 3), unit normal (3,), friction coefficient) per contact, world
    frame, metres. Under gravity alone the region is a vertical prism over a convex polygon
    (``trajectory.equilibrium_polygon``); the outline is that polygon, counter-clockwise,
    at z = ``height``, clipped to a square of half-side ``EQUILIBRIUM_DRAW_RADIUS`` about
    the contacts' centroid. Empty (0, 3) when the region is empty or thinner than
    ``MIN_EQUILIBRIUM_WIDTH``, or there are no contacts.
    """
    if not contacts:
        return np.zeros((0, 3))
    phase = trajectory.ContactPhase(
        [trajectory.Contact(points=p, normal=n, mu=mu) for p, n, mu in contacts], mass=mass
    )
    polygon = trajectory.equilibrium_polygon(phase)
    centre = np.vstack([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p, _, _ in contacts])
    centre_xy = centre.mean(axis=0)[:2]
    box = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    A = np.vstack([polygon.A, box])
    b = np.concatenate([polygon.b, box @ centre_xy + EQUILIBRIUM_DRAW_RADIUS])
    # Chebyshev centre: max r such that A x + r |a_i| <= b, the interior point the
    # half-space intersection needs.
    norms = np.linalg.norm(A, axis=1)
    found = linprog(
        c=[0.0, 0.0, -1.0],
        A_ub=np.hstack([A, norms[:, None]]),
        b_ub=b,
        bounds=[(None, None), (None, None), (0.0, None)],
        method="highs",
    )
    if not found.success or found.x[2] < MIN_EQUILIBRIUM_WIDTH / 2:
        return np.zeros((0, 3))
    corners = HalfspaceIntersection(np.hstack([A, -b[:, None]]), found.x[:2]).intersections
    hull = ConvexHull(corners)
    outline = corners[hull.vertices]  # counter-clockwise in 2D
    return np.column_stack([outline, np.full(len(outline), float(height))])
