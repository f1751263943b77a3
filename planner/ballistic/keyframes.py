"""Whole-body keyframes of jumps (jump paper section 5; anchor brief section 6).

Per jump: takeoff (the stance configuration of the takeoff node), contact break, apex, contact
creation and landing (the stance configuration of the landing node). Stance configurations put
each contact limb on its estimated contact point: the best-ranked sample of the limb's database
near the point (ranked by closeness to the reference posture) seeds an IK projection biased
toward ``q_ref``; free limbs keep the reference (flexion) posture. The contact phases are found
by stepping along the arc at the keyframe times, root exactly on the parabola, solving IK that
holds the stance contacts, until it fails or a ``phase_fraction`` of the flight is used (the
takeoff phase walks forward from 0, the landing phase backward from the landing time). Between
the break and the creation frames the root stays on the parabola and the joints move linearly
through an apex posture blended toward the reference.

Contacts are held in position for point contacts and in full placement for patches.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planner.ballistic.arc import slerp
from planner.ballistic.steering import Jump
from planner.character import Character
from planner.kinematics import (
    ContactNormalTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    Priority,
    frame_placements,
    keyframe_times,
    solve_ik,
)
from planner.kinematics.tasks import Task
from planner.motion import Keyframe
from planner.offline import OfflineData
from planner.scene import Scene, Surface

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]


_TREES: dict[tuple[str, str], cKDTree] = {}


def _tree(data: OfflineData, limb: str) -> cKDTree:
    """k-d tree over a limb's database positions (root frame), cached by the data key."""
    key = (data.cache_key, limb)
    tree = _TREES.get(key)
    if tree is None:
        if len(_TREES) > 256:
            _TREES.clear()
        tree = cKDTree(data.limb(limb).database.positions)
        _TREES[key] = tree
    return tree


_TUCKED: dict[tuple[str, str], IntArray] = {}


def _tucked(data: OfflineData, limb: str) -> IntArray:
    """A limb's database samples by decreasing effector height in the root frame (tucked
    first), cached by the data key."""
    key = (data.cache_key, limb)
    order = _TUCKED.get(key)
    if order is None:
        if len(_TUCKED) > 256:
            _TUCKED.clear()
        heights = data.limb(limb).database.positions[:, 2]
        order = np.asarray(np.argsort(-heights, kind="stable"), dtype=np.int64)
        _TUCKED[key] = order
    return order


@dataclass(frozen=True, slots=True)
class Stance:
    """A whole-body contact configuration at a node.

    q : (nq,) configuration. achieved : (L,) limbs whose contact IK succeeded. placements :
    (L, 4, 4) effector frame poses at ``q`` (world). points : (L, 3) the targeted contact points.
    """

    q: FloatArray
    achieved: BoolArray
    placements: FloatArray
    points: FloatArray


@dataclass(frozen=True, slots=True)
class JumpFrames:
    """Keyframes of one jump (absolute times) and its key instants (absolute, s).

    resampled : flight frames where a colliding limb was re-sampled. limb_collisions : flight
    frames where some limb still touches the scene (no collision-free alternative found).
    """

    frames: tuple[Keyframe, ...]
    contact_break: float
    apex_time: float
    contact_create: float
    resampled: int = 0
    limb_collisions: int = 0


class LimbCollider:
    """Which limbs of a configuration touch the scene (the character's collision geometry of
    each limb's links against the scene BVH). Not thread-safe: one per thread."""

    def __init__(self, character: Character, scene: Scene) -> None:
        self.model = character.model
        self.data = self.model.createData()
        self.gmodel = character.geometry
        self.gdata = pin.GeometryData(self.gmodel)
        self.bvh = scene.collision.bvh
        self.identity = coal.Transform3s()
        self.request = coal.CollisionRequest()
        self.result = coal.CollisionResult()
        objects = list(self.gmodel.geometryObjects)
        self.geoms: list[list[int]] = [
            [i for i, o in enumerate(objects) if int(o.parentJoint) in set(limb.joint_ids.tolist())]
            for limb in character.default_limbs
        ]

    def colliding(self, q: FloatArray, only: int | None = None) -> BoolArray:
        """(L,) True where a link of limb k at ``q`` (nq,) touches the scene (with ``only``,
        just that limb is checked; the others read False)."""
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateGeometryPlacements(self.model, self.data, self.gmodel, self.gdata)
        out = np.zeros(len(self.geoms), dtype=bool)
        for k, ids in enumerate(self.geoms):
            if only is not None and k != only:
                continue
            for i in ids:
                placement = self.gdata.oMg[i]
                transform = coal.Transform3s(placement.rotation, placement.translation)
                self.result.clear()
                geometry = self.gmodel.geometryObjects[i].geometry
                if coal.collide(
                    self.bvh, self.identity, geometry, transform, self.request, self.result
                ):
                    out[k] = True
                    break
        return out


@dataclass(frozen=True, slots=True, eq=False)
class JumpAnimator:
    """Keyframe generator for one character.

    rate : keyframes per second. phase_fraction : at most this fraction of the flight is spent
    in each contact phase. search_radius : m, database samples this close to a contact point
    seed its projection. apex_blend : weight of the reference posture at the apex. tolerance
    (m), angular_tolerance (rad): how well held contacts must hold. steps : the IK walk takes
    at least this many steps per contact phase (besides the keyframe times). limbs : when
    given, flight frames are checked and a colliding limb is re-sampled (the reference
    posture, its break/creation joints, the ``candidates`` best-ranked database samples, then
    the ``candidates`` most tucked ones (highest effector in the root frame);
    the first collision-free one wins; only that limb's joints change, the root never).
    """

    character: Character
    data: OfflineData
    rate: float = 30.0
    phase_fraction: float = 1.0 / 3.0
    search_radius: float = 0.08
    apex_blend: float = 0.4
    tolerance: float = 1e-3
    angular_tolerance: float = 1e-2
    steps: int = 3
    limbs: LimbCollider | None = None
    candidates: int = 8

    def _contact_task(self, k: int, point: FloatArray, normal: FloatArray) -> Task:
        limb = self.character.default_limbs[k]
        if limb.contact == "point":
            return FramePositionTask(limb.effector_frame, point, limb.offset, Priority.CONTACT)
        return ContactNormalTask(
            limb.effector_frame, point, normal, limb.normal, limb.offset, Priority.CONTACT
        )

    def _posture(self, dofs: IntArray) -> PostureTask:
        weights = np.zeros(self.character.model.nv)
        weights[dofs] = 1.0
        return PostureTask(self.character.q_ref, weights, gain=0.3)

    def _project(
        self,
        q: FloatArray,
        k: int,
        rot: FloatArray,
        position: FloatArray,
        point: FloatArray,
        normal: FloatArray,
    ) -> FloatArray | None:
        """``q`` with limb k's contact on ``point`` (IK seeded from the database), or None."""
        limb = self.character.default_limbs[k]
        database = self.data.limb(limb.name).database
        target = rot.T @ (point - position)
        tree = _tree(self.data, limb.name)
        near = tree.query_ball_point(target, self.search_radius)
        seeds: list[int] = [int(min(near))] if near else []  # best ranked (ascending cost)
        _, nearest = tree.query(target)
        if int(nearest) not in seeds:
            seeds.append(int(nearest))
        seeds_q = [database.q[i] for i in seeds] or [q[limb.idx_q]]
        task = self._contact_task(k, point, normal)
        for seed in seeds_q:
            trial = np.array(q)
            trial[limb.idx_q] = seed
            result = solve_ik(
                self.character.model,
                trial,
                [task, self._posture(limb.idx_v)],
                active=limb.idx_v,
                max_iterations=60,
                tolerance=1e-4,
                angular_tolerance=1e-3,
            )
            if result.success:
                return np.array(result.q)
        return None

    def stance(
        self,
        position: FloatArray,
        quaternion: FloatArray,
        active: BoolArray,
        points: FloatArray,
        normals: FloatArray,
        surfaces: Sequence[Surface | None] | None = None,
    ) -> Stance:
        """Contact configuration with the root at (position (3,), quaternion (4,)) and the
        ``active`` (L,) limbs on ``points`` (L, 3) with surface ``normals`` (L, 3).

        When a limb cannot reach its point and its ``surfaces`` entry is given, the limb's
        reference contact dropped onto that surface (then the point half-way) is tried
        instead: the normal, hence the centroidal cone, is unchanged. ``Stance.points`` holds
        the contacts actually made."""
        char = self.character
        q = np.array(char.q_ref, dtype=np.float64)
        q[:3] = position
        q[3:7] = quaternion
        x, y, z, w = quaternion
        rot = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        achieved = np.zeros(len(char.default_limbs), dtype=bool)
        reached = np.array(points, dtype=np.float64)
        reference = frame_placements(
            char.model, q, [limb.effector_frame for limb in char.default_limbs]
        )
        for k in (int(i) for i in np.flatnonzero(active)):
            limb = char.default_limbs[k]
            target = np.asarray(points[k], dtype=np.float64)
            found = self._project(q, k, rot, position, target, normals[k])
            surface = surfaces[k] if surfaces is not None else None
            if found is None and surface is not None:
                # Fallbacks: the reference contact dropped on the surface, then half-way there.
                ref = reference[k, :3, :3] @ limb.offset + reference[k, :3, 3]
                dropped = ref - float((ref - target) @ normals[k]) * normals[k]
                for extra in (dropped, 0.5 * (dropped + target)):
                    if surface.contains_projection(extra[None], margin=0.02)[0]:
                        found = self._project(q, k, rot, position, extra, normals[k])
                        if found is not None:
                            target = extra
                            break
            if found is not None:
                q = found
                achieved[k] = True
                reached[k] = target
        frames = [limb.effector_frame for limb in char.default_limbs]
        placements = frame_placements(char.model, q, frames)
        return Stance(q, achieved, placements, reached)

    def _holds(self, stance: Stance) -> tuple[list[Task], IntArray]:
        tasks: list[Task] = []
        dofs: list[IntArray] = []
        for k in np.flatnonzero(stance.achieved):
            limb = self.character.default_limbs[k]
            if limb.contact == "point":
                tasks.append(
                    FramePositionTask(
                        limb.effector_frame, stance.points[k], limb.offset, Priority.CONTACT
                    )
                )
            else:
                tasks.append(
                    FramePlacementTask(limb.effector_frame, stance.placements[k], Priority.CONTACT)
                )
            dofs.append(limb.idx_v)
        all_dofs = np.concatenate(dofs) if dofs else np.zeros(0, np.int64)
        return tasks, np.asarray(all_dofs, dtype=np.int64)

    def _walk(
        self,
        jump: Jump,
        quat0: FloatArray,
        quat1: FloatArray,
        stance: Stance,
        times: FloatArray,
    ) -> list[tuple[float, FloatArray]]:
        """Hold ``stance`` along the arc at ``times`` (in walking order) until IK fails."""
        tasks, dofs = self._holds(stance)
        out: list[tuple[float, FloatArray]] = []
        if not tasks:
            return out
        posture = self._posture(dofs)
        q_prev = stance.q
        for tau in times:
            q = np.array(q_prev)
            q[:3] = jump.position(float(tau))
            q[3:7] = slerp(quat0, quat1, np.array([tau / jump.duration]))[0]
            result = solve_ik(
                self.character.model,
                q,
                [*tasks, posture],
                active=dofs,
                max_iterations=8,
                tolerance=self.tolerance,
                angular_tolerance=self.angular_tolerance,
            )
            if not result.success:
                break
            q_prev = np.array(result.q)
            out.append((float(tau), q_prev))
        return out

    def animate(
        self,
        jump: Jump,
        quat0: FloatArray,
        quat1: FloatArray,
        takeoff: Stance,
        landing: Stance,
        t0: float,
    ) -> JumpFrames:
        """Keyframes of ``jump`` from absolute time ``t0``; root orientation SLERPed quat0 ->
        quat1 (as in the arc check); the first frame is ``takeoff.q``, the last ``landing.q``."""
        big_t = jump.duration
        grid = keyframe_times(0.0, big_t, self.rate)
        cap = self.phase_fraction * big_t
        # Walk at the keyframe times and at least ``steps`` finer steps per contact phase.
        fine = np.linspace(0.0, cap, self.steps + 1)[1:]
        ahead = np.unique(np.concatenate([grid[(grid > 0) & (grid <= cap)], fine]))
        behind = np.unique(
            np.concatenate([grid[(grid < big_t) & (grid >= big_t - cap)], big_t - fine])
        )
        forward = self._walk(jump, quat0, quat1, takeoff, ahead)
        backward = self._walk(jump, quat0, quat1, landing, behind[::-1])
        t_break, q_break = forward[-1] if forward else (0.0, takeoff.q)
        t_create, q_create = backward[-1] if backward else (big_t, landing.q)
        tau_apex = float(np.clip(jump.v0[2] / jump.g, 0.0, big_t))
        j_break, j_create = q_break[7:], q_create[7:]
        knots_t = [t_break]
        knots_j = [j_break]
        if t_break < tau_apex < t_create:
            frac = (tau_apex - t_break) / (t_create - t_break)
            mid = (1.0 - frac) * j_break + frac * j_create
            knots_t.append(tau_apex)
            knots_j.append(
                (1.0 - self.apex_blend) * mid + self.apex_blend * self.character.q_ref[7:]
            )
        knots_t.append(t_create)
        knots_j.append(j_create)
        kt = np.array(knots_t)
        kj = np.array(knots_j)

        take_names = tuple(
            self.character.default_limbs[k].name for k in np.flatnonzero(takeoff.achieved)
        )
        land_names = tuple(
            self.character.default_limbs[k].name for k in np.flatnonzero(landing.achieved)
        )
        frames: list[Keyframe] = [Keyframe(t0, np.array(takeoff.q), take_names)]
        frames.extend(Keyframe(t0 + tau, q, take_names) for tau, q in forward)
        flight = grid[(grid > t_break) & (grid < t_create)]
        if len(kt) == 3:
            flight = np.unique(np.append(flight, tau_apex))
        resampled = 0
        still = 0
        for tau in flight:
            q = np.empty_like(takeoff.q)
            q[:3] = jump.position(float(tau))
            q[3:7] = slerp(quat0, quat1, np.array([tau / big_t]))[0]
            q[7:] = [np.interp(tau, kt, kj[:, j]) for j in range(kj.shape[1])]
            if self.limbs is not None:
                q, fixed, left = self._free_limbs(q, q_break, q_create)
                resampled += fixed
                still += left
            frames.append(Keyframe(t0 + float(tau), q, ()))
        frames.extend(Keyframe(t0 + tau, q, land_names) for tau, q in reversed(backward))
        frames.append(Keyframe(t0 + big_t, np.array(landing.q), land_names))
        return JumpFrames(
            tuple(frames), t0 + t_break, t0 + tau_apex, t0 + t_create, resampled, still
        )

    def _free_limbs(
        self, q: FloatArray, q_break: FloatArray, q_create: FloatArray
    ) -> tuple[FloatArray, int, int]:
        """Re-sample the colliding limbs of flight frame ``q``; (q, fixed, left colliding)."""
        assert self.limbs is not None
        hit = self.limbs.colliding(q)
        if not hit.any():
            return q, 0, 0
        out = np.array(q)
        fixed = 0
        for k in (int(i) for i in np.flatnonzero(hit)):
            limb = self.character.default_limbs[k]
            database = self.data.limb(limb.name).database
            options = [self.character.q_ref[limb.idx_q], q_break[limb.idx_q], q_create[limb.idx_q]]
            options.extend(database.q[: self.candidates])
            options.extend(database.q[_tucked(self.data, limb.name)[: self.candidates]])
            for option in options:
                trial = np.array(out)
                trial[limb.idx_q] = option
                if not self.limbs.colliding(trial, only=k)[k]:
                    out = trial
                    fixed += 1
                    break
        return out, int(fixed > 0), int(fixed < int(hit.sum()))


__all__ = ["JumpAnimator", "JumpFrames", "LimbCollider", "Stance"]
