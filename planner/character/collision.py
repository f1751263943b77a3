"""Self-collision of a character: geometry model construction and a batched checker.

The checker works on joint placements from :mod:`planner.character.batch_fk`: a numpy broad
phase on bounding spheres discards most (sample, pair) combinations, and coal decides the rest
exactly (``coal.collide``), stopping at the first collision of each sample.
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

from planner.character.batch_fk import TreeKinematics, joint_placements
from planner.shapes import Box, Capsule

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

MIN_SEGMENT = 0.01
"""Shortest link segment (m) that gets a capsule in ``capsules`` mode."""


def capsule_geometry_model(model: Any, radius: float) -> Any:
    """Per-link capsule approximation: for each joint, one capsule of ``radius`` from its origin
    to each child joint origin, and one toward its farthest attached frame when the joint is a
    leaf (a sole, a foot point) or that frame lies beyond every child joint (Talos' fingertips,
    past the gripper joint). Toward a frame, the axis stops ``radius`` short of it, so the
    capsule's surface, not its axis, ends there. Segments shorter than :data:`MIN_SEGMENT` are
    skipped. Used for robots whose URDF collision elements are meshes (loading and checking
    those is slow)."""
    gmodel = pin.GeometryModel()
    children: dict[int, list[FloatArray]] = {j: [] for j in range(1, model.njoints)}
    for j in range(2, model.njoints):
        children[int(model.parents[j])].append(np.array(model.jointPlacements[j].translation))
    farthest: dict[int, FloatArray] = {}
    for frame in model.frames:
        j, end = int(frame.parentJoint), np.array(frame.placement.translation)
        if j >= 2 and np.linalg.norm(end) > np.linalg.norm(farthest.get(j, np.zeros(3))):
            farthest[j] = end
    for j in range(1, model.njoints):
        ends = list(children[j])
        tip = farthest.get(j)
        if tip is not None:
            reach = float(np.linalg.norm(tip))
            beyond = max((float(np.linalg.norm(e)) for e in ends), default=0.0)
            if (not ends and reach > radius) or (ends and reach - radius > beyond + MIN_SEGMENT):
                ends.append(tip * (reach - radius) / reach)
        for k, end in enumerate(ends):
            length = float(np.linalg.norm(end))
            if length < MIN_SEGMENT:
                continue
            z = end / length
            helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            x = np.cross(helper, z)
            x /= np.linalg.norm(x)
            rot = np.column_stack([x, np.cross(z, x), z])
            placement = pin.SE3(rot, end / 2.0)
            shape = coal.Capsule(radius, length)
            gmodel.addGeometryObject(
                pin.GeometryObject(f"{model.names[j]}_capsule_{k}", j, placement, shape)
            )
    return gmodel


def hull_geometry_model(model: Any, urdf_text: str, package_dirs: Sequence[str]) -> Any:
    """The URDF's own collision geometry (``<collision>`` elements), each mesh element
    replaced by its convex hull (``coal.Convex``, Qhull): the body as it is, for the
    whole-body motion (``Character.motion_geometry``). Primitive elements (boxes, cylinders,
    spheres) stay as they are. Meshes are looked up under ``package_dirs``; raises whatever
    Pinocchio raises when one cannot be read."""
    gmodel = pin.buildGeomFromUrdfString(
        model, urdf_text, pin.GeometryType.COLLISION, package_dirs=list(package_dirs)
    )
    for obj in gmodel.geometryObjects:
        if isinstance(obj.geometry, coal.BVHModelBase):
            obj.geometry.buildConvexHull(False, "Qt")
            obj.geometry = obj.geometry.convex
    return gmodel


PLATE_THICKNESS = 0.03
"""m, thickness of the box standing on a patch effector's contact area in ``capsules`` mode."""


def add_contact_plates(
    model: Any, gmodel: Any, patches: list[tuple[int, FloatArray, FloatArray, FloatArray]]
) -> None:
    """Add to ``gmodel`` one box per patch effector: its contact area (a sole, a palm)
    extruded :data:`PLATE_THICKNESS` m along the contact normal, into the body. A capsule
    chain cannot cover a sole's toe and heel. ``patches``: (effector frame id, half sizes
    (2,) m along the frame's x and y, normal (3,) unit, contact centre (3,) m), in the
    effector frame."""
    for frame_id, half_size, normal, offset in patches:
        frame = model.frames[frame_id]
        z = np.asarray(normal, dtype=np.float64)
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        if np.linalg.norm(x) < 1e-6:
            x = np.array([0.0, 1.0, 0.0]) - z[1] * z
        x /= np.linalg.norm(x)
        local = pin.SE3(np.column_stack([x, np.cross(z, x), z]), offset + z * PLATE_THICKNESS / 2)
        shape = coal.Box(2.0 * half_size[0], 2.0 * half_size[1], PLATE_THICKNESS)
        gmodel.addGeometryObject(
            pin.GeometryObject(
                f"{frame.name}_plate", int(frame.parentJoint), frame.placement * local, shape
            )
        )


def add_trunk_shapes(gmodel: Any, shapes: Sequence[Box | Capsule]) -> None:
    """Add the spec's trunk volumes (boxes and capsules, posed in the root frame) to ``gmodel``
    on the root joint, named ``trunk_<k>``: in ``capsules`` mode the capsules from the root to
    the hips leave the body's bulk empty, and a trunk inside the scene would go unseen between
    states. They are for the scene only (see :func:`drop_trunk_pairs`): a torso that turns on
    its own joints (Talos) would read as hitting its arms."""
    for k, shape in enumerate(shapes):
        if isinstance(shape, Box):
            geometry = coal.Box(*(2.0 * np.asarray(shape.half_extents)))
        else:
            geometry = coal.Capsule(shape.radius, 2.0 * shape.half_length)
        offset = np.asarray(shape.offset)
        gmodel.addGeometryObject(
            pin.GeometryObject(f"trunk_{k}", 1, pin.SE3(offset[:3, :3], offset[:3, 3]), geometry)
        )


def drop_trunk_pairs(gmodel: Any) -> None:
    """Remove the collision pairs of the shapes added by :func:`add_trunk_shapes`."""
    names = [str(obj.name) for obj in gmodel.geometryObjects]
    for pair in list(gmodel.collisionPairs):
        if names[pair.first].startswith("trunk_") or names[pair.second].startswith("trunk_"):
            gmodel.removeCollisionPair(pair)


def _geometric_parents(model: Any, joints_with_geometry: set[int]) -> dict[int, int]:
    """Nearest ancestor of each joint that carries geometry (0 if none)."""
    out = {}
    for j in range(1, model.njoints):
        k = int(model.parents[j])
        while k > 0 and k not in joints_with_geometry:
            k = int(model.parents[k])
        out[j] = k
    return out


def _bounding_capsule(geom: Any) -> tuple[FloatArray, FloatArray, float, FloatArray | None]:
    """Capsule (end a, end b, radius) containing the shape, in the shape's frame, and the box
    half extents when the shape is (or is bounded by) a box, else None."""
    if isinstance(geom, coal.Sphere):
        zero = np.zeros(3)
        return zero, zero, float(geom.radius), None
    if isinstance(geom, coal.Capsule | coal.Cylinder):
        h = np.array([0.0, 0.0, float(geom.halfLength)])
        return -h, h, float(geom.radius), None
    if isinstance(geom, coal.Box):
        lo, hi = -np.array(geom.halfSide), np.array(geom.halfSide)
        center = np.zeros(3)
    else:  # meshes and other shapes: their local AABB
        lo, hi = np.array(geom.aabb_local.min_), np.array(geom.aabb_local.max_)
        center = (lo + hi) / 2.0
    half = (hi - lo) / 2.0
    k = int(np.argmax(half))
    axis = np.zeros(3)
    axis[k] = half[k]
    others = np.delete(half, k)
    return center - axis, center + axis, float(np.linalg.norm(others)), half


def _inner_capsule(geom: Any) -> tuple[FloatArray, FloatArray, float]:
    """Capsule (end a, end b, radius) contained in the shape, in the shape's frame; radius -1
    when none is known (meshes)."""
    zero = np.zeros(3)
    if isinstance(geom, coal.Sphere):
        return zero, zero, float(geom.radius)
    if isinstance(geom, coal.Capsule):
        h = np.array([0.0, 0.0, float(geom.halfLength)])
        return -h, h, float(geom.radius)
    if isinstance(geom, coal.Cylinder):
        r, half = float(geom.radius), float(geom.halfLength)
        if half <= r:
            return zero, zero, half
        h = np.array([0.0, 0.0, half - r])
        return -h, h, r
    if isinstance(geom, coal.Box):
        half_side = np.array(geom.halfSide)
        k = int(np.argmax(half_side))
        m = float(np.min(np.delete(half_side, k)))
        axis = np.zeros(3)
        axis[k] = half_side[k] - m
        return -axis, axis, m
    return zero, zero, -1.0


def _apply(rot: FloatArray, vec: FloatArray) -> FloatArray:
    """(N, G, 3) products of rotations (N, G, 3, 3) with per-geometry vectors (G, 3)."""
    return np.asarray(
        rot[..., 0] * vec[:, 0, None]
        + rot[..., 1] * vec[:, 1, None]
        + rot[..., 2] * vec[:, 2, None],
        dtype=np.float64,
    )


def bounding_segment(geom: Any) -> tuple[FloatArray, FloatArray, float]:
    """A capsule (end a, end b, radius) containing the shape, in the shape's frame: for a
    convex hull, along its longest AABB axis, as long as the points' extent along it and as
    thick as their farthest from it; for other shapes, see :func:`_bounding_capsule`."""
    if isinstance(geom, coal.ConvexBase) and geom.num_points > 0:
        points = np.asarray(geom.points(), dtype=np.float64).reshape(-1, 3)
        lo, hi = points.min(axis=0), points.max(axis=0)
        k = int(np.argmax(hi - lo))
        centre = (lo + hi) / 2.0
        radial = np.delete(points - centre, k, axis=1)
        end_a, end_b = centre.copy(), centre.copy()
        end_a[k], end_b[k] = lo[k], hi[k]
        return end_a, end_b, float(np.sqrt(np.max(np.sum(radial * radial, axis=1))))
    end_a, end_b, radius, _ = _bounding_capsule(geom)
    return end_a, end_b, radius


_BOUNDS: dict[int, tuple[Any, tuple[FloatArray, FloatArray]]] = {}
_BOUNDS_KEPT = 64  # geometry models remembered (characters in a process)


def shape_bounds(geometry: Any) -> tuple[FloatArray, FloatArray]:
    """Per shape of a pin.GeometryModel its bounding sphere: centre (G, 3) in the shape's
    frame and radius (G,) m, from its local AABB; computed once per geometry model
    (read-only)."""
    hit = _BOUNDS.get(id(geometry))
    if hit is not None and hit[0] is geometry:
        return hit[1]
    shapes = [o.geometry for o in geometry.geometryObjects]
    for shape in shapes:
        shape.computeLocalAABB()
    centres = np.array([s.aabb_center for s in shapes], dtype=np.float64).reshape(-1, 3)
    radii = np.array([float(s.aabb_radius) for s in shapes], dtype=np.float64)
    centres.flags.writeable = False
    radii.flags.writeable = False
    if len(_BOUNDS) >= _BOUNDS_KEPT:
        _BOUNDS.clear()
    _BOUNDS[id(geometry)] = (geometry, (centres, radii))
    return centres, radii


def _unit_clip(x: FloatArray) -> FloatArray:
    """``x`` clipped to [0, 1] (NaN stays NaN)."""
    return np.minimum(np.maximum(x, 0.0), 1.0)


PARALLEL_SINE_SQUARED = 1e-10
"""Squared sine of the angle under which two segments are measured as parallel (from the
first one's start): relative to their lengths, as the rounding of the squared sine is
(an absolute bound on it took segments a few millimetres long crossing at 19 degrees for
parallel, 0.4 mm too far apart)."""


def _dots(x: FloatArray, y: FloatArray) -> FloatArray:
    """(...,) the row-wise dot products of two (..., 3) arrays."""
    return np.asarray(np.einsum("...i,...i->...", x, y), dtype=np.float64)


def segment_distances(p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray) -> FloatArray:
    """(...,) distances between segments [p1, q1] and [p2, q2] given as (..., 3) arrays."""
    eps = 1e-12
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    # the five dot products, one einsum each: numpy's batched matmul of a stacked (3, 3) Gram
    # matrix per pair costs as much below 50 pairs and 2.4 times as much at a thousand (a
    # real robot's 1,159 declared pairs)
    a, b, c = _dots(d1, d1), _dots(d1, d2), _dots(d1, r)
    e, f = _dots(d2, d2), _dots(d2, r)
    a_safe, e_safe = np.maximum(a, eps), np.maximum(e, eps)
    denom = a * e - b * b  # |d1|^2 |d2|^2 sin^2 of their angle
    # np.minimum(np.maximum(x, 0), 1) is np.clip(x, 0, 1), several times cheaper on small
    # arrays (this runs in every control step's broad phase)
    unit = _unit_clip
    crossing = denom > PARALLEL_SINE_SQUARED * a * e
    s = np.where(crossing, unit((b * f - c * e) / np.where(crossing, denom, 1.0)), 0.0)
    # a second segment that is a point (a sphere's capsule): the first's point nearest it
    point = e <= eps
    s = np.where(point, unit(-c / a_safe), s)
    t = np.where(point, 0.0, (b * s + f) / e_safe)
    low, high = t < 0.0, t > 1.0
    s = np.where(low, unit(-c / a_safe), s)
    s = np.where(high, unit((b - c) / a_safe), s)
    t = unit(t)
    gap = r + d1 * s[..., None] - d2 * t[..., None]
    return np.sqrt(_dots(gap, gap))


FEW_SEGMENTS = 16  # pairs up to which plain floats beat numpy's per-call cost


def few_segment_distances(
    p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray
) -> FloatArray:
    """:func:`segment_distances` of a few pairs of segments given as (n, 3) arrays, in plain
    floats (the same formulas: about ten times cheaper than numpy's calls for one pair, even
    at ``FEW_SEGMENTS``; a control step's broad phase tests a handful)."""
    eps = 1e-12
    sqrt = math.sqrt
    out = []
    for (ax, ay, az), (bx, by, bz), (cx, cy, cz), (dx, dy, dz) in zip(
        p1.tolist(), q1.tolist(), p2.tolist(), q2.tolist(), strict=True
    ):
        d1x, d1y, d1z = bx - ax, by - ay, bz - az
        d2x, d2y, d2z = dx - cx, dy - cy, dz - cz
        rx, ry, rz = ax - cx, ay - cy, az - cz
        a = d1x * d1x + d1y * d1y + d1z * d1z
        e = d2x * d2x + d2y * d2y + d2z * d2z
        b = d1x * d2x + d1y * d2y + d1z * d2z
        c = d1x * rx + d1y * ry + d1z * rz
        f = d2x * rx + d2y * ry + d2z * rz
        a_safe = a if a > eps else eps
        e_safe = e if e > eps else eps
        denom = a * e - b * b
        s = 0.0
        if denom > PARALLEL_SINE_SQUARED * a * e:
            s = min(max((b * f - c * e) / denom, 0.0), 1.0)
        if e <= eps:  # the second segment a point
            s, t = min(max(-c / a_safe, 0.0), 1.0), 0.0
        else:
            t = (b * s + f) / e_safe
        if t < 0.0:
            s, t = min(max(-c / a_safe, 0.0), 1.0), 0.0
        elif t > 1.0:
            s, t = min(max((b - c) / a_safe, 0.0), 1.0), 1.0
        gx = rx + d1x * s - d2x * t
        gy = ry + d1y * s - d2y * t
        gz = rz + d1z * s - d2z * t
        out.append(sqrt(gx * gx + gy * gy + gz * gz))
    return np.array(out, dtype=np.float64)


@dataclass(frozen=True, slots=True, eq=False)
class SelfCollisionChecker:
    """Batched self-collision test over the active pairs of a geometry model.

    Per geometry g (arrays indexed by g, all in the frame of the parent joint ``joint[g]``):
    placement_R/t (g, 3, 3)/(g, 3) of the shape; a bounding capsule ``cap_a``, ``cap_b``
    (g, 3) and ``cap_r`` (g,); for boxes (and shapes bounded by their AABB) ``box_half``
    (g, 3) (zero if not a box) with the box centred at ``box_t`` (g, 3) in the shape axes.
    pairs : (p, 2) geometry indices checked.

    Broad phase (numpy): capsule-capsule distance, then separating axes of each box against
    the other's capsule; narrow phase: ``coal.collide`` on the survivors.
    """

    shapes: tuple[Any, ...]
    joint: IntArray
    placement_R: FloatArray
    placement_t: FloatArray
    cap_a: FloatArray
    cap_b: FloatArray
    cap_r: FloatArray
    box_half: FloatArray
    box_t: FloatArray
    inner_a: FloatArray
    inner_b: FloatArray
    inner_r: FloatArray
    pairs: IntArray

    @staticmethod
    def from_geometry_model(gmodel: Any) -> SelfCollisionChecker:
        """Checker for the collision pairs declared in ``gmodel``."""
        shapes = []
        joints, rots, trans, caps_a, caps_b, caps_r, halves, box_ts = [], [], [], [], [], [], [], []
        inner_a, inner_b, inner_r = [], [], []
        for obj in gmodel.geometryObjects:
            geom = obj.geometry
            geom.computeLocalAABB()
            shapes.append(geom)
            joints.append(int(obj.parentJoint))
            rot = np.array(obj.placement.rotation)
            tr = np.array(obj.placement.translation)
            rots.append(rot)
            trans.append(tr)
            end_a, end_b, radius, half = _bounding_capsule(geom)
            caps_a.append(rot @ end_a + tr)
            caps_b.append(rot @ end_b + tr)
            caps_r.append(radius)
            halves.append(np.zeros(3) if half is None else half)
            box_ts.append((end_a + end_b) / 2.0)
            in_a, in_b, in_r = _inner_capsule(geom)
            inner_a.append(rot @ in_a + tr)
            inner_b.append(rot @ in_b + tr)
            inner_r.append(in_r)
        pairs = np.array([[p.first, p.second] for p in gmodel.collisionPairs], dtype=np.int64)
        return SelfCollisionChecker(
            tuple(shapes),
            np.array(joints, dtype=np.int64),
            np.array(rots).reshape(-1, 3, 3),
            np.array(trans).reshape(-1, 3),
            np.array(caps_a).reshape(-1, 3),
            np.array(caps_b).reshape(-1, 3),
            np.array(caps_r),
            np.array(halves).reshape(-1, 3),
            np.array(box_ts).reshape(-1, 3),
            np.array(inner_a).reshape(-1, 3),
            np.array(inner_b).reshape(-1, 3),
            np.array(inner_r),
            pairs.reshape(-1, 2),
        )

    def subset(self, pair_mask: NDArray[np.bool_]) -> SelfCollisionChecker:
        """The same checker restricted to the pairs selected by ``pair_mask`` (p,)."""
        return SelfCollisionChecker(
            self.shapes,
            self.joint,
            self.placement_R,
            self.placement_t,
            self.cap_a,
            self.cap_b,
            self.cap_r,
            self.box_half,
            self.box_t,
            self.inner_a,
            self.inner_b,
            self.inner_r,
            self.pairs[pair_mask],
        )

    def _box_separates(
        self,
        rot: FloatArray,
        trans: FloatArray,
        samples: IntArray,
        box: IntArray,
        other: IntArray,
        ends_a: FloatArray,
        ends_b: FloatArray,
    ) -> NDArray[np.bool_]:
        """(m,) True where a face axis of geometry ``box`` separates it from the bounding
        capsule of ``other`` (m candidate (sample, pair) rows)."""
        is_box = np.any(self.box_half[box] > 0, axis=1)
        out = np.zeros(len(samples), dtype=bool)
        if not np.any(is_box):
            return out
        s, g, o = samples[is_box], box[is_box], other[is_box]
        r_joint = rot[s, self.joint[g]]
        r_box = r_joint @ self.placement_R[g]
        center = (
            trans[s, self.joint[g]]
            + np.einsum(
                "mab,mb->ma", r_joint, self.placement_t[g] + self.placement_R[g] @ np.zeros(3)
            )
            + np.einsum("mab,mb->ma", r_box, self.box_t[g])
        )
        la = np.einsum("mba,mb->ma", r_box, ends_a[is_box] - center)
        lb = np.einsum("mba,mb->ma", r_box, ends_b[is_box] - center)
        radius = self.cap_r[o][:, None]
        half = self.box_half[g]
        sep = (np.minimum(la, lb) - radius > half) | (np.maximum(la, lb) + radius < -half)
        out[is_box] = np.any(sep, axis=1)
        return out

    def colliding(
        self, rot: FloatArray, trans: FloatArray, moving: NDArray[np.bool_] | None = None
    ) -> NDArray[np.bool_]:
        """(N,) mask of samples in self-collision, from joint placements R (N, J, 3, 3) and
        t (N, J, 3) in a common frame. ``moving`` (J,) optionally marks the joints whose
        placement varies across samples (the others are read from sample 0)."""
        n_batch = rot.shape[0]
        hit = np.zeros(n_batch, dtype=bool)
        if len(self.pairs) == 0:
            return hit
        used = np.unique(self.pairs)
        ends_a = np.zeros((n_batch, len(self.joint), 3))
        ends_b = np.zeros((n_batch, len(self.joint), 3))
        varying = used if moving is None else used[moving[self.joint[used]]]
        fixed = np.setdiff1d(used, varying)
        for group, rows in ((varying, slice(None)), (fixed, slice(0, 1))):
            if len(group) == 0:
                continue
            r_g = rot[rows, self.joint[group]]
            t_g = trans[rows, self.joint[group]]
            ends_a[:, group] = _apply(r_g, self.cap_a[group]) + t_g
            ends_b[:, group] = _apply(r_g, self.cap_b[group]) + t_g
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        mid = (ends_a + ends_b) * 0.5
        half_len = 0.5 * np.linalg.norm(self.cap_b - self.cap_a, axis=1)
        reach = self.cap_r + half_len
        if 3 * len(a) < len(used) ** 2:
            gap = mid[:, a] - mid[:, b]
            d2 = np.sum(gap * gap, axis=2)
        else:
            sq = np.sum(mid * mid, axis=2)
            gram = mid @ mid.transpose(0, 2, 1)
            d2 = sq[:, a] + sq[:, b] - 2.0 * gram[:, a, b]
        sample_idx, pair_idx = np.nonzero(d2 <= (reach[a] + reach[b]) ** 2)
        if len(sample_idx) == 0:
            return hit
        pa, pb = a[pair_idx], b[pair_idx]
        dist = segment_distances(
            ends_a[sample_idx, pa],
            ends_b[sample_idx, pa],
            ends_a[sample_idx, pb],
            ends_b[sample_idx, pb],
        )
        close = dist <= self.cap_r[pa] + self.cap_r[pb] + 1e-9
        sample_idx, pair_idx = sample_idx[close], pair_idx[close]
        if len(sample_idx) == 0:
            return hit
        ga, gb = a[pair_idx], b[pair_idx]
        sep = self._box_separates(
            rot, trans, sample_idx, ga, gb, ends_a[sample_idx, gb], ends_b[sample_idx, gb]
        )
        sep |= self._box_separates(
            rot, trans, sample_idx, gb, ga, ends_a[sample_idx, ga], ends_b[sample_idx, ga]
        )
        sample_idx, ga, gb = sample_idx[~sep], ga[~sep], gb[~sep]
        # Sure hits: the inner capsules (contained in the shapes) already intersect.
        ri, rk = rot[sample_idx, self.joint[ga]], rot[sample_idx, self.joint[gb]]
        ti, tk = trans[sample_idx, self.joint[ga]], trans[sample_idx, self.joint[gb]]
        inner = segment_distances(
            np.einsum("mab,mb->ma", ri, self.inner_a[ga]) + ti,
            np.einsum("mab,mb->ma", ri, self.inner_b[ga]) + ti,
            np.einsum("mab,mb->ma", rk, self.inner_a[gb]) + tk,
            np.einsum("mab,mb->ma", rk, self.inner_b[gb]) + tk,
        )
        sure = (
            (self.inner_r[ga] >= 0)
            & (self.inner_r[gb] >= 0)
            & (inner < self.inner_r[ga] + self.inner_r[gb] - 1e-9)
        )
        hit[sample_idx[sure]] = True
        rest = ~hit[sample_idx]
        sample_idx, ga, gb = sample_idx[rest], ga[rest], gb[rest]
        request = coal.CollisionRequest()
        result = coal.CollisionResult()
        for s, i, k in zip(sample_idx.tolist(), ga.tolist(), gb.tolist(), strict=True):
            if hit[s]:
                continue
            ji, jk = self.joint[i], self.joint[k]
            ri, rk = rot[s, ji], rot[s, jk]
            tf_i = coal.Transform3s(
                ri @ self.placement_R[i], trans[s, ji] + ri @ self.placement_t[i]
            )
            tf_k = coal.Transform3s(
                rk @ self.placement_R[k], trans[s, jk] + rk @ self.placement_t[k]
            )
            result.clear()
            if coal.collide(self.shapes[i], tf_i, self.shapes[k], tf_k, request, result):
                hit[s] = True
        return hit


def set_collision_pairs(model: Any, gmodel: Any, q_ref: FloatArray) -> None:
    """Declare in ``gmodel`` every pair of geometries except those on the same joint, on
    adjacent joints (a joint and its nearest ancestor carrying geometry) and those already
    colliding in the reference configuration ``q_ref`` (nq,)."""
    with_geometry = {int(o.parentJoint) for o in gmodel.geometryObjects}
    gparent = _geometric_parents(model, with_geometry)
    gmodel.removeAllCollisionPairs()
    objs = list(gmodel.geometryObjects)
    for i in range(len(objs)):
        for k in range(i + 1, len(objs)):
            ji, jk = int(objs[i].parentJoint), int(objs[k].parentJoint)
            if ji == jk or gparent.get(ji) == jk or gparent.get(jk) == ji:
                continue
            gmodel.addCollisionPair(pin.CollisionPair(i, k))
    kin = TreeKinematics.from_model(model)
    rot, trans = joint_placements(kin, np.asarray(q_ref, dtype=np.float64)[None, 7:])
    checker = SelfCollisionChecker.from_geometry_model(gmodel)
    index = np.arange(len(checker.pairs))
    colliding = [
        (int(checker.pairs[k, 0]), int(checker.pairs[k, 1]))
        for k in index
        if checker.subset(index == k).colliding(rot, trans)[0]
    ]
    for first, second in colliding:
        gmodel.removeCollisionPair(pin.CollisionPair(first, second))
