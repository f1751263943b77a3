"""An independent checker ("auditor") of the motion Gecko hands over (keyframes, phases, COM).

It shares no code with what produced the motion: no import of ``planner.motion``,
``planner.contact``, ``planner.kinematics``, ``planner.ballistic`` or ``trajectory``.
``planner.character`` is read only for a character's URDF text and limb spec (effector frame,
contact kind, patch size, offset, reference posture), ``planner.scene`` not at all: the scene
is given as its triangle mesh (vertices, faces), as ``GET /v1/scenes/{id}/mesh`` serves it.
The figures are those of ``/work/shared/research/motion-quality.md``.

Character
    The URDF loaded by Pinocchio under a free-flyer root (``pin.buildModelFromXML``) and its
    own collision geometry (``pin.buildGeomFromUrdfString``, COLLISION). Mesh links (Talos,
    HyQ: STL / DAE from example-robot-data, found through its installed ``share`` directory)
    become their convex hulls (``coal`` ``buildConvexHull``). If the meshes cannot be loaded,
    the mesh collision elements are dropped and ``MotionAudit.notes`` says so.

Scene
    The mesh (vertices merged) split into edge-connected components (trimesh), each becoming:

    - ``halfspace``: the ground. A horizontal flat sheet, or a convex slab with a flat top,
      whose x-y box covers at least ``GROUND_COVER`` of the scene's and whose top is no
      higher than the top of any other component. Everything below it and within its x-y
      footprint is inside (true depth), but under a hole of the sheet (debris set into the
      ground) a link is measured against the sheet's own top triangles.
    - ``convex``: a component whose faces all lie on the boundary of its (3-D) convex hull is
      that hull's solid (``coal.Convex``): closed boxes and cylinders, and the boxes left open
      at the bottom where they stand on the ground, posts open where they run into a rail.
      ``coal.distance`` gives the true penetration depth (GJK/EPA, negative inside).
    - ``mesh``: the rest, a triangle BVH (``coal.BVHModelOBBRSS``). The depth against it is
      the deepest of coal's triangle contacts (``coal.collide``; ``coal.distance`` to a BVH
      returns one colliding triangle, not the deepest). That only measures how far a link
      crosses a triangle, and a link wholly inside a solid touches no triangle; so when the
      component is a solid (watertight, or open only along its lowest edges, as a block
      resting on the ground) sample points of the link (box corners and centre, segment ends
      of spheres, capsules and cylinders with their radius, hull vertices) are tested for
      being inside (parity of a vertical ray upward) and their distance to the surface (plus
      the radius of the link around them) is a lower bound of the depth. The depth of a link
      is the larger of the two. (The stairs, the climbing wall, two Bauzil stairs blocks.)

Stance links: for each limb listed in a keyframe's ``contacts``, the joint carrying the
limb's effector frame and its descendants (Pinocchio subtree). Contact points of a limb, as the
character README defines them: a patch's 4 corners ``offset +- half_size`` in the effector
frame (order (+,+), (+,-), (-,-), (-,+)); a point contact is a ball of radius ``|offset|``
centred on the effector frame, touching at the centre minus the radius along the surface
normal (the phase contact's normal; without one, the error is the ball's distance from the
point). Stance contact error: the largest distance of these points from the phase's.

Self-collision: pairs of collision objects on different joints, not adjacent (one joint is the
nearest shape-carrying ancestor of the other) and not already within
``REFERENCE_OVERLAP_M`` of each other in the reference posture (the spec's joint values,
others 0).

Figures per keyframe pair: a pop when some joint moves faster (|pin.difference| / dt) than
``MAX_JOINT_SPEED`` or its URDF velocity limit; a root jump when the root moves more than
``ROOT_JUMP_M`` (scaled up for pairs further apart than 1/30 s) and the pair does not overlap a
flight. Per keyframe: the COM error against the first COM piece whose [t0, t1] holds t
(de Casteljau); the tilt of the root's z axis, and the trunk's (the most tilted body where the
limbs branch or between such a body and the root: a humanoid's pelvis or chest; tilts from
the reference posture's); a still COM when the central difference of the keyframe COMs is
under ``STILL_COM_SPEED``. ``stance_penetrating_frames``
counts keyframes where a stance link is more than 1 cm inside the scene farther than
``STANCE_NEAR_M`` (plus the patch's half diagonal or ball radius) from its phase contact
points (the optional check).

Inputs are plain data (``Frame``, ``PhaseData``, ``ComPiece`` or tuples of the same fields);
``audit_from_domain`` reads today's planner objects and ``audit_from_json`` an HTTP answer.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin
import trimesh
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

FloatArray = NDArray[np.float64]

# -- tolerances (the goals of motion-quality.md) ---------------------------------------------
PENETRATION_TOL_M = 0.01  # a non-stance link deeper than this inside the scene: penetrating
SELF_COLLISION_TOL_M = 0.01  # two links interpenetrating deeper than this: self-collision
STANCE_CONTACT_TOL_M = 0.005  # goal for the stance effector's distance from its contact
STANCE_NEAR_M = 0.05  # a stance link's penetration within this of its contact points is fine
MAX_JOINT_SPEED = 10.0  # rad/s, cap on every joint's speed (below the URDF limit if lower)
ROOT_JUMP_M = 0.05  # root displacement between consecutive keyframes at ROOT_JUMP_RATE_HZ
ROOT_JUMP_RATE_HZ = 30.0  # keyframes further apart than 1/30 s may move proportionally more
COM_ERROR_TOL_M = 0.02  # goal for the p99 of the keyframe COM's distance from the COM curve
TILT_TOL_DEG = 30.0  # goal for the root's tilt on walks and stairs (upright characters)
STILL_COM_SPEED = 0.01  # m/s: a keyframe whose COM moves slower is "still"
CLOSE_SPACING = 0.5  # keyframe pairs closer than this fraction of the median period
REFERENCE_OVERLAP_M = 1e-4  # pairs this close in the reference posture are not checked
TIME_EPS = 1e-9  # s, slack of the time comparisons (phase and segment bounds)
GEOMETRY_EPS = 1e-5  # m, flatness and on-the-hull tests of the scene components
GROUND_COVER = 0.5  # fraction of the scene's x-y box a component covers to be the ground
MAX_PROBE_POINTS = 64  # sample points of a mesh link tested for being inside a solid
MAX_MESH_CONTACTS = 256  # triangle contacts asked of coal per link and scene mesh


# -- plain-data inputs ------------------------------------------------------------------------


class Frame(NamedTuple):
    """One keyframe: time (s), Pinocchio q (nq,) (root position, quaternion [x, y, z, w],
    joints in the URDF's order) and the limbs in contact."""

    t: float
    q: FloatArray
    contacts: tuple[str, ...]


class PhaseContact(NamedTuple):
    """A limb's contact in a phase: world contact points (k, 3) and the unit surface normal
    (3,) pointing out of the surface (None: unknown)."""

    limb: str
    points: FloatArray
    normal: FloatArray | None = None


class PhaseData(NamedTuple):
    """A phase [t0, t1] s and its contacts (``PhaseContact`` or (limb, points[, normal]))."""

    t0: float
    t1: float
    contacts: tuple[PhaseContact, ...]


class ComPiece(NamedTuple):
    """One Bezier piece of the COM curve over [t0, t1]: control points (d + 1, 3), m."""

    t0: float
    t1: float
    control_points: FloatArray


# -- result -----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class MotionAudit:
    """The figures of one motion (motion-quality.md); per-frame arrays for debugging.

    Counts: ``frames`` keyframes, ``pairs`` consecutive keyframe pairs. Depths are positive
    (m). Arrays: ``penetration`` (frames,) the deepest non-stance link, ``stance_error``
    (frames,) the worst stance effector distance (NaN: no stance matched), ``self_penetration``
    (frames,), ``com_error`` (frames,) (NaN: no COM piece at that time), ``tilt_deg``
    (frames,), ``joint_speed`` (pairs,) the fastest joint, ``root_step`` (pairs,) m,
    ``coms`` (frames, 3) m the keyframes' COM (world).
    """

    frames: int
    pairs: int
    penetrating_frames: int
    worst_penetration_m: float
    worst_penetration_link: str
    worst_penetration_frame: int
    stance_penetrating_frames: int
    stance_contact_error_m: float
    self_collision_frames: int
    worst_self_collision_m: float
    worst_self_collision_pair: str
    pops: int
    max_joint_speed: float
    max_speed_joint: str
    root_jumps: int
    max_root_step_m: float
    com_error_p99_m: float
    com_error_max_m: float
    tilt_max_deg: float
    trunk_tilt_max_deg: float
    phases: int
    phases_animated: int
    coverage: float
    min_spacing_s: float
    close_pairs: int
    duration_s: float
    pace_m_per_s: float
    still_com_fraction: float
    times: FloatArray
    penetration: FloatArray
    penetration_links: tuple[str, ...]
    stance_error: FloatArray
    self_penetration: FloatArray
    com_error: FloatArray
    tilt_deg: FloatArray
    joint_speed: FloatArray
    root_step: FloatArray
    notes: tuple[str, ...] = field(default=())
    coms: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def penetrating_fraction(self) -> float:
        return self.penetrating_frames / self.frames if self.frames else math.nan

    @property
    def self_collision_fraction(self) -> float:
        return self.self_collision_frames / self.frames if self.frames else math.nan

    @property
    def pop_fraction(self) -> float:
        return self.pops / self.pairs if self.pairs else math.nan

    def summary(self) -> str:
        """One line with the headline figures."""
        return (
            f"frames {self.frames} penetrating {self.penetrating_frames} "
            f"(worst {1e3 * self.worst_penetration_m:.0f} mm {self.worst_penetration_link}) "
            f"self {self.self_collision_frames} pops {self.pops} "
            f"(max {self.max_joint_speed:.1f} rad/s {self.max_speed_joint}) "
            f"root jumps {self.root_jumps} COM p99 {1e3 * self.com_error_p99_m:.0f} mm "
            f"tilt {self.tilt_max_deg:.0f} deg (trunk {self.trunk_tilt_max_deg:.0f}) "
            f"coverage {self.coverage:.0%}"
        )


# -- geometry helpers -------------------------------------------------------------------------


def _transform(rotation: FloatArray, translation: FloatArray) -> Any:
    return coal.Transform3s(
        np.ascontiguousarray(rotation, dtype=np.float64),
        np.ascontiguousarray(translation, dtype=np.float64),
    )


_IDENTITY = coal.Transform3s()
_POINT = coal.Sphere(1e-9)


def _convex_from_points(points: FloatArray) -> Any:
    vec = coal.StdVec_Vec3s()
    for p in np.asarray(points, dtype=np.float64):
        vec.append(p)
    return coal.Convex.convexHull(vec, False, None)


def _bvh(vertices: FloatArray, faces: NDArray[np.int64]) -> Any:
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(faces), len(vertices))
    model.addVertices(np.ascontiguousarray(vertices, dtype=np.float64))
    model.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    model.endModel()
    return model


def _signed_distance(a: Any, tf_a: Any, b: Any, tf_b: Any) -> tuple[float, FloatArray]:
    """coal distance (negative: penetration depth) and the witness point on ``a``."""
    request = coal.DistanceRequest()
    result = coal.DistanceResult()
    d = coal.distance(a, tf_a, b, tf_b, request, result)
    return float(d), np.array(result.getNearestPoint1(), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class _Probe:
    """A link shape for the scene tests: coal geometry, local bounding sphere, local sample
    points with the radius of the shape around each (inside-solid test)."""

    geometry: Any
    centre: FloatArray
    radius: float
    points: FloatArray
    inner: FloatArray


def _probe(geometry: Any) -> _Probe:
    geometry.computeLocalAABB()
    centre = np.array(geometry.aabb_center, dtype=np.float64)
    radius = float(geometry.aabb_radius)
    if isinstance(geometry, coal.Sphere):
        points, inner = np.zeros((1, 3)), np.array([geometry.radius])
    elif isinstance(geometry, coal.Box):
        h = np.array(geometry.halfSide, dtype=np.float64)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        points = np.vstack([corners * h, np.zeros(3)])
        inner = np.concatenate([np.zeros(8), [float(h.min())]])
    elif isinstance(geometry, coal.Capsule):
        half = float(geometry.halfLength)
        points = np.array([[0.0, 0.0, -half], [0.0, 0.0, 0.0], [0.0, 0.0, half]])
        inner = np.full(3, float(geometry.radius))
    elif isinstance(geometry, coal.Cylinder):
        r, half = float(geometry.radius), float(geometry.halfLength)
        axis = [-half, half, 0.0]
        inner_list = [0.0, 0.0, min(r, half)]
        if half > r:
            axis += [-(half - r), half - r]
            inner_list += [r, r]
        points = np.array([[0.0, 0.0, z] for z in axis])
        inner = np.array(inner_list)
    else:
        vertices = np.array(geometry.points(), dtype=np.float64).reshape(-1, 3)
        if len(vertices) > MAX_PROBE_POINTS:
            vertices = vertices[np.linspace(0, len(vertices) - 1, MAX_PROBE_POINTS).astype(int)]
        points = np.vstack([vertices, vertices.mean(axis=0)])
        inner = np.zeros(len(points))
    return _Probe(geometry, centre, radius, points, inner)


# -- scene --------------------------------------------------------------------------------------


def _deepest_contact(
    geometry: Any, tf: Any, bvh: Any, d: float, witness: FloatArray
) -> tuple[float, FloatArray]:
    """``d`` (m, negative: depth) and its ``witness`` (3,), or the deepest of coal's triangle
    contacts between the placed link ``geometry`` and the triangle BVH when deeper (coal's
    distance to a triangle soup is not the deepest triangle: every one is asked)."""
    request = coal.CollisionRequest()
    request.enable_contact = True
    request.num_max_contacts = MAX_MESH_CONTACTS
    result = coal.CollisionResult()
    coal.collide(geometry, tf, bvh, _IDENTITY, request, result)
    for contact in result.getContacts():
        depth = float(contact.penetration_depth)
        if depth < d:
            d, witness = depth, np.array(contact.pos, dtype=np.float64)
    return d, witness


def _barycentric_xy(triangles: FloatArray, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Barycentric coordinates (u, w), each (n, m), of ``points`` (n, 3) in the x-y
    projections of non-vertical ``triangles`` (m, 3, 3): a point lies over or under triangle
    j when u, w >= 0 and u + w <= 1."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    dx = points[:, None, 0] - a[None, :, 0]
    dy = points[:, None, 1] - a[None, :, 1]
    u = (dx * e2[None, :, 1] - e2[None, :, 0] * dy) / det
    w = (e1[None, :, 0] * dy - dx * e1[None, :, 1]) / det
    return u, w


def _over(triangles: FloatArray, point: FloatArray) -> bool:
    """Whether ``point`` (3,) lies over or under one of the horizontal ``triangles``
    (m, 3, 3), seen from above."""
    if len(triangles) == 0:
        return False
    u, w = _barycentric_xy(triangles, np.asarray(point, dtype=np.float64).reshape(1, 3))
    return bool(np.any((u >= -1e-12) & (w >= -1e-12) & (u + w <= 1.0 + 1e-12)))


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One component of the scene: ``kind`` halfspace / convex / mesh, its coal geometry, its
    axis-aligned bounds (2, 3), whether it is a solid (inside test) and, for meshes, the
    non-vertical triangles (m, 3, 3) used by the vertical-ray parity test."""

    kind: str
    geometry: Any
    bounds: FloatArray
    solid: bool
    triangles: FloatArray
    name: str


class AuditScene:
    """The scene as collision objects (see the module docstring for the choice per component).

    ``objects`` lists them; ``signed_distance(geometry, rotation, translation)`` gives the
    depth convention of the auditor (negative: inside, the deepest object).
    """

    def __init__(self, vertices: Any, faces: Any) -> None:
        mesh = trimesh.Trimesh(
            np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64), process=False
        )
        mesh.merge_vertices()
        mesh.remove_unreferenced_vertices()
        self.mesh = mesh
        self.objects: tuple[SceneObject, ...] = tuple(self._classify(mesh))
        bounds = np.array([obj.bounds for obj in self.objects]).reshape(-1, 2, 3)
        self.lower, self.upper = bounds[:, 0], bounds[:, 1]
        self._probes: dict[int, _Probe] = {}
        self._sheets: dict[int, Any] = {}  # per ground object, its top triangles as a BVH

    @staticmethod
    def _classify(mesh: trimesh.Trimesh) -> list[SceneObject]:
        parts = mesh.split(only_watertight=False) if len(mesh.faces) else []
        lo, hi = mesh.bounds if len(mesh.faces) else (np.zeros(3), np.zeros(3))
        scene_area = max(float((hi[0] - lo[0]) * (hi[1] - lo[1])), 1e-12)
        info = []
        for part in parts:
            v = np.asarray(part.vertices, dtype=np.float64)
            flat_z = float(np.ptp(v[:, 2])) < GEOMETRY_EPS
            hull = None
            try:
                hull = ConvexHull(v)
            except (QhullError, ValueError):
                hull = None
            convex = False
            if hull is not None:
                eq = hull.equations
                centres = np.asarray(part.triangles_center, dtype=np.float64)
                on_v = np.abs((v @ eq[:, :3].T + eq[:, 3]).max(axis=1))
                on_c = np.abs((centres @ eq[:, :3].T + eq[:, 3]).max(axis=1))
                convex = bool(on_v.max() < GEOMETRY_EPS and on_c.max() < GEOMETRY_EPS)
            b = np.asarray(part.bounds, dtype=np.float64)
            cover = float((b[1, 0] - b[0, 0]) * (b[1, 1] - b[0, 1])) / scene_area
            info.append((part, v, flat_z, hull, convex, b, cover))
        ground = -1
        best = 0.0
        tops = [float(item[5][1, 2]) for item in info]
        for i, (_part, v, flat_z, hull, convex, b, cover) in enumerate(info):
            if cover < GROUND_COVER:
                continue
            top = float(b[1, 2])
            if any(t < top - GEOMETRY_EPS for j, t in enumerate(tops) if j != i):
                continue
            if not flat_z:
                if not convex or hull is None:
                    continue
                high = v[v[:, 2] > top - GEOMETRY_EPS]
                try:
                    top_area = ConvexHull(high[:, :2]).volume if len(high) >= 3 else 0.0
                except (QhullError, ValueError):
                    top_area = 0.0
                box_area = float((b[1, 0] - b[0, 0]) * (b[1, 1] - b[0, 1]))
                if top_area < 0.9 * box_area:
                    continue
            if cover > best:
                ground, best = i, cover
        objects = []
        for i, (part, v, flat_z, hull, convex, b, _cover) in enumerate(info):
            name = f"component {i}"
            if i == ground:
                top = float(b[1, 2])
                # the solid below the top, but only under the sheet's own x-y footprint: a
                # link beside the plate (over debris lying off it) is not under the ground
                bounds = np.array([[b[0, 0], b[0, 1], -np.inf], [b[1, 0], b[1, 1], top]])
                halfspace = coal.Halfspace(np.array([0.0, 0.0, 1.0]), top)
                # the scene's triangles at its top height (not the split part's, whose
                # holes trimesh fills): where the sheet has a hole (debris set into the
                # ground), nothing under the hole is inside the ground
                tris = np.asarray(mesh.triangles, dtype=np.float64)
                on_top = np.all(np.abs(tris[:, :, 2] - top) < GEOMETRY_EPS, axis=1)
                objects.append(
                    SceneObject("halfspace", halfspace, bounds, True, tris[on_top], name)
                )
            elif convex and hull is not None and not flat_z:
                geometry = _convex_from_points(v[hull.vertices])
                objects.append(SceneObject("convex", geometry, b, True, np.zeros((0, 3, 3)), name))
            else:
                faces = np.asarray(part.faces, dtype=np.int64)
                tris = v[faces]
                normal_z = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])[:, 2]
                edges = np.sort(np.asarray(part.edges, dtype=np.int64), axis=1)
                _, counts = np.unique(edges, axis=0, return_counts=True)
                uniq = np.unique(edges, axis=0)
                open_edges = uniq[counts == 1]
                low = float(b[0, 2])
                open_at_bottom = bool(
                    len(open_edges) == 0 or np.all(np.abs(v[open_edges][..., 2] - low) < 1e-6)
                )
                solid = bool(open_at_bottom and not flat_z and hull is not None)
                objects.append(
                    SceneObject(
                        "mesh",
                        _bvh(v, faces),
                        b,
                        solid,
                        tris[np.abs(normal_z) > 1e-12],
                        name,
                    )
                )
        return objects

    # -- queries ----------------------------------------------------------------------------

    def reachable(self, centres: FloatArray, radii: FloatArray) -> NDArray[np.bool_]:
        """(g, m): whether the bounding sphere (centre (g, 3), radius (g,)) of each link
        reaches the bounds of each object."""
        c = np.asarray(centres, dtype=np.float64)[:, None, :]
        nearest = np.clip(c, self.lower[None], self.upper[None])
        gap = np.sum((c - nearest) ** 2, axis=2)
        return np.asarray(gap <= np.asarray(radii, dtype=np.float64)[:, None] ** 2)

    def probe(self, geometry: Any) -> _Probe:
        key = id(geometry)
        hit = self._probes.get(key)
        if hit is None or hit.geometry is not geometry:
            hit = _probe(geometry)
            self._probes[key] = hit
        return hit

    @staticmethod
    def _inside(obj: SceneObject, points: FloatArray) -> NDArray[np.bool_]:
        """Whether each point (n, 3) is inside ``obj``: the vertical ray up from it crosses
        the (non-vertical) triangles at an odd number of distinct heights."""
        tris = obj.triangles
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(tris) == 0 or len(pts) == 0:
            return np.zeros(len(pts), dtype=bool)
        a, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
        u, w = _barycentric_xy(tris, pts)
        hit = (u >= -1e-12) & (w >= -1e-12) & (u + w <= 1.0 + 1e-12)
        z = a[None, :, 2] + u * e1[None, :, 2] + w * e2[None, :, 2]
        heights = np.where(hit & (z > pts[:, None, 2] + 1e-9), np.round(z, 6), np.inf)
        heights.sort(axis=1)
        first = np.ones((len(pts), 1), dtype=bool)
        distinct = np.isfinite(heights) & np.concatenate(
            [first, heights[:, 1:] != heights[:, :-1]], axis=1
        )
        return np.asarray(distinct.sum(axis=1) % 2 == 1)

    def object_distance(
        self, probe: _Probe, obj: SceneObject, rotation: FloatArray, translation: FloatArray
    ) -> tuple[float, FloatArray]:
        """Signed distance of a placed link to one object (negative: depth) and the witness
        point on the link (world)."""
        tf = _transform(rotation, translation)
        d, witness = _signed_distance(probe.geometry, tf, obj.geometry, _IDENTITY)
        if obj.kind == "halfspace" and d < 0.0 and not _over(obj.triangles, witness):
            # the deepest point lies under a hole of the ground sheet: the link is measured
            # against the sheet's own triangles there (it may still cross the hole's rim)
            d, witness = self._sheet_distance(probe, obj, tf)
        if obj.kind == "mesh" and d <= 0.0:
            d, witness = _deepest_contact(probe.geometry, tf, obj.geometry, d, witness)
        if obj.kind == "mesh" and obj.solid:
            world = probe.points @ rotation.T + translation
            box = obj.bounds
            near = np.all((world >= box[0] - 1e-9) & (world <= box[1] + 1e-9), axis=1)
            if near.any():
                idx = np.flatnonzero(near)
                inside = self._inside(obj, world[idx])
                for k in idx[inside]:
                    surface, _ = _signed_distance(
                        _POINT, _transform(np.eye(3), world[k]), obj.geometry, _IDENTITY
                    )
                    depth = max(surface, 0.0) + float(probe.inner[k])
                    if -depth < d:
                        d, witness = -depth, world[k]
        return d, witness

    def _sheet_distance(self, probe: _Probe, obj: SceneObject, tf: Any) -> tuple[float, FloatArray]:
        """Signed distance (negative: depth) of a placed link to the top triangles of the
        ground ``obj`` alone and its witness on the link: the deepest of coal's triangle
        contacts, else the distance to the triangles."""
        sheet = self._sheets.get(id(obj))
        if sheet is None:
            tris = obj.triangles
            faces = np.arange(3 * len(tris), dtype=np.int64).reshape(-1, 3)
            sheet = _bvh(tris.reshape(-1, 3), faces)
            self._sheets[id(obj)] = sheet
        d, witness = _signed_distance(probe.geometry, tf, sheet, _IDENTITY)
        return _deepest_contact(probe.geometry, tf, sheet, d, witness)

    def signed_distance(
        self, geometry: Any, rotation: Any = None, translation: Any = None
    ) -> tuple[float, int]:
        """The smallest signed distance of a coal geometry placed at (rotation (3, 3),
        translation (3,)) to the scene objects whose bounds it may reach (inf if none), and
        the index of that object (-1 if none)."""
        rot = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        pos = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        probe = self.probe(geometry)
        centre = rot @ probe.centre + pos
        best, which = math.inf, -1
        hits = self.reachable(centre[None], np.array([probe.radius]))[0]
        for i in np.flatnonzero(hits):
            d, _ = self.object_distance(probe, self.objects[i], rot, pos)
            if d < best:
                best, which = d, i
        return best, which


def scene_key(vertices: Any, faces: Any) -> str:
    """Content hash of a mesh (the auditor's scene cache key)."""
    digest = hashlib.sha1()
    digest.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    return digest.hexdigest()


_SCENES: dict[str, AuditScene] = {}


def audit_scene(mesh: Any) -> AuditScene:
    """An ``AuditScene`` (cached by content) from a trimesh, a ``(vertices, faces)`` pair, an
    object with ``vertices`` and ``faces`` (a planner scene) or mesh file bytes (STL, GLB)."""
    if isinstance(mesh, AuditScene):
        return mesh
    if isinstance(mesh, bytes | bytearray):
        kind = "glb" if bytes(mesh[:4]) == b"glTF" else "stl"
        loaded = trimesh.load(trimesh.util.wrap_as_stream(bytes(mesh)), file_type=kind)
        if isinstance(loaded, trimesh.Scene):
            loaded = loaded.to_geometry()
        mesh = loaded
    if isinstance(mesh, tuple | list):
        vertices, faces = mesh
    else:
        vertices, faces = mesh.vertices, mesh.faces
    key = scene_key(vertices, faces)
    if key not in _SCENES:
        _SCENES[key] = AuditScene(vertices, faces)
    return _SCENES[key]


# -- character ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class LimbDef:
    """A limb as the spec defines it: effector frame, contact kind (``point`` / ``patch``),
    its contact points (k, 3) in the effector frame (a point: the frame origin, the centre of
    its ball; a patch: 4 corners) and the radius of a point contact's ball (0 for a patch)."""

    name: str
    effector_frame: str
    contact: str
    points: FloatArray
    radius: float = 0.0


def limb_points(contact: str, half_size: Sequence[float], offset: Sequence[float]) -> FloatArray:
    """Contact points (k, 3) in the effector frame: the origin (ball centre) for a point, the
    corners ``offset + (+-hx, +-hy, 0)`` in the order (+,+), (+,-), (-,-), (-,+) for a patch."""
    off = np.asarray(offset, dtype=np.float64)
    if contact == "point":
        return np.zeros((1, 3))
    hx, hy = float(half_size[0]), float(half_size[1])
    corners = np.array([[hx, hy, 0.0], [hx, -hy, 0.0], [-hx, -hy, 0.0], [-hx, hy, 0.0]])
    return np.asarray(corners + off, dtype=np.float64)


def _erd_share() -> Path | None:
    """The ``share`` directory of the installed example-robot-data (URDF package dir)."""
    try:
        files = importlib.metadata.files("example-robot-data") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        parts = Path(str(f)).parts
        if "share" in parts and "example-robot-data" in parts:
            located = Path(str(f.locate())).resolve()
            up = len(parts) - parts.index("share") - 1
            return located.parents[up - 1]
    return None


_MESH_COLLISION = re.compile(
    r"<collision\b[^>]*>(?:(?!</collision>).)*?<mesh\b.*?</collision>", re.S
)


class AuditCharacter:
    """A character for the auditor: Pinocchio model and collision geometry from the URDF.

    ``model``, ``geometry`` (pin.GeometryModel, mesh links as convex hulls), ``limbs`` by name,
    ``joint_names`` (actuated, configuration order), ``q_reference`` (spec posture, root at the
    origin), ``self_pairs`` (collision object index pairs checked), ``notes``.
    """

    def __init__(
        self,
        urdf_text: str,
        limbs: Iterable[LimbDef],
        reference_posture: Mapping[str, float] | Iterable[tuple[str, float]] = (),
        package_dirs: Sequence[str] | None = None,
        name: str = "",
    ) -> None:
        self.name = name
        self.notes: list[str] = []
        self.model = pin.buildModelFromXML(urdf_text, pin.JointModelFreeFlyer())
        dirs = list(package_dirs) if package_dirs is not None else []
        share = _erd_share()
        if share is not None and str(share) not in dirs:
            dirs.append(str(share))
        try:
            geometry = pin.buildGeomFromUrdfString(
                self.model, urdf_text, pin.COLLISION, package_dirs=dirs
            )
        except Exception as exc:  # meshes not found: keep the primitive shapes
            stripped = _MESH_COLLISION.sub("", urdf_text)
            geometry = pin.buildGeomFromUrdfString(
                self.model, stripped, pin.COLLISION, package_dirs=dirs
            )
            self.notes.append(f"mesh collision links skipped ({exc.__class__.__name__}: {exc})")
        for obj in geometry.geometryObjects:
            if isinstance(obj.geometry, coal.BVHModelBase):
                obj.geometry.buildConvexHull(False, "Qt")
                obj.geometry = obj.geometry.convex
        self.geometry = geometry
        self.data = self.model.createData()
        self.geometry_data = pin.GeometryData(geometry)
        self.limbs = {limb.name: limb for limb in limbs}
        self.joint_names = tuple(str(n) for n in self.model.names[2:])
        self.object_names = tuple(str(o.name) for o in geometry.geometryObjects)
        self.object_joints = np.array([o.parentJoint for o in geometry.geometryObjects], dtype=int)
        self.link_names = tuple(
            str(self.model.frames[o.parentFrame].name)
            if o.parentFrame < len(self.model.frames)
            else str(o.name)
            for o in geometry.geometryObjects
        )
        self.frame_ids = {}
        self.stance_objects: dict[str, frozenset[int]] = {}
        for limb in self.limbs.values():
            if not self.model.existFrame(limb.effector_frame):
                self.notes.append(f"limb {limb.name}: no frame {limb.effector_frame!r}")
                continue
            fid = self.model.getFrameId(limb.effector_frame)
            self.frame_ids[limb.name] = fid
            joint = int(self.model.frames[fid].parentJoint)
            subtree = {int(j) for j in self.model.subtrees[joint]}
            self.stance_objects[limb.name] = frozenset(
                i for i, j in enumerate(self.object_joints) if int(j) in subtree
            )
        # the trunk: the joints where the limbs' chains branch (effectors in two child
        # subtrees or more) and those between them and the root (a humanoid's pelvis and
        # chest, a quadruped's body alone; not a thigh that carries a seat and a foot)
        branches: dict[int, set[int]] = {}
        for fid in self.frame_ids.values():
            child = int(self.model.frames[fid].parentJoint)
            while child > 0:
                parent = int(self.model.parents[child])
                branches.setdefault(parent, set()).add(child)
                child = parent
        trunk: set[int] = set()
        for j, children in branches.items():
            if len(children) < 2:
                continue
            while j > 0 and j not in trunk:  # the branch point and its ancestors
                trunk.add(j)
                j = int(self.model.parents[j])
        self.trunk_joints = tuple(sorted(trunk))
        self.velocity_limit = np.array(self.model.velocityLimit, dtype=np.float64)
        posture = dict(reference_posture)
        q = np.array(pin.neutral(self.model), dtype=np.float64)
        for j in range(2, self.model.njoints):
            jname = str(self.model.names[j])
            if jname in posture and self.model.joints[j].nq == 1:
                q[self.model.joints[j].idx_q] = float(posture[jname])
        self.q_reference = q
        # each trunk body's up direction in its own frame: the world's z axis at the reference
        # posture (upright, root level), against which its tilt is measured
        pin.forwardKinematics(self.model, self.data, q)
        self.trunk_up = tuple(
            np.array(self.data.oMi[j].rotation[2, :], dtype=np.float64) for j in self.trunk_joints
        )
        self.self_pairs = self._self_pairs()

    def _shape_ancestor(self, joint: int) -> int:
        carriers = {int(j) for j in self.object_joints}
        j = int(self.model.parents[joint])
        while j > 0 and j not in carriers:
            j = int(self.model.parents[j])
        return j

    def _self_pairs(self) -> list[tuple[int, int]]:
        self.place(self.q_reference)
        n = len(self.object_names)
        pairs = []
        for i in range(n):
            for k in range(i + 1, n):
                ji, jk = int(self.object_joints[i]), int(self.object_joints[k])
                if ji == jk or self._shape_ancestor(ji) == jk or self._shape_ancestor(jk) == ji:
                    continue
                if self.pair_distance(i, k) < REFERENCE_OVERLAP_M:
                    continue
                pairs.append((i, k))
        return pairs

    # -- kinematics -------------------------------------------------------------------------

    def place(self, q: FloatArray) -> FloatArray:
        """Forward kinematics of q (quaternion normalised): frames and collision objects
        placed; returns the COM (3,)."""
        com = pin.centerOfMass(self.model, self.data, q, False)
        pin.updateFramePlacements(self.model, self.data)
        pin.updateGeometryPlacements(self.model, self.data, self.geometry, self.geometry_data)
        return np.array(com, dtype=np.float64)

    def object_pose(self, i: int) -> tuple[FloatArray, FloatArray]:
        m = self.geometry_data.oMg[i]
        return np.array(m.rotation), np.array(m.translation)

    def pair_distance(self, i: int, k: int) -> float:
        ri, pi = self.object_pose(i)
        rk, pk = self.object_pose(k)
        d, _ = _signed_distance(
            self.geometry.geometryObjects[i].geometry,
            _transform(ri, pi),
            self.geometry.geometryObjects[k].geometry,
            _transform(rk, pk),
        )
        return d

    def contact_points(self, limb: str, normal: Any = None) -> FloatArray | None:
        """World contact points (k, 3) of a limb at the current placement on a surface of
        ``normal`` (a point contact: its ball's centre when the normal is None); None for an
        unknown limb."""
        fid = self.frame_ids.get(limb)
        if fid is None:
            return None
        m = self.data.oMf[fid]
        spec = self.limbs[limb]
        points = spec.points @ np.array(m.rotation).T + np.array(m.translation)
        if spec.contact == "point" and normal is not None:
            points = points - spec.radius * np.asarray(normal, dtype=np.float64)
        return np.asarray(points)

    def stance_error(self, limb: str, target: PhaseContact) -> float | None:
        """Largest distance (m) of the limb's contact points from a phase contact's (None:
        unknown limb). Point contact without a normal: the ball's distance from the point;
        different point counts: the distance of the centroids."""
        spec = self.limbs.get(limb)
        here = self.contact_points(limb, target.normal)
        if spec is None or here is None:
            return None
        goal = np.asarray(target.points, dtype=np.float64).reshape(-1, 3)
        if spec.contact == "point" and target.normal is None:
            gap = np.linalg.norm(goal - here[0], axis=1) - spec.radius
            return float(np.abs(gap).max())
        if len(here) == len(goal):
            return float(np.linalg.norm(here - goal, axis=1).max())
        return float(np.linalg.norm(here.mean(axis=0) - goal.mean(axis=0)))

    def q_from_pose(
        self,
        position: Sequence[float],
        orientation: Sequence[float],
        joints: Mapping[str, float],
    ) -> FloatArray:
        """q from a root position, orientation [x, y, z, w] and joints by name (missing
        joints: the reference posture)."""
        q = np.array(self.q_reference, dtype=np.float64)
        q[:3] = position
        q[3:7] = orientation
        for j in range(2, self.model.njoints):
            jname = str(self.model.names[j])
            if jname in joints and self.model.joints[j].nq == 1:
                q[self.model.joints[j].idx_q] = float(joints[jname])
        return q


@cache
def audit_character(character_id: str) -> AuditCharacter:
    """The auditor's model of a Gecko character: its URDF text and limb spec only."""
    from planner.character import get_character  # URDF text and limb spec, nothing else

    character = get_character(character_id)
    spec = character.spec
    limbs = [
        LimbDef(
            limb.name,
            limb.effector_frame,
            limb.contact,
            limb_points(limb.contact, limb.half_size, limb.offset),
            float(np.linalg.norm(limb.offset)) if limb.contact == "point" else 0.0,
        )
        for limb in spec.limbs
    ]
    return AuditCharacter(character.urdf_text, limbs, spec.reference_posture, name=character_id)


# -- curves -------------------------------------------------------------------------------------


def bezier_point(control_points: Any, s: float) -> FloatArray:
    """De Casteljau evaluation of a Bezier curve (d + 1, 3) at s in [0, 1]."""
    pts = np.array(control_points, dtype=np.float64)
    while len(pts) > 1:
        pts = (1.0 - s) * pts[:-1] + s * pts[1:]
    return np.asarray(pts[0])


def com_curve_at(pieces: Sequence[ComPiece], t: float) -> FloatArray | None:
    """The COM curve at time t (the first piece whose [t0, t1] holds t), None if none."""
    for piece in pieces:
        t0, t1 = float(piece.t0), float(piece.t1)
        if t0 - TIME_EPS <= t <= t1 + TIME_EPS:
            s = 0.0 if t1 - t0 <= TIME_EPS else min(1.0, max(0.0, (t - t0) / (t1 - t0)))
            return bezier_point(piece.control_points, s)
    return None


def flights_from_contacts(keyframes: Iterable[Any]) -> list[tuple[float, float]]:
    """Flight intervals of a motion (keyframes as ``Frame`` or (t, q, contacts)): from the
    last keyframe with contacts before a run of keyframes without any to the first keyframe
    with contacts after it."""
    frames = _as_frames(keyframes)
    out = []
    k = 0
    n = len(frames)
    while k < n:
        if frames[k].contacts:
            k += 1
            continue
        start = k
        while k < n and not frames[k].contacts:
            k += 1
        t0 = float(frames[start - 1].t if start > 0 else frames[start].t)
        t1 = float(frames[k].t if k < n else frames[n - 1].t)
        out.append((t0, t1))
    return out


# -- the audit ----------------------------------------------------------------------------------


def _as_frames(keyframes: Iterable[Any]) -> list[Frame]:
    frames = []
    for item in keyframes:
        t, q, contacts = item
        frames.append(Frame(float(t), np.array(q, dtype=np.float64), tuple(contacts)))
    return frames


def _as_contact(item: Any) -> PhaseContact:
    limb, points, *rest = item
    normal = rest[0] if rest else None
    return PhaseContact(
        str(limb),
        np.asarray(points, dtype=np.float64).reshape(-1, 3),
        None if normal is None else np.asarray(normal, dtype=np.float64).reshape(3),
    )


def _as_phases(phases: Iterable[Any]) -> list[PhaseData]:
    out = []
    for t0, t1, contacts in phases:
        items = contacts.items() if isinstance(contacts, Mapping) else contacts
        out.append(PhaseData(float(t0), float(t1), tuple(_as_contact(c) for c in items)))
    return out


def audit_motion(
    character: AuditCharacter,
    scene: AuditScene,
    keyframes: Iterable[Any],
    phases: Iterable[Any] = (),
    com: Iterable[Any] = (),
    flights: Iterable[tuple[float, float]] = (),
) -> MotionAudit:
    """Audit a motion given as plain data.

    keyframes : (t, q (nq,), contact limb names) each, in time order. phases : (t0, t1,
    contacts) with contacts (limb, world points (k, 3)[, normal (3,)]) or a mapping. com : (t0, t1,
    control points (d + 1, 3)) Bezier pieces. flights : (t0, t1) intervals in which root
    jumps are not counted.
    """
    frames = _as_frames(keyframes)
    phase_list = _as_phases(phases)
    pieces = [ComPiece(float(a), float(b), np.asarray(c, dtype=np.float64)) for a, b, c in com]
    flight_list = [(float(a), float(b)) for a, b in flights]
    n = len(frames)
    notes = list(character.notes)
    geoms = character.geometry.geometryObjects
    probes = [scene.probe(o.geometry) for o in geoms]
    radii = np.array([pr.radius for pr in probes], dtype=np.float64)
    pair_a = np.array([a for a, _ in character.self_pairs], dtype=int)
    pair_b = np.array([b for _, b in character.self_pairs], dtype=int)
    times = np.array([f.t for f in frames], dtype=np.float64)
    penetration = np.zeros(n)
    pen_links = ["" for _ in range(n)]
    stance_error = np.full(n, np.nan)
    self_pen = np.zeros(n)
    com_error = np.full(n, np.nan)
    tilt = np.zeros(n)
    trunk_tilt = np.zeros(n)
    coms = np.zeros((n, 3))
    roots = np.zeros((n, 3))
    stance_pen_frames = 0
    worst_self, worst_self_pair = 0.0, ""
    unknown: set[str] = set()
    for k, frame in enumerate(frames):
        q = np.array(frame.q, dtype=np.float64)
        norm = float(np.linalg.norm(q[3:7]))
        q[3:7] = q[3:7] / norm if norm > 0 else np.array([0.0, 0.0, 0.0, 1.0])
        coms[k] = character.place(q)
        roots[k] = q[:3]
        rotation = np.array(pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix())
        tilt[k] = math.degrees(math.acos(min(1.0, max(-1.0, float(rotation[2, 2])))))
        upright = min(  # the joint placements of ``place(q)`` above
            (
                float(character.data.oMi[j].rotation[2, :] @ up)
                for j, up in zip(character.trunk_joints, character.trunk_up, strict=True)
            ),
            default=float(rotation[2, 2]),
        )
        trunk_tilt[k] = math.degrees(math.acos(min(1.0, max(-1.0, upright))))
        stance: set[int] = set()
        for limb in frame.contacts:
            if limb in character.stance_objects:
                stance |= character.stance_objects[limb]
            else:
                unknown.add(limb)
        covering = [p for p in phase_list if p.t0 - TIME_EPS <= frame.t <= p.t1 + TIME_EPS]
        # stance contact error
        errors = []
        targets: dict[str, list[FloatArray]] = {}
        for limb in frame.contacts:
            options = [c for p in covering for c in p.contacts if c.limb == limb]
            targets[limb] = [c.points for c in options]
            found = [e for c in options if (e := character.stance_error(limb, c)) is not None]
            if found:
                errors.append(min(found))
        if errors:
            stance_error[k] = max(errors)
        # scene penetration
        poses = [character.object_pose(i) for i in range(len(geoms))]
        centres = np.array([r @ pr.centre + p for (r, p), pr in zip(poses, probes, strict=True)])
        reach = scene.reachable(centres.reshape(-1, 3), radii)
        worst, worst_name, stance_far = 0.0, "", False
        for i, j in zip(*np.nonzero(reach), strict=True):
            probe, obj = probes[i], scene.objects[j]
            rot, pos = poses[i]
            d, witness = scene.object_distance(probe, obj, rot, pos)
            depth = -d
            if i in stance:
                if depth > PENETRATION_TOL_M and not _near_contact(
                    witness, frame.contacts, character, targets
                ):
                    stance_far = True
                continue
            if depth > worst:
                worst, worst_name = depth, character.link_names[i]
        penetration[k] = worst
        pen_links[k] = worst_name
        stance_pen_frames += stance_far
        # self-collision
        deepest = 0.0
        if len(pair_a):
            gaps = np.linalg.norm(centres[pair_a] - centres[pair_b], axis=1)
            close = np.flatnonzero(gaps < radii[pair_a] + radii[pair_b])
        else:
            close = np.zeros(0, dtype=int)
        for m in close:
            i, j = int(pair_a[m]), int(pair_b[m])
            depth = -character.pair_distance(i, j)
            if depth > deepest:
                deepest = depth
                if depth > worst_self:
                    worst_self = depth
                    worst_self_pair = f"{character.link_names[i]}/{character.link_names[j]}"
        self_pen[k] = deepest
        # COM
        target = com_curve_at(pieces, frame.t)
        if target is not None:
            com_error[k] = float(np.linalg.norm(coms[k] - target))
    if unknown:
        notes.append(f"unknown limbs in keyframe contacts: {sorted(unknown)}")
    # pairs: joint speeds, root steps
    pairs = max(0, n - 1)
    joint_speed = np.zeros(pairs)
    root_step = np.zeros(pairs)
    dts = np.diff(times) if n > 1 else np.zeros(0)
    limit = np.minimum(
        MAX_JOINT_SPEED, np.where(character.velocity_limit > 0, character.velocity_limit, np.inf)
    )[6:]
    pops = 0
    root_jumps = 0
    max_speed, max_joint = 0.0, ""
    vnames = _velocity_names(character)
    for k in range(pairs):
        q0 = _normalised(frames[k].q)
        q1 = _normalised(frames[k + 1].q)
        dq = np.abs(np.array(pin.difference(character.model, q0, q1))[6:])
        dt = float(dts[k])
        speed = dq / dt if dt > TIME_EPS else np.where(dq > 1e-09, np.inf, 0.0)
        top = int(np.argmax(speed)) if len(speed) else 0
        joint_speed[k] = float(speed[top]) if len(speed) else 0.0
        if joint_speed[k] > max_speed:
            max_speed, max_joint = joint_speed[k], vnames[top]
        pops += bool(np.any(speed > limit * (1.0 + 1e-9)))
        root_step[k] = float(np.linalg.norm(roots[k + 1] - roots[k]))
        in_flight = any(
            times[k] < f1 - TIME_EPS and times[k + 1] > f0 + TIME_EPS for f0, f1 in flight_list
        )
        allowed = ROOT_JUMP_M * max(1.0, dt * ROOT_JUMP_RATE_HZ)
        if not in_flight and root_step[k] > allowed:
            root_jumps += 1
    # COM stillness (central differences of the keyframe COM)
    still = math.nan
    if n >= 2:
        speeds = np.zeros(n)
        for k in range(n):
            a, b = max(0, k - 1), min(n - 1, k + 1)
            span = times[b] - times[a]
            dist = float(np.linalg.norm(coms[b] - coms[a]))
            speeds[k] = dist / span if span > TIME_EPS else (0.0 if dist < 1e-9 else math.inf)
        still = float(np.mean(speeds < STILL_COM_SPEED))
    animated = sum(
        1 for p in phase_list if np.any((times >= p.t0 - TIME_EPS) & (times <= p.t1 + TIME_EPS))
    )
    valid_com = com_error[np.isfinite(com_error)]
    duration = float(times[-1] - times[0]) if n >= 2 else 0.0
    worst_frame = int(np.argmax(penetration)) if n else -1
    median_dt = float(np.median(dts)) if len(dts) else math.nan
    return MotionAudit(
        frames=n,
        pairs=pairs,
        penetrating_frames=int(np.sum(penetration > PENETRATION_TOL_M)),
        worst_penetration_m=float(penetration.max()) if n else 0.0,
        worst_penetration_link=pen_links[worst_frame] if n else "",
        worst_penetration_frame=worst_frame,
        stance_penetrating_frames=int(stance_pen_frames),
        stance_contact_error_m=float(np.nanmax(stance_error))
        if np.isfinite(stance_error).any()
        else math.nan,
        self_collision_frames=int(np.sum(self_pen > SELF_COLLISION_TOL_M)),
        worst_self_collision_m=float(worst_self),
        worst_self_collision_pair=worst_self_pair,
        pops=int(pops),
        max_joint_speed=float(max_speed),
        max_speed_joint=max_joint,
        root_jumps=int(root_jumps),
        max_root_step_m=float(root_step.max()) if pairs else 0.0,
        com_error_p99_m=float(np.percentile(valid_com, 99)) if len(valid_com) else math.nan,
        com_error_max_m=float(valid_com.max()) if len(valid_com) else math.nan,
        tilt_max_deg=float(tilt.max()) if n else math.nan,
        trunk_tilt_max_deg=float(trunk_tilt.max()) if n else math.nan,
        phases=len(phase_list),
        phases_animated=int(animated),
        coverage=animated / len(phase_list) if phase_list else math.nan,
        min_spacing_s=float(dts.min()) if len(dts) else math.nan,
        close_pairs=int(np.sum(dts < CLOSE_SPACING * median_dt)) if len(dts) else 0,
        duration_s=duration,
        pace_m_per_s=float(np.linalg.norm(roots[-1] - roots[0]) / duration)
        if duration > 0
        else math.nan,
        still_com_fraction=still,
        times=times,
        penetration=penetration,
        penetration_links=tuple(pen_links),
        stance_error=stance_error,
        self_penetration=self_pen,
        com_error=com_error,
        tilt_deg=tilt,
        joint_speed=joint_speed,
        root_step=root_step,
        notes=tuple(notes),
        coms=coms,
    )


def _normalised(q: Any) -> FloatArray:
    out = np.array(q, dtype=np.float64)
    norm = float(np.linalg.norm(out[3:7]))
    if norm > 0:
        out[3:7] /= norm
    return out


def _velocity_names(character: AuditCharacter) -> list[str]:
    """Joint name per velocity index after the free flyer."""
    names = [""] * (character.model.nv - 6)
    for j in range(2, character.model.njoints):
        joint = character.model.joints[j]
        for i in range(joint.idx_v, joint.idx_v + joint.nv):
            names[i - 6] = str(character.model.names[j])
    return names


def _near_contact(
    witness: FloatArray,
    limbs: Sequence[str],
    character: AuditCharacter,
    targets: Mapping[str, list[FloatArray]],
) -> bool:
    """Whether a stance link's deepest point lies within ``STANCE_NEAR_M`` (plus the patch's
    half-diagonal or the ball's radius) of a phase contact point of one of the frame's
    stance limbs; True when no phase gives the limbs' contacts (nothing to check against)."""
    known = False
    for limb in limbs:
        spec = character.limbs.get(limb)
        if spec is None:
            continue
        reach = STANCE_NEAR_M + spec.radius
        if len(spec.points) > 1:
            reach += float(np.linalg.norm(spec.points - spec.points.mean(axis=0), axis=1).max())
        for pts in targets.get(limb, []):
            known = True
            if np.min(np.linalg.norm(pts - witness, axis=1)) <= reach:
                return True
    return not known


# -- adapters -----------------------------------------------------------------------------------


def _resolve_character(character: AuditCharacter | str) -> AuditCharacter:
    return character if isinstance(character, AuditCharacter) else audit_character(character)


def audit_from_domain(
    character: AuditCharacter | str,
    scene: Any,
    keyframes: Iterable[Any],
    phases: Iterable[Any] = (),
    com: Iterable[Any] = (),
    flights: Iterable[tuple[float, float]] = (),
) -> MotionAudit:
    """Audit the planner's own objects, reading their attributes only: keyframes with ``t``,
    ``q``, ``contacts``; phases with ``t0``, ``t1``, ``contacts`` (each with ``limb``,
    ``points`` and, if it has one, ``normal``); COM segments with ``t0``, ``t1``,
    ``control_points``. ``character``: an ``AuditCharacter`` or a character id; ``scene``:
    anything ``audit_scene`` accepts."""
    frames = [(k.t, k.q, tuple(k.contacts)) for k in keyframes]
    phase_data = [
        (
            p.t0,
            p.t1,
            tuple((c.limb, np.asarray(c.points), getattr(c, "normal", None)) for c in p.contacts),
        )
        for p in phases
    ]
    pieces = [(s.t0, s.t1, np.asarray(s.control_points)) for s in com]
    return audit_motion(
        _resolve_character(character), audit_scene(scene), frames, phase_data, pieces, flights
    )


def frames_from_json(
    character: AuditCharacter, keyframes: Iterable[Mapping[str, Any]]
) -> list[Frame]:
    """Keyframes of an HTTP answer (``t``, ``root`` {position, orientation}, ``joints`` by
    name, ``contacts``) as ``Frame``s."""
    out = []
    for key in keyframes:
        root = key["root"]
        q = character.q_from_pose(
            root["position"], root.get("orientation", (0.0, 0.0, 0.0, 1.0)), key["joints"]
        )
        out.append(Frame(float(key["t"]), q, tuple(key.get("contacts", ()))))
    return out


def audit_from_json(
    response: Mapping[str, Any],
    character_id: str | AuditCharacter,
    scene_mesh: Any,
    flights: Iterable[tuple[float, float]] | None = None,
) -> MotionAudit:
    """Audit an HTTP answer (plan, Twister step or jumps): its ``keyframes``, ``phases`` and
    ``com`` lists. Flights: as given, else, for a jump answer (``jumps``), the runs of
    keyframes without contacts."""
    character = _resolve_character(character_id)
    frames = frames_from_json(character, response.get("keyframes", []))
    phases = [
        (
            p["t0"],
            p["t1"],
            tuple((c["limb"], c["points"], c.get("normal")) for c in p["contacts"]),
        )
        for p in response.get("phases", [])
    ]
    pieces = [
        (s["t0"], s["t1"], np.asarray(s["control_points"], dtype=np.float64))
        for s in response.get("com", [])
    ]
    if flights is None:
        flights = flights_from_contacts(frames) if "jumps" in response else []
    return audit_motion(character, audit_scene(scene_mesh), frames, phases, pieces, flights)
