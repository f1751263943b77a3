"""The one test a keyframe must pass: no body shape inside the scene (stance effectors
excepted, they rest on their surfaces), no two body parts inside each other, and the stance
contacts where they were placed.

Depths are signed distances from coal (negative inside) of the character's collision
shapes against the scene BVH, static obstacles and each other (the declared pairs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character
from planner.kinematics.model import signed_geometry_data
from planner.motion import tuning
from planner.motion.clearance import (
    PairBroadPhase,
    SceneDistances,
    shape_poses,
)
from planner.motion.tracker import WholeBodyTracker, effector_geometries

if TYPE_CHECKING:
    from planner.contact.state import LimbContact

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class KeyframeCheck:
    """scene_depth : m, deepest non-stance shape inside the scene or an obstacle (0 when
    none); shape : its name. self_depth : m, deepest body pair overlap; hold_error : m,
    largest distance of a stance effector from its contact placement. self_pair : the
    names of the two shapes of the deepest body pair overlap (None when none overlap)."""

    scene_depth: float
    shape: str | None
    self_depth: float
    hold_error: float
    self_pair: tuple[str, str] | None = None

    @property
    def colliding(self) -> bool:
        """Deeper than the tolerances of ``tuning`` into the scene or into itself."""
        return (
            self.scene_depth > tuning.PENETRATION_TOLERANCE
            or self.self_depth > tuning.SELF_PENETRATION_TOLERANCE
        )

    @property
    def valid(self) -> bool:
        """Not colliding, and every stance contact held within ``HOLD_TOLERANCE``."""
        return not self.colliding and self.hold_error <= tuning.HOLD_TOLERANCE


class KeyframeChecker:
    """Checks keyframes of one character in one scene (``obstacles``: (coal geometry,
    coal.Transform3s) pairs). Not thread-safe: one per thread. Given the ``tracker`` of the
    same character, scene and obstacles, it shares its distance bounds (a keyframe is where
    the tracker's next control step starts: most of its queries are answered then)."""

    def __init__(
        self,
        character: Character,
        scene_bvh: Any,
        obstacles: Sequence[tuple[Any, Any]] = (),
        tracker: WholeBodyTracker | None = None,
        geometry_data: Any = None,
    ) -> None:
        self.character = character
        self.model = character.model
        self.geometry = character.motion_geometry
        # with a ``tracker`` of the same character, scene and obstacles, its kinematics
        # buffers (each step recomputes them) and its distance bounds (exact lower bounds,
        # whoever measured them) are shared; not its pair distance buffers (coal starts
        # from their last results: sharing them changes the tracker's witnesses slightly)
        # ``geometry_data`` (distance requests signed), lent by the caller for the checker's
        # life, or its own
        self.geometry_data = (
            signed_geometry_data(self.geometry) if geometry_data is None else geometry_data
        )
        self.tracker = tracker
        if tracker is None:
            self.data = self.model.createData()
            self.distances = SceneDistances(scene_bvh, obstacles, self.geometry)
            self.broad = PairBroadPhase(self.geometry)
            self.effectors = effector_geometries(character)
        else:
            self.data = tracker.data
            self.distances = tracker.scene.distances
            self.broad = tracker.self_clearance.broad
            self.effectors = tracker.effectors
        self.shapes = [
            (i, o.geometry, str(o.name)) for i, o in enumerate(self.geometry.geometryObjects)
        ]
        self.frame_ids = {limb.name: int(limb.frame_id) for limb in character.limbs}
        objects = self.geometry.geometryObjects
        self._pair_names = [
            (str(objects[p.first].name), str(objects[p.second].name))
            for p in self.geometry.collisionPairs
        ]

    def check(
        self,
        q: FloatArray,
        stance: Sequence[LimbContact],
        lifting: Mapping[int, float] | None = None,
    ) -> KeyframeCheck:
        """The check of configuration ``q`` (nq,) holding ``stance``. ``lifting``: shapes of
        effectors that left their contacts (shape index: m, how deep it was then, see
        :meth:`depths`): such a shape may stay that deep (plus ``SWING_SECURITY_MARGIN``),
        as the tracker lets it, not deeper."""
        model, data = self.model, self.data
        pin.framesForwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, self.geometry, self.geometry_data)
        poses = shape_poses(self.geometry_data)
        if self.tracker is not None:
            self.tracker.offer_poses(q, poses)  # its next control step starts from q
        skipped: set[int] = set()
        hold = 0.0
        for contact in stance:
            skipped |= self.effectors[contact.limb]
            frame = data.oMf[self.frame_ids[contact.limb]]
            gap = frame.translation - contact.placement[:3, 3]
            hold = max(hold, float(np.sqrt(gap @ gap)))
        allowed = lifting or {}
        deepest, shape = 0.0, None
        settled = self.distances.settled_at(poses, 0.0)
        placements = self.geometry_data.oMg
        for i, geometry, name in self.shapes:
            if i in skipped or settled[i]:
                continue
            d = self.distances.deepest(geometry, placements[i])
            self.distances.remember(i, d)
            if i in allowed and -d <= allowed[i] + tuning.SWING_SECURITY_MARGIN:
                continue
            if -d > deepest:
                deepest, shape = -d, name
        self_depth, self_pair = 0.0, None
        near = self.broad.near_at(poses, 0.0)
        if near:
            measured = []
            results = None
            for k in near:
                pin.computeDistance(self.geometry, self.geometry_data, k)
                if results is None:
                    results = self.geometry_data.distanceResults
                d = float(results[k].min_distance)
                measured.append(d)
                if -d > self_depth:
                    self_depth, self_pair = -d, self._pair_names[k]
            self.broad.remember_all(near, measured)
        return KeyframeCheck(deepest, shape, self_depth, hold, self_pair)

    def depths(self, q: FloatArray, limbs: Sequence[str]) -> dict[int, float]:
        """Per shape index of the effectors of ``limbs``, m how deep it is in the scene at
        ``q`` (nq,) (0 when clear)."""
        if not limbs:
            return {}
        pin.framesForwardKinematics(self.model, self.data, q)
        pin.updateGeometryPlacements(self.model, self.data, self.geometry, self.geometry_data)
        placements = self.geometry_data.oMg
        out = {}
        for limb in limbs:
            for i in self.effectors[limb]:
                d = self.distances.deepest(self.shapes[i][1], placements[i])
                out[i] = max(0.0, -d)
        return out
