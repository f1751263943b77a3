"""Collision avoidance as QP inequalities on the control step (a velocity damper).

For every pair of shapes closer than ``INFLUENCE_DISTANCE`` (a body shape and the scene, or
two body shapes), with signed distance ``d``, witness points ``p_a`` and ``p_b`` and unit
normal ``n`` from ``a`` to ``b`` (coal), the step ``dq`` must satisfy

    n . (J_b(p_b) - J_a(p_a)) dq >= -DAMPER_RATE (d - d_s)

so that no pair closes more than a fraction of its remaining gap to ``d_s`` per step
(Faverjon and Tournassoud's damper in discrete time). ``J(p)`` is the Jacobian of the body
point ``p`` (world axes); the scene does not move. Both limits follow pink's ``Limit``
interface (``G dq <= h``) and read the kinematics pink computed for the step.

coal gives one witness pair per shape, so a foot rising along a riser sees only the riser,
then only the tread once past the edge, and would slide into the corner between them. The
scene limit therefore remembers each shape's recent witnesses (scene point, normal, body
point in its joint's frame) for ``WITNESS_MEMORY`` steps and keeps a row for each: the
half-spaces of the last few steps bound the shape together.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from pink.limits import Limit

from planner.motion import tuning

FloatArray = NDArray[np.float64]


def point_jacobian(model: Any, data: Any, joint: int, point: FloatArray) -> FloatArray:
    """(3, nv) Jacobian of the world velocity of the world ``point`` (3,) fixed to ``joint``;
    needs ``computeJointJacobians`` at the current configuration."""
    j = pin.getJointJacobian(model, data, joint, pin.LOCAL_WORLD_ALIGNED)
    lever = point - data.oMi[joint].translation
    skew = np.array(
        [[0.0, -lever[2], lever[1]], [lever[2], 0.0, -lever[0]], [-lever[1], lever[0], 0.0]]
    )
    return np.asarray(j[:3] - skew @ j[3:], dtype=np.float64)


def _damper_row(
    normal: FloatArray, jacobian: FloatArray, distance: float, security: float
) -> tuple[FloatArray, float]:
    """One row of ``G dq <= h`` for ``n . J dq >= -rate (d - d_s)`` while the shape is
    farther than the security distance ``d_s``; closer, it may not approach (a forearm next
    to the hand on the floor is not pushed up, dragging the held hand off its contact), and
    a shape inside the scene is pushed out at ``rate * |d|``, capped at ``MAX_PUSH``."""
    if distance >= security:
        bound = tuning.DAMPER_RATE * (distance - security)
    else:
        bound = min(0.0, tuning.DAMPER_RATE * distance)
    return -normal @ jacobian, max(bound, -tuning.MAX_PUSH)


class SceneDistances:
    """Signed distances (m, negative inside) of body shapes to the scene (a triangle BVH)
    and static obstacles ((coal geometry, coal.Transform3s) pairs). Not thread-safe.

    An exact distance on a BVH costs tens of microseconds (the traversal looks for the
    nearest triangle), a collision test with a security margin a few (it stops at the first
    bounding volume within the margin, or prunes the tree): callers that only need the
    distances below a bound (the dampers within ``INFLUENCE_DISTANCE``, the checker's
    penetrations) ask :meth:`within` and :meth:`penetration`, which run the collision test
    first and compute the distance only when it says the shape is that close."""

    def __init__(self, scene_bvh: Any, obstacles: Sequence[tuple[Any, Any]] = ()) -> None:
        self.targets: list[tuple[Any, Any]] = [(scene_bvh, coal.Transform3s()), *obstacles]
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True
        self.result = coal.DistanceResult()
        self._near = coal.CollisionRequest()
        self._near.security_margin = tuning.INFLUENCE_DISTANCE
        self._touch = coal.CollisionRequest()
        self._touch.security_margin = 0.0
        self._collision = coal.CollisionResult()

    def each(self, geometry: Any, placement: Any) -> Iterator[tuple[float, Any]]:
        """Per target, the distance of ``geometry`` at ``placement`` (pin.SE3) and coal's
        result (witness points, normal from the target to the shape); the result is reused,
        read it before the next item."""
        transform = coal.Transform3s(placement.rotation, placement.translation)
        for target, target_tf in self.targets:
            self.result.clear()
            d = coal.distance(target, target_tf, geometry, transform, self.request, self.result)
            yield float(d), self.result

    def _close(self, request: Any, target: Any, target_tf: Any, geometry: Any, tf: Any) -> bool:
        self._collision.clear()
        return bool(coal.collide(target, target_tf, geometry, tf, request, self._collision))

    def within(self, geometry: Any, placement: Any) -> Iterator[tuple[float, Any]]:
        """As :meth:`each`, for the targets closer than ``INFLUENCE_DISTANCE`` only (the
        others may be skipped without computing their distance)."""
        transform = coal.Transform3s(placement.rotation, placement.translation)
        for target, target_tf in self.targets:
            if not self._close(self._near, target, target_tf, geometry, transform):
                continue
            self.result.clear()
            d = coal.distance(target, target_tf, geometry, transform, self.request, self.result)
            yield float(d), self.result

    def nearest(self, geometry: Any, placement: Any) -> float:
        """The smallest signed distance of ``geometry`` at ``placement`` to any target."""
        return min(d for d, _ in self.each(geometry, placement))

    def penetration(self, geometry: Any, placement: Any) -> float:
        """How deep (m, >= 0) ``geometry`` at ``placement`` is inside the deepest target: 0
        when it touches none (then no distance is computed)."""
        transform = coal.Transform3s(placement.rotation, placement.translation)
        deepest = 0.0
        for target, target_tf in self.targets:
            if not self._close(self._touch, target, target_tf, geometry, transform):
                continue
            self.result.clear()
            d = coal.distance(target, target_tf, geometry, transform, self.request, self.result)
            deepest = max(deepest, -float(d))
        return deepest


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
        self.geometry_data = pin.GeometryData(geometry)
        self.distances = SceneDistances(scene_bvh, obstacles)
        self.skipped: frozenset[int] = frozenset()
        self.light: dict[int, float] = {}
        self.rows = 0
        # per shape: recent (step, scene point (3,), normal (3,), body point in joint frame)
        self.memory: dict[int, list[tuple[int, FloatArray, FloatArray, FloatArray]]] = {}
        self.steps = 0

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
        """``G dq <= h`` rows of the shapes within the influence distance (None if none)."""
        model, data = self.model, configuration.data
        pin.updateGeometryPlacements(model, data, self.geometry, self.geometry_data)
        rows: list[FloatArray] = []
        bounds: list[float] = []
        self.steps += 1
        oldest = self.steps - tuning.WITNESS_MEMORY
        for i, obj in enumerate(self.geometry.geometryObjects):
            if i in self.skipped:
                continue
            security = self.light.get(i, tuning.SECURITY_DISTANCE)
            joint = int(obj.parentJoint)
            frame = data.oMi[joint]
            memory = [m for m in self.memory.get(i, []) if m[0] > oldest]
            self.memory[i] = memory
            for d, result in self.distances.within(obj.geometry, self.geometry_data.oMg[i]):
                if d > tuning.INFLUENCE_DISTANCE:
                    continue
                local = frame.actInv(np.array(result.getNearestPoint2()))
                scene_point = np.array(result.getNearestPoint1())
                memory.append((self.steps, scene_point, np.array(result.normal), local))
            for _, scene_point, normal, local in memory:
                point = frame.act(local)
                d = float(normal @ (point - scene_point))
                if d > tuning.INFLUENCE_DISTANCE:
                    continue
                jac = point_jacobian(model, data, joint, point)
                row, bound = _damper_row(normal, jac, d, security)
                rows.append(row)
                bounds.append(bound)
        self.rows = len(rows)
        if not rows:
            return None
        return np.vstack(rows), np.asarray(bounds, dtype=np.float64)


class PairSpheres:
    """The broad phase of the declared collision pairs of a pin.GeometryModel: each shape's
    bounding sphere (its local AABB's centre and radius)."""

    def __init__(self, geometry: Any) -> None:
        pairs = [(int(p.first), int(p.second)) for p in geometry.collisionPairs]
        self.pair_array = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        self.centres: list[FloatArray | None] = []
        radii = []
        for obj in geometry.geometryObjects:
            obj.geometry.computeLocalAABB()
            centre = np.array(obj.geometry.aabb_center, dtype=np.float64)
            self.centres.append(None if not centre.any() else centre)
            radii.append(float(obj.geometry.aabb_radius))
        r = np.array(radii)
        self.radii_sum = r[self.pair_array[:, 0]] + r[self.pair_array[:, 1]]

    def overlapping(self, geometry_data: Any, margin: float = 0.0) -> NDArray[np.int64]:
        """Indices of the pairs whose bounding spheres, at the placements of
        ``geometry_data`` (updated), are less than ``margin`` (m) apart: the others are
        farther apart than that."""
        # a shape centred on its frame (most primitives) is at its placement's translation
        centres = np.array(
            [
                placement.translation if c is None else placement.act(c)
                for placement, c in zip(geometry_data.oMg, self.centres, strict=True)
            ]
        )
        a_idx, b_idx = self.pair_array[:, 0], self.pair_array[:, 1]
        gaps = np.linalg.norm(centres[a_idx] - centres[b_idx], axis=1) - self.radii_sum
        return np.flatnonzero(gaps <= margin)


class SelfClearance(Limit):  # type: ignore[misc]
    """Body shapes kept apart: the collision pairs declared in the character's geometry
    model (adjacent links and pairs touching in the reference posture are not declared)."""

    def __init__(self, model: Any, geometry: Any) -> None:
        self.model = model
        self.geometry = geometry
        self.geometry_data = pin.GeometryData(geometry)
        for request in self.geometry_data.distanceRequests:
            request.enable_signed_distance = True
        self.pairs = [(int(p.first), int(p.second)) for p in geometry.collisionPairs]
        self.spheres = PairSpheres(geometry)
        self.joints = [int(o.parentJoint) for o in geometry.geometryObjects]
        self.rows = 0

    def compute_qp_inequalities(
        self, configuration: Any, dt: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """``G dq <= h`` rows of the pairs within the influence distance (None if none)."""
        model, data = self.model, configuration.data
        pin.updateGeometryPlacements(model, data, self.geometry, self.geometry_data)
        # broad phase: bounding spheres farther apart than the influence distance are skipped
        near = self.spheres.overlapping(self.geometry_data, tuning.INFLUENCE_DISTANCE)
        rows: list[FloatArray] = []
        bounds: list[float] = []
        for k in near.tolist():
            a, b = self.pairs[k]
            pin.computeDistance(self.geometry, self.geometry_data, k)
            result = self.geometry_data.distanceResults[k]
            d = float(result.min_distance)
            if d > tuning.INFLUENCE_DISTANCE:
                continue
            normal = np.array(result.normal)
            jac_a = point_jacobian(model, data, self.joints[a], np.array(result.getNearestPoint1()))
            jac_b = point_jacobian(model, data, self.joints[b], np.array(result.getNearestPoint2()))
            row, bound = _damper_row(normal, jac_b - jac_a, d, tuning.SECURITY_DISTANCE)
            rows.append(row)
            bounds.append(bound)
        self.rows = len(rows)
        if not rows:
            return None
        return np.vstack(rows), np.asarray(bounds, dtype=np.float64)
