"""Collision avoidance as QP inequalities on the control step (a velocity damper).

For every pair of shapes closer than ``INFLUENCE_DISTANCE`` (a body shape and the scene, or
two body shapes), with signed distance ``d``, witness points ``p_a`` and ``p_b`` and unit
normal ``n`` from ``a`` to ``b`` (coal), the step ``dq`` must satisfy

    n . (J_b(p_b) - J_a(p_a)) dq >= -DAMPER_RATE (d - d_s)

so that no pair closes more than a fraction of its remaining gap to ``d_s`` per step
(Faverjon and Tournassoud's damper in discrete time). ``J(p)`` is the Jacobian of the body
point ``p`` (world axes); the scene does not move. Both limits follow pink's ``Limit``
interface (``G dq <= h``) and read the kinematics pink computed for the step. The body shapes
are ``Character.motion_geometry`` (a real robot's URDF meshes as convex hulls).

coal gives one witness pair per shape, so a foot rising along a riser sees only the riser,
then only the tread once past the edge, and would slide into the corner between them. The
scene limit therefore remembers each shape's recent witnesses (scene point, normal, body
point in its joint's frame) for ``WITNESS_MEMORY`` steps and keeps a row for each: the
half-spaces of the last few steps bound the shape together. A new witness replaces those it
sees the scene locally convex with (``_superseded``): round a convex edge one plane is
enough, and the older, tilted ones would hold the shape back.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from pink.limits import Limit

from planner.character.collision import (
    FEW_SEGMENTS,
    bounding_segment,
    few_segment_distances,
    segment_distances,
    shape_bounds,
)
from planner.kinematics.model import signed_geometry_data
from planner.motion import tuning

FloatArray = NDArray[np.float64]


Poses = tuple[FloatArray, FloatArray]


def shape_poses(geometry_data: Any) -> Poses:
    """The placements of ``geometry_data`` (updated by the caller) as arrays: rotations
    (G, 3, 3) and translations (G, 3), world frame."""
    # tolist() copies the placements out in one call: indexing or iterating the pinocchio
    # vector converts one element at a time, several times slower
    homogeneous = np.array([m.homogeneous for m in geometry_data.oMg.tolist()]).reshape(-1, 4, 4)
    return (
        np.ascontiguousarray(homogeneous[:, :3, :3]),
        np.ascontiguousarray(homogeneous[:, :3, 3]),
    )


_MASKS: dict[int, tuple[Any, NDArray[np.bool_]]] = {}
_PAIR_LISTS: dict[int, tuple[Any, tuple[list[tuple[int, int]], list[int]]]] = {}
_MEMO_SIZE = 64  # geometry models remembered by each memo below (characters in a process)


def _pair_lists(geometry: Any) -> tuple[list[tuple[int, int]], list[int]]:
    """The declared collision pairs of a pin.GeometryModel as (first, second) shape
    indices, and each shape's parent joint; computed once per geometry model (do not
    modify)."""
    hit = _PAIR_LISTS.get(id(geometry))
    if hit is not None and hit[0] is geometry:
        return hit[1]
    pairs = [(int(p.first), int(p.second)) for p in geometry.collisionPairs]
    joints = [int(o.parentJoint) for o in geometry.geometryObjects]
    if len(_PAIR_LISTS) >= _MEMO_SIZE:
        _PAIR_LISTS.clear()
    _PAIR_LISTS[id(geometry)] = (geometry, (pairs, joints))
    return pairs, joints


# e_ijk: (a x b)_i = e_ijk a_j b_k
_LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI_CIVITA[_i, _j, _k], _LEVI_CIVITA[_i, _k, _j] = 1.0, -1.0


def support_masks(model: Any) -> NDArray[np.bool_]:
    """(njoints, nv) per joint, the velocity coordinates that move it (those of the joints
    from the root to it, itself included); computed once per model (read-only)."""
    cached = _MASKS.get(id(model))
    if cached is not None and cached[0] is model:
        return cached[1]
    masks = np.zeros((model.njoints, model.nv), dtype=bool)
    parents = list(model.parents)
    joints = list(model.joints)
    for joint in range(1, model.njoints):  # a parent's index is below its children's
        masks[joint] = masks[parents[joint]]
        start = int(joints[joint].idx_v)
        masks[joint, start : start + int(joints[joint].nv)] = True
    masks.flags.writeable = False
    if len(_MASKS) > 64:
        _MASKS.clear()
    _MASKS[id(model)] = (model, masks)
    return masks


class PointJacobians:
    """Speeds of body points along directions per unit of dq, at one configuration (rows
    of the points' Jacobians, world axes); reads the world-frame joint Jacobians ``data.J``
    of ``computeJointJacobians`` (or ``jacobianCenterOfMass``) there, once. ``masks`` :
    :func:`support_masks` of the model (computed if not given)."""

    def __init__(self, model: Any, data: Any, masks: NDArray[np.bool_] | None = None) -> None:
        self.model, self.data = model, data
        self.masks = support_masks(model) if masks is None else masks
        self._world: FloatArray | None = None

    def along(
        self, joints: Sequence[int], points: FloatArray, directions: FloatArray
    ) -> FloatArray:
        """(r, nv) ``n . J(p)`` for each world point p (r, 3) fixed to its joint (r,) and
        direction n (r, 3): the column of a joint moving p adds n.v + (p x n).w, with (v, w)
        that joint's world twist (the velocity of the point at the world origin, and the
        rotation)."""
        if self._world is None:
            self._world = np.array(self.data.J)
        world = self._world
        moment = np.einsum("ijk,rj,rk->ri", _LEVI_CIVITA, points, directions)  # p x n
        speeds = directions @ world[:3] + moment @ world[3:]
        return np.asarray(speeds * self.masks[np.asarray(joints)], dtype=np.float64)


def _damper_rows(
    speeds: FloatArray, distances: FloatArray, securities: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Rows of ``G dq <= h`` for ``n . J dq >= -rate (d - d_s)`` (``speeds`` (r, nv) are the
    ``n . J``, approach speeds per unit of dq, negated; ``distances`` d and security
    distances d_s (r,)) while a shape is farther than d_s; closer, it may not approach (a
    forearm next to the hand on the floor is not pushed up, dragging the held hand off its
    contact), and a shape inside the scene is pushed out at ``rate * |d|``, capped at
    ``MAX_PUSH``."""
    far = tuning.DAMPER_RATE * (distances - securities)
    near = np.minimum(0.0, tuning.DAMPER_RATE * distances)
    bounds = np.where(distances >= securities, far, near)
    return -speeds, np.maximum(bounds, -tuning.MAX_PUSH)


def _superseded(
    memory: list[tuple[int, FloatArray]], row: FloatArray
) -> list[tuple[int, FloatArray]]:
    """``memory`` (step, witness row (9,): scene point, normal, body point) without the
    witnesses that the new ``row`` supersedes: those locally convex with it, each scene
    point on or behind the other's plane (``WITNESS_SUPERSEDE_TOLERANCE``)."""
    if not memory:
        return memory
    # plain floats: a handful of 3-vectors per call, where numpy's per-call cost dominates
    px, py, pz, nx, ny, nz = row[:6].tolist()
    tolerance = tuning.WITNESS_SUPERSEDE_TOLERANCE
    kept = []
    for entry in memory:
        ox, oy, oz, mx, my, mz = entry[1][:6].tolist()
        gx, gy, gz = ox - px, oy - py, oz - pz
        if nx * gx + ny * gy + nz * gz > tolerance or mx * gx + my * gy + mz * gz < -tolerance:
            kept.append(entry)  # concave: the new plane does not fence the old feature
    return kept


class SceneDistances:
    """Signed distances (m, negative inside) of body shapes to the scene (a triangle BVH)
    and static obstacles ((coal geometry, coal.Transform3s) pairs). Not thread-safe.

    With the character's ``geometry`` (pin.GeometryModel), a shape's distance is known to
    stay above ``d - moved`` while its points have moved at most ``moved`` since it was
    measured ``d`` away: :meth:`settled` says for which shapes that bound alone answers a
    query (most shapes, most steps, are far from everything), so that the convex hulls of a
    real robot's links cost little more than capsules."""

    def __init__(
        self, scene_bvh: Any, obstacles: Sequence[tuple[Any, Any]] = (), geometry: Any = None
    ) -> None:
        self.targets: list[tuple[Any, Any]] = [(scene_bvh, coal.Transform3s()), *obstacles]
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True
        self.result = coal.DistanceResult()
        # per shape: bounding sphere (centre in the shape's frame, radius); the distance last
        # measured (-inf: never) and the world centre and rotation it was measured at
        if geometry is None:
            self.local_centres, self.radii = np.zeros((0, 3)), np.zeros(0)
        else:
            self.local_centres, self.radii = shape_bounds(geometry)
        count = len(self.radii)
        self.measured = np.full(count, -np.inf)
        self.measured_centres = np.zeros((count, 3))
        self.measured_rotations = np.zeros((count, 3, 3))
        self.rotations = np.zeros((count, 3, 3))
        self.centres = np.zeros((count, 3))
        self._placed: Poses | None = None  # the poses ``centres`` were computed at

    def each(self, geometry: Any, placement: Any) -> Iterator[tuple[float, Any]]:
        """Per target, the distance of ``geometry`` at ``placement`` (pin.SE3) and coal's
        result (witness points, normal from the target to the shape); the result is reused,
        read it before the next item."""
        return self.each_at(geometry, placement.rotation, placement.translation)

    def each_at(
        self, geometry: Any, rotation: FloatArray, translation: FloatArray
    ) -> Iterator[tuple[float, Any]]:
        """:meth:`each` with the placement given as a rotation (3, 3) and a translation
        (3,) (world frame; a :func:`shape_poses` row costs no pinocchio conversion)."""
        transform = coal.Transform3s(rotation, translation)
        for target, target_tf in self.targets:
            self.result.clear()
            d = coal.distance(target, target_tf, geometry, transform, self.request, self.result)
            yield float(d), self.result

    def nearest(self, geometry: Any, placement: Any) -> float:
        """The smallest signed distance of ``geometry`` at ``placement`` to any target."""
        return min(d for d, _ in self.each(geometry, placement))

    def deepest(self, geometry: Any, placement: Any) -> float:
        """:meth:`nearest`, and when that is negative (inside), the deepest penetration of
        ``geometry`` into any one of the targets' triangles (negative): coal's signed
        distance to a triangle soup is the nearest triangle's, which a shape pushed through
        a face toward an edge reports as shallow."""
        d = self.nearest(geometry, placement)
        if d >= 0.0:
            return d
        transform = coal.Transform3s(placement.rotation, placement.translation)
        request = coal.CollisionRequest()
        request.enable_contact = True
        request.num_max_contacts = tuning.MAX_DEPTH_CONTACTS
        for target, target_tf in self.targets:
            result = coal.CollisionResult()
            coal.collide(target, target_tf, geometry, transform, request, result)
            for contact in result.getContacts():
                d = min(d, float(contact.penetration_depth))
        return d

    def settled(self, geometry_data: Any, threshold: float) -> NDArray[np.bool_]:
        """(G,) whether each shape, at the placements of ``geometry_data`` (updated by the
        caller), is surely farther than ``threshold`` m from every target: its last
        :meth:`remember`-ed distance minus the farthest any of its points can have moved
        since (centre displacement plus the rotation change's Frobenius norm, which bounds
        its spectral norm, times the bounding radius). Keeps the placements for
        :meth:`remember`."""
        return self.settled_at(shape_poses(geometry_data), threshold)

    def settled_at(self, poses: Poses, threshold: float) -> NDArray[np.bool_]:
        """:meth:`settled` with the placements given as :func:`shape_poses` arrays."""
        if poses is not self._placed:  # the same arrays (a checker's, then a step's): known
            self.rotations, translations = poses
            self.centres = (
                np.einsum("gab,gb->ga", self.rotations, self.local_centres) + translations
            )
            self._placed = poses
        moved = self.centres - self.measured_centres
        shift = np.sqrt(np.einsum("ga,ga->g", moved, moved))
        turned = self.rotations - self.measured_rotations
        turn = np.sqrt(np.einsum("gab,gab->g", turned, turned))
        return np.asarray(self.measured - shift - turn * self.radii > threshold)

    def remember(self, i: int, distance: float) -> None:
        """Record that shape ``i`` is ``distance`` m from the nearest target at the
        placement of the last :meth:`settled` call."""
        self.measured[i] = distance
        self.measured_centres[i] = self.centres[i]
        self.measured_rotations[i] = self.rotations[i]

    def remember_all(self, shapes: Sequence[int], distances: Sequence[float]) -> None:
        """:meth:`remember` of each of ``shapes`` (distinct) at its distance, in one go."""
        if not shapes:
            return
        index = np.asarray(shapes, dtype=np.int64)
        self.measured[index] = distances
        self.measured_centres[index] = self.centres[index]
        self.measured_rotations[index] = self.rotations[index]


class SceneClearance(Limit):  # type: ignore[misc]  # pink ships no type information
    """Body shapes kept out of the scene (a triangle BVH) and of static obstacles.

    ``geometry`` is the character's pin.GeometryModel. ``set_phase`` says which shapes rest
    on surfaces by design (stance effectors: skipped) and which may touch lightly (the swing
    effector: ``SWING_SECURITY_DISTANCE``). ``obstacles`` are (coal geometry,
    coal.Transform3s) pairs in the world.
    """

    def __init__(
        self,
        model: Any,
        geometry: Any,
        scene_bvh: Any,
        obstacles: Sequence[tuple[Any, Any]] = (),
    ) -> None:
        self.model = model
        self.geometry = geometry
        self._geometry_data: Any = None  # made when first needed (the tracker lends its own)
        self.distances = SceneDistances(scene_bvh, obstacles, geometry)
        self.skipped: frozenset[int] = frozenset()
        self.light: dict[int, float] = {}
        self.rows = 0
        self.masks = support_masks(model)
        self.shapes = [
            (i, o.geometry, int(o.parentJoint)) for i, o in enumerate(geometry.geometryObjects)
        ]
        # per shape: recent (step, [scene point (3,), normal (3,), body point in its joint's
        # frame (3,)] as one row (9,))
        self.memory: dict[int, list[tuple[int, FloatArray]]] = {}
        self.steps = 0

    @property
    def geometry_data(self) -> Any:
        """This limit's own pin.GeometryData (for :meth:`depths` and pink's interface)."""
        if self._geometry_data is None:
            self._geometry_data = pin.GeometryData(self.geometry)
        return self._geometry_data

    def set_phase(self, skipped: frozenset[int], light: dict[int, float]) -> None:
        """Shapes (geometry indices) not checked, and the security distance (m) of those
        allowed to touch lightly; the witnesses of skipped shapes are forgotten."""
        self.skipped, self.light = skipped, light
        for i in skipped:
            self.memory.pop(i, None)

    def depths(self, data: Any, shapes: frozenset[int]) -> dict[int, float]:
        """Signed distance (m) of each shape in ``shapes`` to the scene and obstacles, at the
        kinematics of ``data``."""
        pin.updateGeometryPlacements(self.model, data, self.geometry, self.geometry_data)
        return {
            i: self.distances.nearest(
                self.geometry.geometryObjects[i].geometry, self.geometry_data.oMg[i]
            )
            for i in shapes
        }

    def compute_qp_inequalities(
        self, configuration: Any, dt: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """``G dq <= h`` rows of the shapes within the influence distance (None if none)
        (pink's ``Limit`` interface; the tracker calls :meth:`rows_at`)."""
        data = configuration.data
        pin.updateGeometryPlacements(self.model, data, self.geometry, self.geometry_data)
        poses = shape_poses(self.geometry_data)
        return self.rows_at(
            data, self.geometry_data, poses, PointJacobians(self.model, data, self.masks)
        )

    def rows_at(
        self, data: Any, geometry_data: Any, poses: Poses, jacobians: PointJacobians
    ) -> tuple[FloatArray, FloatArray] | None:
        """The rows of :meth:`compute_qp_inequalities` at the kinematics of ``data`` (joint
        placements and Jacobians), the shape placements ``geometry_data`` and ``poses``
        (:func:`shape_poses`) already computed there."""
        self.steps += 1
        oldest = self.steps - tuning.WITNESS_MEMORY
        settled = self.distances.settled_at(poses, tuning.INFLUENCE_DISTANCE)
        rotations_g, translations_g = poses
        # the remembered witnesses of every shape, in order: their joints, security distances
        # and (scene point, normal, body point in the joint frame) as one row (9,) each
        joints_w: list[int] = []
        securities_w: list[float] = []
        table: list[FloatArray] = []
        measured: list[int] = []
        nearest_of: list[float] = []
        # only shapes near the scene or with witnesses to remember need a look
        active = set(np.flatnonzero(~settled).tolist())
        active.update(i for i, m in self.memory.items() if m)
        joint_placements: list[Any] = []  # data.oMi copied out once, when first needed
        influence = tuning.INFLUENCE_DISTANCE
        for i in sorted(active - self.skipped):
            _, shape, joint = self.shapes[i]
            memory = [m for m in self.memory.get(i, ()) if m[0] > oldest]
            self.memory[i] = memory
            if not memory and settled[i]:
                continue
            if not settled[i]:
                if not joint_placements:
                    joint_placements = data.oMi.tolist()
                frame = joint_placements[joint]
                nearest = np.inf
                for d, result in self.distances.each_at(shape, rotations_g[i], translations_g[i]):
                    nearest = min(nearest, d)
                    if d > influence:
                        continue
                    local = frame.actInv(np.array(result.getNearestPoint2()))
                    row = np.concatenate((result.getNearestPoint1(), result.normal, local))
                    memory[:] = _superseded(memory, row)  # the list self.memory holds
                    memory.append((self.steps, row))
                measured.append(i)
                nearest_of.append(nearest)
            if memory:
                security = self.light.get(i, tuning.SECURITY_DISTANCE)
                joints_w += [joint] * len(memory)
                securities_w += [security] * len(memory)
                table += [m[1] for m in memory]
        self.distances.remember_all(measured, nearest_of)
        self.rows = 0
        if not table:
            return None
        joints = np.array(joints_w)
        stacked = np.array(table)
        scene_points = stacked[:, :3]
        normals = stacked[:, 3:6]
        locals_ = stacked[:, 6:]
        securities = np.array(securities_w)
        if not joint_placements:
            joint_placements = data.oMi.tolist()
        # each joint's placement read once (a pinocchio attribute costs a conversion)
        frames = {j: joint_placements[j].homogeneous for j in set(joints_w)}
        placed = np.array([frames[j] for j in joints_w])
        rotations = np.ascontiguousarray(placed[:, :3, :3])
        points = np.einsum("rab,rb->ra", rotations, locals_) + placed[:, :3, 3]
        distances = np.einsum("ra,ra->r", normals, points - scene_points)
        keep = distances <= influence
        if not keep.any():
            return None
        speeds = jacobians.along(joints[keep], points[keep], normals[keep])
        rows, bounds = _damper_rows(speeds, distances[keep], securities[keep])
        self.rows = len(rows)
        return rows, bounds


_PAIR_SHAPES: dict[int, tuple[Any, tuple[Any, ...]]] = {}


def _pair_shapes(geometry: Any) -> tuple[Any, ...]:
    """What :class:`PairBroadPhase` knows of a pin.GeometryModel before any query, computed
    once per geometry model (read-only arrays): the declared pairs (P, 2); per shape its
    bounding capsule's ends (G, 3) in its frame; per pair the sum of the capsules' radii (P,);
    per shape its capsule's middle (G, 3), the middle and the ends stacked (G, 3, 3) (one
    product places them all) and the radius of the sphere around the capsule (G,)."""
    hit = _PAIR_SHAPES.get(id(geometry))
    if hit is not None and hit[0] is geometry:
        return hit[1]
    pairs = [(int(p.first), int(p.second)) for p in geometry.collisionPairs]
    pair_array = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    ends_a, ends_b, radii = [], [], []
    for obj in geometry.geometryObjects:
        end_a, end_b, radius = bounding_segment(obj.geometry)
        ends_a.append(end_a)
        ends_b.append(end_b)
        radii.append(radius)
    a = np.array(ends_a, dtype=np.float64).reshape(-1, 3)
    b = np.array(ends_b, dtype=np.float64).reshape(-1, 3)
    r = np.array(radii, dtype=np.float64)
    radii_sum = r[pair_array[:, 0]] + r[pair_array[:, 1]]
    middles = (a + b) / 2.0
    local_points = np.stack([middles, a, b], axis=1)
    spheres = r + np.linalg.norm(b - a, axis=1) / 2.0
    out = (pair_array, a, b, radii_sum, middles, local_points, spheres)
    for array in out:
        array.flags.writeable = False
    if len(_PAIR_SHAPES) >= 64:
        _PAIR_SHAPES.clear()
    _PAIR_SHAPES[id(geometry)] = (geometry, out)
    return out


class PairBroadPhase:
    """Broad phase of the collision pairs declared in a pin.GeometryModel.

    Two filters, both exact. Each shape keeps an odometer, the sum over queries of how far
    any of its points can have moved since the previous one (centre shift plus rotation
    change times its bounding radius), in the frame of a shape on the root joint (two
    shapes' distance is the same in any frame, and the trunk's shapes stay put in it while
    the body walks; in the world frame when no shape is on the root joint): a pair whose
    last known distance (:meth:`remember`, or the bounding-capsule gap measured here) minus
    what both odometers ran since then is above the margin is skipped outright. The others
    are tested on bounding capsules (:func:`bounding_segment`); those farther apart than the
    margin remember their capsule gap. One instance per sequence of queries (it
    remembers)."""

    def __init__(self, geometry: Any) -> None:
        shapes = _pair_shapes(geometry)
        self.pair_array, self.ends_a, self.ends_b, self.radii_sum = shapes[:4]
        self.middles, self.local_points, self.spheres = shapes[4:]
        # the frame the odometers run in: a shape on the root joint (the trunk), whose
        # shapes then do not move while the body walks; the world when there is none
        self.frame = next(
            (i for i, o in enumerate(geometry.geometryObjects) if int(o.parentJoint) == 1),
            None,
        )
        self.odometer = np.zeros(len(self.spheres))
        self.last: tuple[FloatArray, FloatArray] | None = None
        # the poses of the last query and the capsule points placed there (G, 3, 3)
        self._placed: tuple[Poses, FloatArray] | None = None
        # per pair: distance known (-inf: none), both odometers when it was known
        n = len(self.pair_array)
        self.known = np.full(n, -np.inf)
        self.known_odometers = np.zeros((n, 2))

    def near(self, geometry_data: Any, margin: float) -> list[int]:
        """Indices of the pairs that may be at most ``margin`` m apart at the placements of
        ``geometry_data`` (updated by the caller); the caller :meth:`remember` s the
        distances it then computes."""
        if len(self.pair_array) == 0:
            return []
        return self.near_at(shape_poses(geometry_data), margin)

    def near_at(self, poses: Poses, margin: float) -> list[int]:
        """:meth:`near` with the placements given as :func:`shape_poses` arrays."""
        if len(self.pair_array) == 0:
            return []
        if self._placed is not None and self._placed[0] is poses:
            # the same arrays as the last query (a checker's, then a step's): nothing moved
            world = self._placed[1]
        else:
            rot, trans = poses
            world = np.matmul(self.local_points, rot.transpose(0, 2, 1))  # R p for each point
            world += trans[:, None, :]
            centres, turns = world[:, 0], rot
            if self.frame is not None:  # placements in the trunk shape's frame
                frame_rot = rot[self.frame]
                centres = (centres - trans[self.frame]) @ frame_rot
                turns = np.einsum("ba,gbc->gac", frame_rot, rot)
            if self.last is not None:
                last_rot, last_centres = self.last
                turned = turns - last_rot
                moved = centres - last_centres
                self.odometer += np.sqrt(np.einsum("ga,ga->g", moved, moved))
                self.odometer += np.sqrt(np.einsum("gab,gab->g", turned, turned)) * self.spheres
            self.last = (turns, centres)
            self._placed = (poses, world)
        run = self.odometer[self.pair_array] - self.known_odometers
        open_ = np.flatnonzero(self.known - (run[:, 0] + run[:, 1]) <= margin)
        if len(open_) == 0:
            return []
        pairs = self.pair_array[open_]
        first, second = world[pairs[:, 0]], world[pairs[:, 1]]
        segments = (first[:, 1], first[:, 2], second[:, 1], second[:, 2])
        if len(open_) <= FEW_SEGMENTS:
            gaps = few_segment_distances(*segments)
        else:
            gaps = segment_distances(*segments)
        gaps -= self.radii_sum[open_]
        far = gaps > margin
        done = open_[far]
        self.known[done] = gaps[far]
        self.known_odometers[done] = self.odometer[self.pair_array[done]]
        near: list[int] = open_[~far].tolist()
        return near

    def remember(self, k: int, distance: float) -> None:
        """Pair ``k`` is at least ``distance`` m apart at the placements of the last
        :meth:`near` call."""
        self.known[k] = distance
        self.known_odometers[k] = self.odometer[self.pair_array[k]]

    def remember_all(self, pairs: Sequence[int], distances: Sequence[float]) -> None:
        """:meth:`remember` of each of ``pairs`` (distinct) at its distance, in one go."""
        if not pairs:
            return
        index = np.asarray(pairs, dtype=np.int64)
        self.known[index] = distances
        self.known_odometers[index] = self.odometer[self.pair_array[index]]


class SelfClearance(Limit):  # type: ignore[misc]
    """Body shapes kept apart: the collision pairs declared in the character's geometry
    model (adjacent links and pairs touching in the reference posture are not declared)."""

    def __init__(self, model: Any, geometry: Any) -> None:
        self.model = model
        self.geometry = geometry
        self._geometry_data: Any = None  # made when first needed (the tracker lends its own)
        self.pairs, self.joints = _pair_lists(geometry)
        self.broad = PairBroadPhase(geometry)
        self.rows = 0
        self.masks = support_masks(model)

    @property
    def geometry_data(self) -> Any:
        """This limit's own pin.GeometryData, distance requests signed (pink's interface)."""
        if self._geometry_data is None:
            self._geometry_data = signed_geometry_data(self.geometry)
        return self._geometry_data

    def compute_qp_inequalities(
        self, configuration: Any, dt: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """``G dq <= h`` rows of the pairs within the influence distance (None if none)
        (pink's ``Limit`` interface; the tracker calls :meth:`rows_at`)."""
        data = configuration.data
        pin.updateGeometryPlacements(self.model, data, self.geometry, self.geometry_data)
        poses = shape_poses(self.geometry_data)
        return self.rows_at(self.geometry_data, poses, PointJacobians(self.model, data, self.masks))

    def rows_at(
        self, geometry_data: Any, poses: Poses, jacobians: PointJacobians
    ) -> tuple[FloatArray, FloatArray] | None:
        """The rows of :meth:`compute_qp_inequalities` at the shape placements of
        ``geometry_data`` (its distance requests signed) and ``poses`` (:func:`shape_poses`),
        with ``jacobians`` read at the same kinematics."""
        near = self.broad.near_at(poses, tuning.INFLUENCE_DISTANCE)
        # per pair within the influence distance: its joints, witness points, normal (from
        # a to b) and distance; every pair's distance is remembered after the loop
        influence = tuning.INFLUENCE_DISTANCE
        compute, geometry = pin.computeDistance, self.geometry
        measured: list[float] = []
        inside: list[tuple[int, Any]] = []  # (pair, its distance result) within the influence
        for k in near:
            result = compute(geometry, geometry_data, k)
            d = result.min_distance
            measured.append(d)
            if d <= influence:
                inside.append((k, result))
        self.broad.remember_all(near, measured)
        self.rows = len(inside)
        if not inside:
            return None
        pairs, joint_of = self.pairs, self.joints
        joints: list[int] = []
        points: list[FloatArray] = []
        normals: list[FloatArray] = []
        for k, result in inside:
            a, b = pairs[k]
            joints += [joint_of[a], joint_of[b]]
            points += [result.getNearestPoint1(), result.getNearestPoint2()]
            normal = result.normal
            normals += [normal, normal]
        speeds = jacobians.along(
            joints, np.array(points, dtype=np.float64), np.array(normals, dtype=np.float64)
        )
        gap = np.array([result.min_distance for _, result in inside], dtype=np.float64)
        return _damper_rows(
            speeds[1::2] - speeds[0::2], gap, np.full(len(gap), tuning.SECURITY_DISTANCE)
        )
