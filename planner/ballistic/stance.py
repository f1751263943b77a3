"""Whole-body contact configurations at jump nodes (jump paper section 5: "two contact
configurations at the take-off and landing phases").

Each contact limb is put on its estimated contact point: the best-ranked sample of the limb's
database near the point (ranked by closeness to the reference posture) seeds an IK
projection biased toward ``q_ref``; free limbs keep the reference posture. Point contacts are
placed in position, patches in full placement (on the surface normal). The motion between
these stances (push, flight, landing) is the whole-body builder's (``planner.motion.jump``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planner.character import Character
from planner.kinematics import (
    ContactNormalTask,
    FramePositionTask,
    PostureTask,
    Priority,
    frame_placements,
    solve_ik,
)
from planner.kinematics.tasks import Task
from planner.offline import OfflineData
from planner.scene import Surface

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


@dataclass(frozen=True, slots=True, eq=False)
class NodeStancer:
    """Contact configurations of one character at roadmap nodes.

    search_radius : m, database samples this close to a contact point seed its projection.
    """

    character: Character
    data: OfflineData
    search_radius: float = 0.08

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


__all__ = ["NodeStancer", "Stance"]
