"""The character's body as the contact code sees it: which collision shapes carry each
limb's contact, and where a contact is recorded (placement and contact points).

One rule for every producer of contacts (standing states, contact creation, states sent by
clients), so that every check agrees on what touches the scene by design.

A point contact is a sphere foot: a ball of radius ``|offset|`` centred on the effector frame
origin (the spec's ``offset`` is its lowest point while the effector's contact normal points
along the surface normal, as the built-in feet do in ``q_ref``). Its contact point is the
ball's lowest point, ``origin - |offset| n`` for a surface of normal ``n``, however the frame
is turned: a real robot's foot frame (HyQ's) is tilted in ``q_ref``, so ``origin + R offset``
is not on the surface. :func:`contact_points` and :func:`sphere_centre` are the only places
this rule is written; IK targets, recorded contacts and checks all go through them.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character, Limb
from planner.contact.reachability import ground_limbs
from planner.contact.state import LimbContact
from planner.motion import tuning as motion_tuning
from planner.motion.clearance import PairBroadPhase, shape_poses
from planner.scene import Surface

FloatArray = NDArray[np.float64]

EXEMPT_DISTANCE = 0.01
"""Geometries of a contacting effector's link closer than this (m) to its contact points (or,
for ground limbs, reaching this close to the ground in ``q_ref``) may touch the scene: they
carry the contact."""


@dataclass(frozen=True, slots=True, eq=False)
class BodyGeometry:
    """Per character: the collision objects and the ones exempt per contacting limb."""

    objects: tuple[tuple[int, object, pin.SE3], ...]  # (parent joint, coal geometry, placement)
    exempt: dict[str, frozenset[int]]
    depth: dict[tuple[str, int], float]  # (limb, geometry): m the shape reaches below the sole


_GEOMETRY: dict[int, tuple[Character, BodyGeometry]] = {}  # characters are few and memoised


def _lowest_along(
    geometry: Any, rotation: FloatArray, origin: FloatArray, direction: FloatArray
) -> float:
    """Smallest ``x . direction`` (m) over the points x of a coal ``geometry`` placed at
    (``rotation`` (3, 3), ``origin`` (3,)): exact for spheres, capsules and boxes, from the
    corners of the local bounding box otherwise (a tilted box overestimates the reach)."""
    local = rotation.T @ direction
    base = float(origin @ direction)
    if isinstance(geometry, coal.Sphere):
        return base - float(geometry.radius)
    if isinstance(geometry, coal.Capsule):
        end = float(geometry.halfLength) * abs(float(local[2]))
        return base - end - float(geometry.radius)
    if isinstance(geometry, coal.Box):
        return base - float(np.abs(local) @ np.asarray(geometry.halfSide))
    geometry.computeLocalAABB()
    lo, hi = np.array(geometry.aabb_local.min_), np.array(geometry.aabb_local.max_)
    box = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    return base + float((box @ local).min())


def body_geometry(character: Character) -> BodyGeometry:
    """The character's collision objects, which of them carry each limb's contact (those on
    the effector's link within ``EXEMPT_DISTANCE`` of its contact points, or of the ground for
    ground limbs) and how deep each reaches below the sole, all measured in ``q_ref``;
    memoised per character."""
    key = id(character)
    hit = _GEOMETRY.get(key)
    if hit is not None and hit[0] is character:
        return hit[1]
    model, gmodel = character.model, character.geometry
    data = model.createData()
    pin.framesForwardKinematics(model, data, character.q_ref)
    objects = tuple((int(o.parentJoint), o.geometry, o.placement) for o in gmodel.geometryObjects)
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    exempt: dict[str, frozenset[int]] = {}
    depth: dict[tuple[str, int], float] = {}
    grounded = ground_limbs(character)
    for limb in character.limbs:
        placement = np.asarray(data.oMf[limb.frame_id].homogeneous, dtype=np.float64)
        points, normal = reference_contact(limb, placement)
        joint = int(model.frames[limb.frame_id].parentJoint)
        sole = float((points @ normal).min())
        near = set()
        for g, (parent, geometry, offset) in enumerate(objects):
            if parent != joint:
                continue
            world = data.oMi[parent] * offset
            tf = coal.Transform3s(np.array(world.rotation), np.array(world.translation))
            rotation, origin = np.array(world.rotation), np.array(world.translation)
            lowest = _lowest_along(geometry, rotation, origin, np.array([0.0, 0.0, 1.0]))
            depth[(limb.name, g)] = max(
                0.0, sole - _lowest_along(geometry, rotation, origin, normal)
            )
            if limb.name in grounded and lowest < EXEMPT_DISTANCE:
                near.add(g)
            for point in points:
                result.clear()
                probe = coal.Transform3s(np.eye(3), np.asarray(point, dtype=np.float64))
                d = coal.distance(geometry, tf, coal.Sphere(1e-4), probe, request, result)
                if d < EXEMPT_DISTANCE:
                    near.add(g)
        exempt[limb.name] = frozenset(near)
    out = BodyGeometry(objects, exempt, depth)
    if len(_GEOMETRY) > 64:
        _GEOMETRY.clear()
    _GEOMETRY[key] = (character, out)
    return out


CONTACT_LIFT = 0.006
"""How far (m) a contact-carrying shape is raised along its contact normal before it is tested
against the scene: a sole resting on its surface is free, a toe inside a riser is not."""


def lifted_geometries(
    character: Character, contacts: Sequence[tuple[str, FloatArray]], extra: float = 0.0
) -> dict[int, FloatArray]:
    """For each (limb, unit world normal (3,)) contact, the collision geometries carrying it,
    mapped to the world displacement (3,) they are tested at: along the normal, by
    ``CONTACT_LIFT`` plus how far the shape reaches below the sole (a bounding capsule of a
    real robot's foot may hang 5 cm under it), plus ``extra`` m."""
    body = body_geometry(character)
    out: dict[int, FloatArray] = {}
    for name, normal in contacts:
        for g in body.exempt.get(name, frozenset()):
            lift = CONTACT_LIFT + body.depth.get((name, g), 0.0) + extra
            out[g] = lift * np.asarray(normal, dtype=np.float64)
    return out


def contact_placement(character: Character, limb: str, q: FloatArray, data: Any) -> FloatArray:
    """(4, 4) world placement recorded for ``limb``'s contact at configuration ``q`` (nq,):
    the effector frame for a patch contact; for a point contact (free to turn about its
    point) the effector position with the root's orientation, the frame its offline COM
    polytope is expressed in. ``data`` is Pinocchio scratch data of the character's model."""
    pin.framesForwardKinematics(character.model, data, np.asarray(q, dtype=np.float64))
    spec = character.limb(limb)
    out = np.asarray(data.oMf[spec.frame_id].homogeneous, dtype=np.float64).copy()
    if spec.contact == "point":
        out[:3, :3] = np.asarray(data.oMi[1].rotation)
    return out


def point_radius(limb: Limb) -> float:
    """Radius (m) of a point contact's sphere foot: the length of the limb's offset."""
    return float(np.linalg.norm(limb.offset))


def sphere_centre(limb: Limb, point: FloatArray, normal: FloatArray) -> FloatArray:
    """(3,) world position of the effector frame origin (the sphere's centre) putting point
    contact ``limb`` at ``point`` (3,) on a surface of unit ``normal`` (3,): the inverse of
    :func:`contact_points` for a point contact."""
    return np.asarray(point, dtype=np.float64) + point_radius(limb) * np.asarray(
        normal, dtype=np.float64
    )


def contact_points(limb: Limb, placement: FloatArray, normal: FloatArray) -> FloatArray:
    """(k, 3) world contact points of ``limb`` with its effector at ``placement`` (4, 4) on a
    surface of unit ``normal`` (3,): the patch corners, or for a point contact the lowest
    point of its sphere (frame origin minus the radius along the normal; the placement's
    rotation plays no part)."""
    if limb.contact == "point":
        centre = placement[:3, 3] - point_radius(limb) * np.asarray(normal)
        return np.asarray(centre, dtype=np.float64)[None]
    return np.asarray(limb.contact_points() @ placement[:3, :3].T + placement[:3, 3])


def reference_contact(limb: Limb, placement: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(contact points (k, 3), unit normal (3,)) of ``limb`` with its effector at ``placement``
    (4, 4) as the reference posture means it: a patch on the plane of its contact normal, a
    point foot on level ground (normal +z); a point limb used on request (a sit bone, not
    touching anything in the reference posture) along its frame's contact normal."""
    if limb.contact == "point" and not limb.on_request:
        normal = np.array([0.0, 0.0, 1.0])
    else:
        normal = placement[:3, :3] @ np.asarray(limb.normal, dtype=np.float64)
        normal = normal / np.linalg.norm(normal)
    return contact_points(limb, placement, normal), normal


def lies_on(
    contact: LimbContact,
    surface: Surface,
    limb: Limb,
    *,
    height_tolerance: float,
    normal_tolerance: float,
) -> bool:
    """Whether ``contact`` rests on ``surface``: its points within ``height_tolerance`` (m)
    of the surface plane and inside its polygon, its normal within ``normal_tolerance``
    (rad) of the surface normal, and for a patch the effector's contact normal too (a point
    contact has no orientation). The one rule every check of a contact uses."""
    if float(np.abs(surface.height(contact.points)).max()) > height_tolerance:
        return False
    if not bool(np.all(surface.contains_projection(contact.points))):
        return False
    limit = float(np.cos(normal_tolerance))
    if float(contact.normal @ surface.normal) < limit:
        return False
    if limb.contact == "point":
        return True
    axis = contact.placement[:3, :3] @ limb.normal
    return float(axis @ surface.normal / np.linalg.norm(axis)) >= limit


def self_collides(character: Character, q: FloatArray, data: Any, geometry_data: Any) -> bool:
    """Whether two body shapes of a declared collision pair intersect at ``q`` (nq,);
    ``data`` and ``geometry_data`` are the character's Pinocchio scratch data. Where the
    character's motion geometry (the URDF's own shapes, which the keyframe checker tests)
    is not its planning geometry, those shapes count too, when two of them overlap by more
    than ``STATE_SELF_PENETRATION``: the motion builder could not hold such a state.

    Of the motion geometry's pairs (a real robot's URDF: over a thousand), only those whose
    bounding capsules overlap by more than that are tested (:class:`PairBroadPhase`, exact:
    a shape's penetration into another is at most their capsules'); most states have a few
    dozen."""
    q = np.asarray(q, dtype=np.float64)
    model = character.model
    if pin.computeCollisions(model, data, character.geometry, geometry_data, q, True):
        return True
    motion = _motion_collision(character)
    if motion is None:
        return False
    geometry = character.motion_geometry
    pin.updateGeometryPlacements(model, data, geometry, motion.data)
    near = motion.broad.near_at(shape_poses(motion.data), -motion_tuning.STATE_SELF_PENETRATION)
    if not near:
        return False
    tested = np.zeros(motion.map_shape, dtype=bool)
    pairs = motion.broad.pair_array[near]
    tested[pairs[:, 0], pairs[:, 1]] = tested[pairs[:, 1], pairs[:, 0]] = True
    motion.data.setActiveCollisionPairs(geometry, tested, True)
    return bool(pin.computeCollisions(geometry, motion.data, True))


@dataclass(frozen=True, slots=True)
class _MotionCollision:
    """A thread's scratch for the motion geometry's self-collision test: its GeometryData
    (collision requests reporting only overlaps deeper than ``STATE_SELF_PENETRATION``; the
    pairs tested are switched on per query), the broad phase of its pairs (it remembers
    the gaps of the previous queries) and the shape of the pair map, (G, G)."""

    data: Any
    broad: PairBroadPhase
    map_shape: tuple[int, int]


_MOTION_DATA = threading.local()


def _motion_collision(character: Character) -> _MotionCollision | None:
    """This thread's :class:`_MotionCollision` of ``character.motion_geometry`` (None when
    the motion geometry is the planning geometry)."""
    geometry = character.motion_geometry
    if geometry is character.geometry:
        return None
    cache: dict[int, tuple[Any, _MotionCollision]] | None = getattr(
        _MOTION_DATA, "by_geometry", None
    )
    if cache is None:
        cache = _MOTION_DATA.by_geometry = {}
    hit = cache.get(id(geometry))
    if hit is None or hit[0] is not geometry:
        made = pin.GeometryData(geometry)
        for request in made.collisionRequests:
            request.security_margin = -motion_tuning.STATE_SELF_PENETRATION
        count = len(geometry.geometryObjects)
        if len(cache) >= 8:
            cache.clear()
        hit = (geometry, _MotionCollision(made, PairBroadPhase(geometry), (count, count)))
        cache[id(geometry)] = hit
    return hit[1]
