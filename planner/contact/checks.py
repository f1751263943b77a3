"""Validity checks of contact states: contacts on surfaces, collisions, balance, kinematics.

All positions are world frame, metres; COM polytopes follow 2PAC Eq. 3-4.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character.collision import shape_bounds
from planner.contact.body import (
    contact_placement,
    contact_points,
    lies_on,
    lifted_geometries,
)
from planner.contact.body import self_collides as body_self_collides
from planner.contact.context import ContactContext
from planner.contact.state import ContactState, LimbContact
from trajectory import (
    Contact,
    ContactPhase,
    EffectorConstraint,
    Halfspaces,
    equilibrium_halfspaces,
    equilibrium_margin,
    kinematic_polytope,
)

FloatArray = NDArray[np.float64]

KINEMATIC_TOLERANCE = 1e-3  # m, slack allowed on the learned COM polytopes


def forward(ctx: ContactContext, q: FloatArray) -> None:
    """Update ``ctx.pin_data`` frames for ``q`` (nq,)."""
    pin.framesForwardKinematics(ctx.model, ctx.pin_data, q)


def effector_pose(ctx: ContactContext, limb: str, q: FloatArray | None = None) -> FloatArray:
    """(4, 4) world pose of ``limb``'s effector frame (at ``q`` when given, else last FK)."""
    if q is not None:
        forward(ctx, q)
    fid = ctx.character.limb(limb).frame_id
    return np.asarray(ctx.pin_data.oMf[fid].homogeneous, dtype=np.float64).copy()


def com_of(ctx: ContactContext, q: FloatArray) -> FloatArray:
    """(3,) whole-body COM at ``q``."""
    return np.asarray(pin.centerOfMass(ctx.model, ctx.pin_data, q), dtype=np.float64).copy()


def contact_points_at(
    ctx: ContactContext, limb: str, pose: FloatArray, normal: FloatArray
) -> FloatArray:
    """(k, 3) world contact points of ``limb`` with its effector at ``pose`` (4, 4) on a
    surface of ``normal`` (3,) (see :func:`planner.contact.body.contact_points`)."""
    return contact_points(ctx.character.limb(limb), pose, normal)


def hold_error(ctx: ContactContext, q: FloatArray, contacts: Sequence[LimbContact]) -> float:
    """Largest distance (m) between a contact's points and where ``q`` puts them."""
    forward(ctx, q)
    worst = 0.0
    for c in contacts:
        pts = contact_points_at(ctx, c.limb, effector_pose(ctx, c.limb), c.normal)
        gaps = pts - c.points
        worst = max(worst, math.sqrt(float((gaps * gaps).sum(axis=1).max())))
    return worst


def make_contact(ctx: ContactContext, limb: str, q: FloatArray, surface: int) -> LimbContact:
    """The contact of ``limb`` on scene ``surface`` where configuration ``q`` (nq,) puts it."""
    spec = ctx.character.limb(limb)
    pose = contact_placement(ctx.character, limb, q, ctx.pin_data)
    normal = ctx.scene.surfaces[surface].normal
    pts = contact_points_at(ctx, limb, pose, normal)
    return LimbContact(limb, pose, pts, normal, float(spec.mu), int(surface))


def contacts_key(contacts: Sequence[LimbContact]) -> tuple[Any, ...]:
    """A hashable key of the geometry of ``contacts``."""
    return tuple((c.points.tobytes(), c.normal.tobytes(), c.mu) for c in contacts)


def phase_of(ctx: ContactContext, contacts: Sequence[LimbContact]) -> ContactPhase:
    """The trajectory contact phase of ``contacts`` (mass of the character), memoised."""

    def make() -> ContactPhase:
        return ContactPhase(
            [Contact(c.points, c.normal, c.mu) for c in contacts], float(ctx.character.mass)
        )

    phase: ContactPhase = ctx.shared(("phase", contacts_key(contacts)), make)
    return phase


def kinematics_of(ctx: ContactContext, contacts: Sequence[LimbContact]) -> Halfspaces:
    """World ``K c <= k`` of the COM for the effectors of ``contacts`` (Eq. 4), memoised."""
    if not contacts:
        return Halfspaces(np.zeros((0, 3)), np.zeros(0))

    def make() -> Halfspaces:
        return kinematic_polytope(
            [
                EffectorConstraint(ctx.com_local[c.limb], c.placement[:3, :3], c.placement[:3, 3])
                for c in contacts
            ]
        )

    key = ("kin", tuple((c.limb, c.placement.tobytes()) for c in contacts))
    out: Halfspaces = ctx.shared(key, make)
    return out


def shrunk_equilibrium(
    ctx: ContactContext, contacts: Sequence[LimbContact], depth: float = 1.0
) -> Halfspaces:
    """The static-equilibrium prism of ``contacts`` shrunk by ``depth`` times
    ``params.com_shrink`` (memoised)."""

    def make() -> Halfspaces:
        eq = equilibrium_halfspaces(phase_of(ctx, contacts))
        norms = np.linalg.norm(eq.A, axis=1)
        return Halfspaces(eq.A, eq.b - depth * ctx.params.com_shrink * norms)

    key = ("shrunk", depth, ctx.params.com_shrink, contacts_key(contacts))
    out: Halfspaces = ctx.shared(key, make)
    return out


def balance_margin(ctx: ContactContext, contacts: Sequence[LimbContact], com: FloatArray) -> float:
    """Robustness (N) of static equilibrium of ``com`` (3,) on ``contacts``; -inf if none."""
    if not contacts:
        return -np.inf
    return float(equilibrium_margin(phase_of(ctx, contacts), com).margin)


def contact_on_surface(ctx: ContactContext, contact: LimbContact) -> bool:
    """Contact points within ``surface_tolerance`` of the surface, inside it, normals aligned
    (``body.lies_on`` with the context's tolerances); remembered per contact object."""
    if contact.surface < 0 or contact.surface >= len(ctx.scene.surfaces):
        return False
    on: bool = ctx.per_state(  # a contact is checked again in every state that holds it
        contact,
        "on_surface",
        lambda: lies_on(
            contact,
            ctx.scene.surfaces[contact.surface],
            ctx.character.limb(contact.limb),
            height_tolerance=ctx.params.surface_tolerance,
            normal_tolerance=ctx.params.normal_tolerance,
        ),
    )
    return on


_REQUEST = coal.CollisionRequest()


def _collide(ctx: ContactContext, geometry: Any, matrix: FloatArray) -> bool:
    """Whether a coal ``geometry`` at the world ``matrix`` (4, 4) touches the scene or an
    obstacle (obstacles first filtered by bounding balls)."""
    # CollisionWorld has no public query for a raw coal geometry; reuse its private one.
    hit: bool = ctx.base_world._collide(geometry, matrix)
    if hit or not ctx.obstacle_geometry:
        return bool(hit)
    return _hits_obstacle(ctx, geometry, matrix)


def _hits_obstacle(ctx: ContactContext, geometry: Any, matrix: FloatArray) -> bool:
    """Whether a coal ``geometry`` at the world ``matrix`` (4, 4) touches one of the
    context's obstacles (filtered by bounding balls first)."""
    centre = matrix[:3, :3] @ np.asarray(geometry.aabb_center) + matrix[:3, 3]
    radius = float(geometry.aabb_radius)
    transform = None
    for other, other_tf, other_centre, other_radius in ctx.obstacle_geometry:
        gap = centre - other_centre
        if float(gap @ gap) > (radius + other_radius) ** 2:
            continue
        if transform is None:
            transform = coal.Transform3s(
                np.ascontiguousarray(matrix[:3, :3]), np.ascontiguousarray(matrix[:3, 3])
            )
        result = coal.CollisionResult()
        if coal.collide(other, other_tf, geometry, transform, _REQUEST, result):
            return True
    return False


def _touching(
    ctx: ContactContext,
    q: FloatArray,
    only: Sequence[int] | NDArray[np.int64] | None,
    contacts: Sequence[LimbContact],
    lift: float = 0.0,
) -> list[tuple[int, FloatArray]]:
    """(geometry index, world placement (4, 4) it was tested at) of the character's shapes
    touching the scene or obstacles at ``q``, the shapes carrying ``contacts`` raised
    (``lifted_geometries``, ``lift`` m more)."""
    geometry = ctx.character.geometry
    pin.updateGeometryPlacements(ctx.model, ctx.pin_data, geometry, ctx.geom_data, q)
    objects = geometry.geometryObjects
    indices = list(range(len(objects))) if only is None else [int(i) for i in only]
    raised = lifted_geometries(ctx.character, [(c.limb, c.normal) for c in contacts], lift)
    placed = ctx.geom_data.oMg.tolist()  # one conversion of the list, then only ``indices``
    placements = np.array([placed[i].homogeneous for i in indices])
    for k, i in enumerate(indices):
        if i in raised:
            placements[k, :3, 3] += raised[i]
    # shapes whose bounding balls lie outside the box of the scene (and its obstacles)
    # touch none of it: most of a walker's shapes above level ground
    centres, radii = shape_bounds(geometry)
    balls = np.einsum("kab,kb->ka", placements[:, :3, :3], centres[indices])
    beyond = ctx.base_world.beyond(balls + placements[:, :3, 3], radii[indices])
    hits = []
    for k, i in enumerate(indices):
        placement = placements[k]
        if beyond[k]:
            if ctx.obstacle_geometry and _hits_obstacle(ctx, objects[i].geometry, placement):
                hits.append((i, placement))
            continue
        if _collide(ctx, objects[i].geometry, placement):
            hits.append((i, placement))
    return hits


def scene_collisions(
    ctx: ContactContext,
    q: FloatArray,
    only: Sequence[int] | NDArray[np.int64] | None = None,
    contacts: Sequence[LimbContact] = (),
) -> list[str]:
    """Names of the character's collision geometries touching the scene or obstacles at q
    (only the geometry indices ``only`` when given). The shapes carrying ``contacts`` touch
    their surface by design: they are tested raised by ``CONTACT_LIFT`` along the contact
    normal, so only a real intrusion (a toe in a riser) counts."""
    objects = ctx.character.geometry.geometryObjects
    return [str(objects[i].name) for i, _ in _touching(ctx, q, only, contacts)]


def obstacle_normal(
    ctx: ContactContext, q: FloatArray, contacts: Sequence[LimbContact] = ()
) -> FloatArray | None:
    """Unit direction (3,) pushing the body at ``q`` out of the scene and the obstacles: the
    mean contact normal over the shapes :func:`scene_collisions` reports; None when none."""
    objects = ctx.character.geometry.geometryObjects
    total = np.zeros(3)
    for i, placement in _touching(ctx, q, None, contacts):
        push = ctx.world.push_direction(objects[i].geometry, placement)
        if push is not None:
            total += push
    norm = float(np.linalg.norm(total))
    return None if norm < 1e-9 else np.asarray(total / norm, dtype=np.float64)


def lifts_clear(ctx: ContactContext, q: FloatArray, contact: LimbContact, lift: float) -> bool:
    """Whether the shapes carrying ``contact`` at ``q`` (nq,), raised straight along its
    normal by ``lift`` m (half of it, then all of it) above where :func:`scene_collisions`
    tests them, touch neither the scene nor an obstacle: a sole set half under a rock's
    overhang could not lift off its foothold without driving into the rock."""
    carrying = sorted(lifted_geometries(ctx.character, [(contact.limb, contact.normal)]))
    return not any(_touching(ctx, q, carrying, (contact,), share * lift) for share in (0.5, 1.0))


def self_collides(ctx: ContactContext, q: FloatArray) -> bool:
    """Whether two non-adjacent body shapes intersect at ``q`` (``body.self_collides``)."""
    return body_self_collides(ctx.character, q, ctx.pin_data, ctx.geom_data)


def collision_free(
    ctx: ContactContext, q: FloatArray, contacts: Sequence[LimbContact] = ()
) -> bool:
    """No self-collision and no contact of the body with the scene or obstacles at ``q``,
    the shapes carrying ``contacts`` tested as :func:`scene_collisions` says; remembered per
    configuration and contact limbs and normals (what the test reads of them)."""
    free: bool = ctx.per_configuration(
        q,
        ("collision_free", tuple((c.limb, c.normal.tobytes()) for c in contacts)),
        lambda: not self_collides(ctx, q) and not scene_collisions(ctx, q, contacts=contacts),
    )
    return free


def within_limits(ctx: ContactContext, q: FloatArray, tol: float = 1e-6) -> bool:
    """Joint values of ``q`` inside the character's limits."""
    lo, hi = ctx.model.lowerPositionLimit[7:], ctx.model.upperPositionLimit[7:]
    return bool(np.all(q[7:] >= lo - tol) and np.all(q[7:] <= hi + tol))


@dataclass(frozen=True, slots=True)
class StateReport:
    """Validity of a state: each flag True when the check passes; margin in N."""

    on_surfaces: bool
    held: bool
    collision_free: bool
    balanced: bool
    kinematic: bool
    margin: float
    com: FloatArray

    @property
    def valid(self) -> bool:
        """All checks pass."""
        return (
            self.on_surfaces
            and self.held
            and self.collision_free
            and self.balanced
            and self.kinematic
        )


def check_state(ctx: ContactContext, state: ContactState, hold_tol: float = 1e-3) -> StateReport:
    """Check ``state``: contacts on surfaces, effectors at their contacts (``hold_tol`` m),
    no collision, balance with ``params.margin``, COM inside the kinematic polytopes
    (counted in ``ctx.work``)."""
    ctx.work.states_checked += 1
    q = state.q
    held = hold_error(ctx, q, state.contacts) <= hold_tol
    on = all(contact_on_surface(ctx, c) for c in state.contacts)
    com = com_of(ctx, q)
    margin = balance_margin(ctx, state.contacts, com)
    kin = kinematics_of(ctx, state.contacts)
    kin_ok = bool(kin.violation(com) <= KINEMATIC_TOLERANCE)
    free = collision_free(ctx, q, state.contacts)
    return StateReport(on, held, free, margin >= ctx.params.margin, kin_ok, margin, com)
