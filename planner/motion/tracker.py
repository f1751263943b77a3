"""Whole-body tracking as a constrained QP per control step (differential IK).

Each step solves, over the configuration step ``dq`` (tangent space),

    min  sum of weighted task errors after the step  +  DAMPING |dq|^2
    s.t. joint position limits, joint speeds <= min(URDF limit, MAX_JOINT_SPEED),
         the root's speed <= ROOT_LINEAR_SPEED, ROOT_ANGULAR_SPEED per axis of its frame
         but ROOT_YAW_SPEED about its z axis (outside a jump's fast phases,
         ``StepTargets.root_bounded``), and there the free limbs' joint accelerations
         <= FREE_LIMB_ACCELERATION (pink's ``AccelerationLimit`` rows),
         collision dampers against the scene and between body parts (``clearance``)

with the tasks, by cost: stance contacts held (dominant), the COM on its curve, the swing
effector on its arc, the trunk's roll and pitch at the planned orientation, and a posture
pull toward the phase's planned configuration. With ``StepTargets.rigid_stance`` (a jump's
stance phases, where the COM moves fast, and a plan's dynamic COM) the stance contacts are
equality constraints instead, ``J_c dq = -e_c`` (position for a point contact, full
placement for a patch): the COM then lags its curve rather than drag a contact. When the QP
has no solution (a damper that cannot be met within the speed limits), the step is retried
without the dampers, then (rigid stance) with the contacts back in the cost, then skipped
(the body holds still).

The QP is pink's (its FrameTask, ComTask and PostureTask costs, ConfigurationLimit and
VelocityLimit rows) assembled here: the kinematics (joint placements and Jacobians, frames,
COM and its Jacobian) computed once per step and the task rows stacked with numpy, about
1.3x cheaper per step than ``pink.build_ik``, whose tasks recompute them
(``bench/tracker.py``); ``tests/planner/motion/test_tracker_qp.py`` checks that H, c, G, h,
A, b equal ``build_ik``'s to 1e-9. daqp solves it directly, the limit rows (rows of the
identity) given as bounds on dq.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import daqp
import numpy as np
import pinocchio as pin
import qpsolvers
from numpy.typing import NDArray
from pink.limits import AccelerationLimit, ConfigurationLimit, VelocityLimit
from scipy.spatial.transform import Rotation

from planner.character import Character
from planner.kinematics.model import signed_geometry_data
from planner.motion import tuning
from planner.motion.clearance import (
    PointJacobians,
    Poses,
    SceneClearance,
    SelfClearance,
    shape_poses,
    support_masks,
)
from planner.motion.spec import torso_columns

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_UPRIGHT = math.cos(1e-3)  # a trunk target this close to upright is upright
_WORLD_UP = np.array([0.0, 0.0, 1.0])
_COS_TILT_WATCH = math.cos(tuning.TILT_WATCH)
_COS_MAX_TILT = math.cos(tuning.MAX_TILT)
_COS_CHEST_WATCH = math.cos(tuning.MAX_CHEST_TILT - (tuning.MAX_TILT - tuning.TILT_WATCH))
_COS_MAX_CHEST_TILT = math.cos(tuning.MAX_CHEST_TILT)
_DAQP_EQUALITY = 5  # daqp's constraint sense of an equality row
# daqp's constraint sense type (numpy converts a ctypes type to a dtype slowly: once here)
_DAQP_SENSE = np.dtype(ctypes.c_int)


@dataclass(frozen=True, slots=True)
class StepTargets:
    """What one control step aims at (world frame).

    stance : (limb, effector pose (4, 4)) held. com : (3,) m. swing : (limb, pose (4, 4))
    or None. posture : (nq,) pulled toward; its root orientation is the trunk target.
    swing_guarded : whether the swinging effector's own shapes are kept off the scene (a last
    resort lets a swing that cannot land otherwise through: the checker still counts it).
    level_trunk : the trunk aims at the posture's yaw only (and its pitch for a character
    whose trunk may pitch); otherwise at the posture's own roll and pitch.
    carried : (limb, pose (4, 4)) effectors carried through a flight, or swinging ahead of
    their landing phase (an overlapping swing, ``MotionPhase.early``): swing cost, guarded
    like a swing. exact_com : a flight: the COM moves to ``com`` as an equality of the QP
    (``StepQP.com_move``) and the whole body is translated onto it after the step (the
    linearisation's residue).
    com_reach : m, the COM target is pulled in to this distance from the COM
    (``COM_MAX_ERROR``; unbounded for a fast COM). rigid_stance : the stance contacts are
    equality constraints of the QP, not costs. posture_led : the posture is a moving
    target the joints track dead-beat (``TASK_GAIN``, unsaturated) at ``JUMP_POSTURE_COST``
    (a jump's push and landing, led along the whole-body IK's crouch), instead of a
    gentle pull (``POSTURE_GAIN``, ``POSTURE_MAX_ERROR``) at ``POSTURE_COST``.
    swing_settle : share (0 to 1) of the swing's landing settle (``LANDING_SETTLE_S``) gone
    by: the effector's cost rises from the swing's to ``SETTLE_COST`` with it (and as it
    comes within ``SETTLE_REACH`` of its landing), so that it is pulled onto the contact it is
    about to hold (0 before its arc has landed).
    """

    stance: tuple[tuple[str, FloatArray], ...]
    com: FloatArray
    swing: tuple[str, FloatArray] | None
    posture: FloatArray
    swing_guarded: bool = True
    level_trunk: bool = True
    carried: tuple[tuple[str, FloatArray], ...] = ()
    exact_com: bool = False
    com_reach: float = tuning.COM_MAX_ERROR
    rigid_stance: bool = False
    root_bounded: bool = True
    posture_led: bool = False
    swing_settle: float = 0.0


def effector_geometries(character: Character) -> dict[str, frozenset[int]]:
    """Per limb, the collision shapes (geometry indices) of its effector: those on the
    effector frame and the frames rigidly attached below it (a foot link after a fixed
    joint); when none carries a shape, those of the nearest frame above it on the same joint
    that does (a sole frame under the foot link). The rest of the limb (a shin) is checked
    against the scene like any other link, in stance too."""
    model = character.model
    frames = model.frames
    shapes_of: dict[int, set[int]] = {}
    for i, o in enumerate(character.motion_geometry.geometryObjects):
        shapes_of.setdefault(int(o.parentFrame), set()).add(i)
    out = {}
    for limb in character.limbs:
        frame = int(limb.frame_id)
        joint = int(frames[frame].parentJoint)
        below = {frame}
        for k in range(frame + 1, len(frames)):
            if int(frames[k].parentFrame) in below and int(frames[k].parentJoint) == joint:
                below.add(k)
        found = set().union(*(shapes_of.get(k, set()) for k in below))
        up = frame
        while not found and up > 0 and int(frames[up].parentJoint) == joint:
            up = int(frames[up].parentFrame)
            if int(frames[up].parentJoint) == joint:
                found = shapes_of.get(up, set())
        out[limb.name] = frozenset(found)
    return out


def speed_limits(model: Any, root_bounded: bool = False) -> FloatArray:
    """(nv,) rad/s: each joint's URDF velocity limit capped at ``MAX_JOINT_SPEED`` (joints
    without a limit get the cap). The free-flyer root (its local frame) is left unbounded,
    or with ``root_bounded`` held to ``ROOT_LINEAR_SPEED`` m/s and ``ROOT_ANGULAR_SPEED``
    rad/s per axis (``ROOT_YAW_SPEED`` about its z axis)."""
    limits = np.array(model.velocityLimit, dtype=np.float64)
    root = int(model.joints[1].nv) if model.njoints > 1 and model.joints[1].nq == 7 else 0
    joints = limits[root:]
    joints[~(joints > 0)] = tuning.MAX_JOINT_SPEED
    limits[root:] = np.minimum(joints, tuning.MAX_JOINT_SPEED)
    if root:
        limits[:3] = tuning.ROOT_LINEAR_SPEED if root_bounded else np.inf
        turning = (tuning.ROOT_ANGULAR_SPEED,) * 2 + (tuning.ROOT_YAW_SPEED,)
        limits[3:6] = turning if root_bounded else np.inf
    return limits


def trunk_orientation_cost(character: Character) -> float:
    """Weight (per rad) of the trunk task's roll and pitch for ``character``: a level trunk
    is held firmer than one that pitches with the terrain (``tuning.TRUNK_COST``,
    ``tuning.PITCHING_TRUNK_COST``)."""
    if character.max_pitch <= tuning.LEVEL_TRUNK_PITCH:
        return tuning.TRUNK_COST
    return tuning.PITCHING_TRUNK_COST


def _nonzero(
    position: float | Sequence[float], orientation: float | Sequence[float]
) -> tuple[FloatArray, IntArray | slice]:
    """The nonzero weights of a frame task's six error rows (position then orientation
    costs, each a scalar or (3,)) and their row indices (a slice when they are consecutive:
    the same rows, without a copy): rows of cost 0 add nothing to the QP."""
    costs = np.concatenate([np.broadcast_to(position, 3), np.broadcast_to(orientation, 3)])
    keep = np.flatnonzero(costs)
    weights = np.asarray(costs[keep], dtype=np.float64)
    if len(keep) and np.array_equal(keep, np.arange(keep[0], keep[0] + len(keep))):
        return weights, slice(int(keep[0]), int(keep[0]) + len(keep))
    return weights, keep


@dataclass(frozen=True, slots=True)
class StepQP:
    """The cost of one control step's QP over dq (tangent): 1/2 dq' H dq + c' dq with
    ``hessian`` H (nv, nv) and ``linear`` c (nv,); ``held``: per stance limb, its frame
    task's Jacobian (6, nv) and error (6,) (for rigid contacts); ``com_move``: a flight's
    COM held to its curve exactly, ``J_com dq = c_target - c`` (J_com (3, nv), (3,) m)."""

    hessian: FloatArray
    linear: FloatArray
    held: dict[str, tuple[FloatArray, FloatArray]]
    com_move: tuple[FloatArray, FloatArray] | None = None


def _saturated(here: FloatArray, target: FloatArray, reach: float) -> FloatArray:
    """``target`` (3,) moved toward ``here`` (3,) to at most ``reach`` m from it."""
    gap = np.asarray(target, dtype=np.float64) - here
    norm = math.sqrt(float(gap @ gap))  # np.linalg.norm's own arithmetic, without its cost
    if norm <= reach:
        return np.array(target, dtype=np.float64)
    return np.asarray(here + gap * (reach / norm), dtype=np.float64)


def _position_limited(model: Any) -> BoolArray:
    """(nv,) whether each tangent index belongs to a joint with finite position limits (the
    joints that must brake before them), as pink's ``AccelerationLimit`` decides it."""
    limit = AccelerationLimit(model, np.ones(model.nv))
    out = np.zeros(model.nv, dtype=bool)
    out[limit.indices] = limit.has_configuration_limit
    return out


@dataclass(frozen=True, slots=True, eq=False)
class _CharacterTerms:
    """What a tracker needs of its character that no step changes, computed once per
    character (its arrays read-only): the effectors' shapes, the frame ids, the tasks'
    nonzero-cost weights and rows, pink's ConfigurationLimit and VelocityLimit rows (per
    root bound: True, the root's speed bounded) and the cost's constant diagonal."""

    effectors: dict[str, frozenset[int]]
    frame_ids: dict[str, int]
    stance_weights: dict[str, tuple[FloatArray, IntArray | slice]]
    swing_weights: dict[str, tuple[FloatArray, IntArray | slice]]
    settle_weights: dict[str, tuple[FloatArray, IntArray | slice]]
    rigid_keep: dict[str, slice]
    trunk_weights: FloatArray
    trunk_keep: IntArray | slice
    config: IntArray
    config_gain: float
    g_limits: dict[bool, FloatArray]
    speeds: dict[bool, FloatArray]
    speed_index: dict[bool, IntArray]
    root_nv: int
    bounded: IntArray
    joints: slice
    lower: FloatArray
    upper: FloatArray
    lower_limit: FloatArray
    upper_limit: FloatArray
    diagonal_terms: FloatArray
    posture_weights: FloatArray
    limb_columns: dict[str, frozenset[int]]
    braking: BoolArray
    chest: int | None
    chest_limbs: frozenset[str]


def _carried_limbs(character: Character, joint: int) -> frozenset[str]:
    """The limbs whose effectors ``joint``'s subtree carries."""
    model = character.model
    subtree = set(model.subtrees[joint])
    return frozenset(
        limb.name
        for limb in character.limbs
        if int(model.frames[limb.frame_id].parentJoint) in subtree
    )


def chest_joint(character: Character) -> int | None:
    """The joint id of the character's chest: the deepest joint of no limb (not the root)
    whose subtree carries two limbs' effectors or more (a humanoid's torso pitch, under its
    arms); None when only the root carries two (a quadruped's, a hexapod's trunk)."""
    model = character.model
    in_limbs = {int(j) for limb in character.limbs for j in limb.joint_ids}
    best: int | None = None
    for joint in range(2, model.njoints):
        deeper = best is None or len(model.subtrees[joint]) < len(model.subtrees[best])
        if joint not in in_limbs and deeper and len(_carried_limbs(character, joint)) >= 2:
            best = joint
    return best


_TERMS: dict[int, tuple[Character, _CharacterTerms]] = {}


def _read_only(array: Any) -> Any:
    array.flags.writeable = False
    return array


def _character_terms(character: Character) -> _CharacterTerms:
    """The :class:`_CharacterTerms` of ``character``, memoised per character object."""
    hit = _TERMS.get(id(character))
    if hit is not None and hit[0] is character:
        return hit[1]
    model = character.model
    # per task the weights of its error's nonzero-cost rows (pink's FrameTask costs:
    # position then orientation, in the frame), and those rows' indices
    stance_weights: dict[str, tuple[FloatArray, IntArray | slice]] = {}
    swing_weights: dict[str, tuple[FloatArray, IntArray | slice]] = {}
    settle_weights: dict[str, tuple[FloatArray, IntArray | slice]] = {}
    rigid_keep: dict[str, slice] = {}
    for limb in character.limbs:
        patch = limb.contact == "patch"
        stance_weights[limb.name] = _nonzero(
            tuning.STANCE_COST, tuning.STANCE_COST if patch else 0.0
        )
        swing_weights[limb.name] = _nonzero(
            tuning.SWING_POSITION_COST, tuning.SWING_ORIENTATION_COST if patch else 0.0
        )
        settle_weights[limb.name] = _nonzero(
            tuning.SETTLE_COST, tuning.SETTLE_COST if patch else 0.0
        )
        rigid_keep[limb.name] = slice(0, 6) if patch else slice(0, 3)
    trunk_cost = trunk_orientation_cost(character)
    trunk_weights, trunk_keep = _nonzero(
        [0.0, 0.0, tuning.TRUNK_HEIGHT_COST], [trunk_cost, trunk_cost, 0.0]
    )
    config = ConfigurationLimit(model)
    g_limits: dict[bool, FloatArray] = {}
    speeds: dict[bool, FloatArray] = {}
    speed_index: dict[bool, IntArray] = {}
    for bounded in (False, True):
        velocity = VelocityLimit(model, speed_limits(model, root_bounded=bounded))
        speeds[bounded] = np.asarray(velocity.velocity_limit[velocity.indices], dtype=np.float64)
        speed_index[bounded] = np.asarray(velocity.indices, dtype=np.int64)
        blocks = [config.projection_matrix, velocity.projection_matrix]
        g_limits[bounded] = np.vstack([x for m in blocks if m is not None for x in (m, -m)])
    root_nq = 7 if model.joints[1].nq == 7 else 0
    root_nv = 6 if root_nq else 0
    # the cost's constant diagonal: the posture task's weight on the joints (its Jacobian
    # is the identity there) and the damping everywhere
    posture_weights = np.full(model.nv - root_nv, tuning.POSTURE_COST**2)
    torso = [i - root_nv for i in torso_columns(character, root_nv)]
    posture_weights[torso] = tuning.TORSO_POSTURE_COST**2
    diagonal = np.full(model.nv, tuning.DAMPING)
    diagonal[root_nv:] += posture_weights
    arrays = [trunk_weights, trunk_keep, *speeds.values(), *speed_index.values()]
    arrays += [*g_limits.values(), *(x for pair in stance_weights.values() for x in pair)]
    arrays += [x for pair in swing_weights.values() for x in pair]
    arrays += [x for pair in settle_weights.values() for x in pair]
    for array in arrays:
        if isinstance(array, np.ndarray):
            _read_only(array)
    chest = chest_joint(character)
    terms = _CharacterTerms(
        effectors=effector_geometries(character),
        frame_ids={limb.name: int(limb.frame_id) for limb in character.limbs},
        stance_weights=stance_weights,
        swing_weights=swing_weights,
        settle_weights=settle_weights,
        rigid_keep=rigid_keep,
        trunk_weights=trunk_weights,
        trunk_keep=trunk_keep,
        config=_read_only(np.asarray(config.indices, dtype=np.int64)),
        config_gain=float(config.config_limit_gain),
        g_limits=g_limits,
        speeds=speeds,
        speed_index=speed_index,
        root_nv=root_nv,
        bounded=_read_only(np.arange(root_nq, model.nq)),
        joints=slice(root_nq, None),
        lower=_read_only(np.array(model.lowerPositionLimit[root_nq:], dtype=np.float64)),
        upper=_read_only(np.array(model.upperPositionLimit[root_nq:], dtype=np.float64)),
        lower_limit=_read_only(np.array(model.lowerPositionLimit, dtype=np.float64)),
        upper_limit=_read_only(np.array(model.upperPositionLimit, dtype=np.float64)),
        diagonal_terms=_read_only(np.diag(diagonal)),
        posture_weights=_read_only(posture_weights),
        limb_columns={limb.name: frozenset(int(i) for i in limb.idx_v) for limb in character.limbs},
        braking=_read_only(_position_limited(model)),
        chest=chest,
        chest_limbs=frozenset() if chest is None else _carried_limbs(character, chest),
    )
    if len(_TERMS) >= 64:
        _TERMS.clear()
    _TERMS[id(character)] = (character, terms)
    return terms


class WholeBodyTracker:
    """One character in one scene; :meth:`step` moves a configuration one control step.

    ``obstacles`` are (coal geometry, coal.Transform3s) pairs the body avoids besides the
    scene (other characters). ``data`` (pin.Data) and ``geometry_data``
    (pin.GeometryData of the motion geometry, distance requests signed), when given, are the
    tracker's alone for its life. Not thread-safe: one per thread.
    """

    def __init__(
        self,
        character: Character,
        scene_bvh: Any,
        obstacles: Sequence[tuple[Any, Any]] = (),
        data: Any = None,
        geometry_data: Any = None,
    ) -> None:
        self.character = character
        model = character.model
        self.model = model
        # pin.Data for its kinematics: ``data`` (lent by the caller for the tracker's life)
        # or its own
        self.data = model.createData() if data is None else data
        terms = _character_terms(character)
        self.effectors = terms.effectors
        self._root_frame = 1
        self._frame_ids = terms.frame_ids
        self._stance_weights = terms.stance_weights
        self._swing_weights = terms.swing_weights
        self._settle_weights = terms.settle_weights
        self._rigid_keep = terms.rigid_keep
        self._trunk_weights, self._trunk_keep = terms.trunk_weights, terms.trunk_keep
        # pin.GeometryData of the motion geometry, distance requests signed: lent by the
        # caller for the tracker's life, or its own
        self.geometry_data = (
            signed_geometry_data(character.motion_geometry)
            if geometry_data is None
            else geometry_data
        )
        self.scene = SceneClearance(model, character.motion_geometry, scene_bvh, obstacles)
        self.self_clearance = SelfClearance(model, character.motion_geometry)
        self._config = terms.config
        self._config_gain = terms.config_gain
        self._g_limits = terms.g_limits
        self._speeds = terms.speeds
        self._speed_index = terms.speed_index
        self.fallbacks = 0
        self._lift_off: dict[str, dict[int, float]] = {}
        self._trunk_cache: dict[tuple[bool, bytes], FloatArray] = {}
        self._held: dict[int, tuple[FloatArray, Any]] = {}
        self._root_nv = terms.root_nv
        self._bounded = terms.bounded
        self._joints = terms.joints
        self._lower, self._upper = terms.lower, terms.upper
        self._joint_speeds = speed_limits(model)[terms.root_nv :]
        self._lower_limit, self._upper_limit = terms.lower_limit, terms.upper_limit
        self._unbounded = np.full(model.nv, 1e30)  # the bound of an unbounded dq
        self._diagonal_terms = terms.diagonal_terms
        self._posture_weights = terms.posture_weights
        self._limb_columns = terms.limb_columns
        self._braking = terms.braking
        self.q = pin.neutral(model)
        # the velocity (nv,) of the last control step (rad/s, m/s in the root's frame): the
        # free limbs' acceleration bound counts from it
        self.velocity = np.zeros(model.nv)
        # the free limbs' tangent indices of the last objective, memoised per set of limbs
        # in use
        self._free: IntArray = np.zeros(0, dtype=np.int64)
        self._free_of: dict[frozenset[str], IntArray] = {}
        # kinematics stamps: of the last objective, of the last shape placements
        self._stamp = 0
        self._placed = -1
        self._poses: Poses = (np.zeros((0, 3, 3)), np.zeros((0, 3)))
        self._masks = support_masks(model)
        self._jacobians = PointJacobians(model, self.data, self._masks)
        # shape placements computed elsewhere at a configuration (:meth:`offer_poses`)
        self._offered: tuple[FloatArray, Poses] | None = None
        # the trunk tilt bound of the last objective, if the trunk aims upright and leans,
        # and the chest's, if the character has one and it leans
        self._tilt_row: tuple[FloatArray, FloatArray] | None = None
        # the chest and the limbs it carries (a humanoid's arms): while one holds or reaches
        # for a contact (a handrail, a climbing hold), the chest leans as that contact needs
        self._chest, self._chest_limbs = terms.chest, terms.chest_limbs
        self._chest_row: tuple[FloatArray, FloatArray] | None = None

    def trunk_rotation(self, posture: FloatArray, level: bool = True) -> FloatArray:
        """(3, 3) trunk orientation aimed at from a planned configuration (nq,): with
        ``level``, its yaw, and its pitch only for a character whose trunk may pitch (a
        hexapod on a slope), never a roll; otherwise its own orientation. Memoised per
        posture (a phase keeps its posture for many steps)."""
        key = (level, posture[3:7].tobytes())
        cached = self._trunk_cache.get(key)
        if cached is None:
            rotation = pin.Quaternion(posture[3:7]).toRotationMatrix()
            if level:
                yaw, pitch, _ = Rotation.from_matrix(rotation).as_euler("ZYX")
                if self.character.max_pitch <= tuning.LEVEL_TRUNK_PITCH:
                    pitch = 0.0
                rotation = Rotation.from_euler("ZY", [yaw, pitch]).as_matrix()
            cached = np.asarray(rotation, dtype=np.float64)
            cached.flags.writeable = False
            if len(self._trunk_cache) > 4096:
                self._trunk_cache.clear()
            self._trunk_cache[key] = cached
        return cached

    def reset(self, velocity: FloatArray | None = None) -> None:
        """Forget what earlier steps left (remembered witnesses, the lift-off depths): the
        next step starts a fresh track, from ``velocity`` (nv,) (the motion's velocity where
        the track starts; at rest when None)."""
        self.scene.memory.clear()
        self._lift_off = {}
        if velocity is None:
            self.velocity = np.zeros(self.model.nv)
        else:
            self.velocity = np.array(velocity, dtype=np.float64)

    def _free_columns(self, in_use: frozenset[str]) -> IntArray:
        """The tangent indices (sorted) of the joints of the limbs not ``in_use`` (holding a
        contact, swinging or carried) that no limb in use moves as well (a humanoid's seat
        shares its leg's joints)."""
        hit = self._free_of.get(in_use)
        if hit is None:
            free: set[int] = set()
            for limb, columns in self._limb_columns.items():
                if limb not in in_use:
                    free |= columns
            for limb in in_use:
                free -= self._limb_columns[limb]
            hit = _read_only(np.array(sorted(free), dtype=np.int64))
            self._free_of[in_use] = hit
        return hit

    def _swing_security(self, limbs: Sequence[str]) -> dict[int, float]:
        """Security distance (m) of each shape of the swinging (or carried) ``limbs``'
        effectors: never deeper than where it lifted off (a real robot's foot capsule may
        hang under the sole by design), nor than ``SWING_SECURITY_DISTANCE``; measured when
        the limb starts moving, forgotten when it stops."""
        for limb in [k for k in self._lift_off if k not in limbs]:
            del self._lift_off[limb]
        security: dict[int, float] = {}
        for limb in limbs:
            if limb not in self._lift_off:
                depths = self.scene.depths(self.data, self.effectors[limb])
                self._lift_off[limb] = {
                    i: min(tuning.SWING_SECURITY_DISTANCE, d - tuning.SWING_SECURITY_MARGIN)
                    for i, d in depths.items()
                }
            security.update(self._lift_off[limb])
        return security

    def _onto_com(self, q: FloatArray, com: FloatArray) -> FloatArray:
        """``q`` (nq,) translated so that its COM is ``com`` (3,) m (a floating base moves
        every body by its own translation)."""
        here = pin.centerOfMass(self.model, self.data, q, False)
        out = np.array(q, dtype=np.float64)
        out[:3] += np.asarray(com, dtype=np.float64) - here
        return out

    def step(
        self, q: FloatArray, targets: StepTargets, dt: float, share: float = 1.0
    ) -> FloatArray:
        """The configuration (nq,) one control step of ``dt`` s after ``q`` (nq,).
        ``share`` : this step is that fraction of a nominal control step (finer steps, as
        ``FAST_SUBSTEPS``): the gentle trunk and posture pulls, which are fractions per step,
        are scaled so that they converge as fast per second as with nominal steps."""
        q = np.array(q, dtype=np.float64)
        joints = self._joints
        q[joints] = np.minimum(np.maximum(q[joints], self._lower), self._upper)
        # a flight's COM moves along its curve as a constraint of the QP (``com_move``), so
        # that the collision dampers see the whole body's fall; translated onto the curve
        # before the step, a body falling past a platform's corner drove its legs 240 mm
        # into it, unseen
        qp = self.objective(q, targets, share)
        rigid = [limb for limb, _ in targets.stance] if targets.rigid_stance else []
        # (dampers, contacts hard, free limbs' acceleration bounded): the acceleration bound
        # yields first (a hand let go of a wall must get off it), then the dampers, with the
        # bound tried again without them (a phase's first step whose dampers could not be
        # met flung Talos's free arms at 38 rad/s^2)
        attempts = [(True, True, True)]
        if self._free.size and targets.root_bounded:
            attempts += [(True, True, False), (False, True, True)]
        attempts.append((False, True, False))
        if rigid:
            attempts += [(True, False, False), (False, False, False)]
        for dampers, hard, smooth in attempts:
            velocity = self._solve(
                qp, dt, dampers, targets.root_bounded, rigid if hard else [], smooth
            )
            if velocity is None:
                self.fallbacks += 1
                continue
            self.velocity = velocity
            q = np.asarray(pin.integrate(self.model, q, velocity * dt), dtype=np.float64)
            return self._onto_com(q, targets.com) if targets.exact_com else q
        self.velocity = np.zeros(self.model.nv)
        return np.array(q, dtype=np.float64)

    def hold_stance(
        self,
        q: FloatArray,
        stance: Sequence[tuple[str, FloatArray]],
        reference: FloatArray | None = None,
        dt: float = 0.0,
    ) -> FloatArray:
        """``q`` (nq,) moved by the smallest steps (damped least norm over the tangent space,
        ``HOLD_STANCE_ITERATIONS`` Gauss-Newton steps at most) that put the ``stance``
        effectors (limb, pose (4, 4)) back on their contacts: the second-order drift that a
        control step's linearised contact rows leave (millimetres) is taken out once per
        keyframe, without the QP. The joints stay within their position limits and, given the
        previous keyframe ``reference`` (nq,) ``dt`` s before, within their speed limits from
        it; a joint at a bound does not take part, and a step that does not lower the squared
        contact error is not taken."""
        if not stance:
            return q
        model, data = self.model, self.data
        lower, upper = self._lower, self._upper
        if reference is not None:
            reach = dt * self._joint_speeds
            lower = np.maximum(lower, reference[self._joints] - reach)
            upper = np.minimum(upper, reference[self._joints] + reach)
        kept = out = np.array(q, dtype=np.float64)
        best = math.inf
        held = [
            (self._frame_ids[limb], self._held_target(pose), self._stance_weights[limb][1])
            for limb, pose in stance
        ]
        oMf = data.oMf
        for iteration in range(tuning.HOLD_STANCE_ITERATIONS + 1):
            # the placements first: the Jacobians only when a step is taken (the frame
            # placements are the same ones computeJointJacobians then recomputes)
            pin.framesForwardKinematics(model, data, out)
            errors = [
                pin.log6(oMf[frame].actInv(target)).vector[keep] for frame, target, keep in held
            ]
            err = np.concatenate(errors)
            squared = float(err @ err)
            if squared >= best:
                break  # the last step did not help: ``kept`` stays
            best, kept = squared, out
            if squared < tuning.HOLD_STANCE_TOLERANCE**2:
                break
            if iteration < tuning.HOLD_STANCE_ITERATIONS:
                pin.computeJointJacobians(model, data, out)
                rows = [self._frame_jacobian(frame, target)[keep] for frame, target, keep in held]
                out = self._hold_step(out, np.concatenate(rows), err, lower, upper)
        self._stamp += 1
        return kept

    def _hold_step(
        self, q: FloatArray, jac: FloatArray, err: FloatArray, lower: FloatArray, upper: FloatArray
    ) -> FloatArray:
        """``q`` (nq,) after the damped least-norm step ``dq`` with ``jac @ dq = -err``
        (``jac`` (m, nv), ``err`` (m,)), joints that the step would push past their bounds
        ``lower``, ``upper`` (rad, one per joint) held where they are (the step found again
        without them), and clipped to them if that is not enough."""
        model = self.model
        free = np.ones(model.nv, dtype=bool)
        for _ in range(2):
            active = jac[:, free]
            gram = active @ active.T
            gram.flat[:: len(gram) + 1] += tuning.HOLD_STANCE_DAMPING  # the diagonal
            step = np.zeros(model.nv)
            step[free] = -(active.T @ np.linalg.solve(gram, err))
            out = np.asarray(pin.integrate(model, q, step), dtype=np.float64)
            joints = out[self._joints]
            over = (joints < lower) | (joints > upper)
            if not over.any():
                return out
            free[self._root_nv :] &= ~over
        out[self._joints] = np.minimum(np.maximum(out[self._joints], lower), upper)
        return out

    def objective(self, q: FloatArray, targets: StepTargets, share: float = 1.0) -> StepQP:
        """The kinematics at ``q`` (nq,) (joint placements and Jacobians, frames, COM and
        its Jacobian, each computed once) and the QP cost of the step toward ``targets``:
        ``H`` (nv, nv) and ``c`` (nv,) over the step dq (tangent, rad or m), equal to pink's
        ``build_ik`` on the same tasks (``tests/planner/motion/test_tracker_qp.py``)."""
        model, data = self.model, self.data
        self.q = q
        jcom = pin.jacobianCenterOfMass(model, data, q)
        pin.updateFramePlacements(model, data)
        self._stamp += 1
        rows: list[FloatArray] = []
        errors: list[FloatArray] = []
        skipped: set[int] = set()
        held: dict[str, tuple[FloatArray, FloatArray]] = {}
        for limb, pose in targets.stance:
            jac, err = self._frame_error(self._frame_ids[limb], self._held_target(pose))
            held[limb] = (jac, err)
            weights, keep = self._stance_weights[limb]
            rows.append(weights[:, None] * jac[keep])
            errors.append(weights * (-tuning.TASK_GAIN * err[keep]))
            skipped |= self.effectors[limb]
        moving = [] if targets.swing is None else [targets.swing]
        moving += list(targets.carried)
        for n, (limb, pose) in enumerate(moving):
            frame = self._frame_ids[limb]
            goal = _saturated(data.oMf[frame].translation, pose[:3, 3], tuning.SWING_MAX_ERROR)
            jac, err = self._frame_error(frame, pin.SE3(pose[:3, :3], goal))
            weights, keep = self._swing_weights[limb]
            if n == 0 and targets.swing is not None and targets.swing_settle > 0.0:
                # seated as a contact once near it; an effector still far (held back, now
                # catching up) must not drag the stance contacts
                gap = float(np.linalg.norm(data.oMf[frame].translation - pose[:3, 3]))
                near = max(0.0, 1.0 - gap / tuning.SETTLE_REACH)
                seat = min(1.0, targets.swing_settle) * near
                weights = weights + seat * (self._settle_weights[limb][0] - weights)
            rows.append(weights[:, None] * jac[keep])
            errors.append(weights * (-tuning.TASK_GAIN * err[keep]))
        guarded = [limb for limb, _ in targets.carried]
        if targets.swing is not None:
            if targets.swing_guarded:
                guarded.insert(0, targets.swing[0])
            else:
                skipped |= self.effectors[targets.swing[0]]
        light = self._swing_security(guarded)
        in_use = [limb for limb, _ in targets.stance] + [limb for limb, _ in moving]
        self._free = self._free_columns(frozenset(in_use))
        com = np.array(data.com[0])
        goal = _saturated(com, np.asarray(targets.com, dtype=np.float64), targets.com_reach)
        rows.append(tuning.COM_COST * jcom)
        errors.append(tuning.COM_COST * (-tuning.TASK_GAIN * (com - goal)))
        posture = np.asarray(targets.posture, dtype=np.float64)
        trunk = self.trunk_rotation(posture, targets.level_trunk)
        gain = 1.0 - (1.0 - tuning.TRUNK_GAIN) ** share
        jac, err = self._frame_error(self._root_frame, pin.SE3(trunk, posture[:3]))
        rows.append(self._trunk_weights[:, None] * jac[self._trunk_keep])
        errors.append(self._trunk_weights * (-gain * err[self._trunk_keep]))
        upright = targets.level_trunk and trunk[2, 2] > _UPRIGHT
        # a flight's trunk stays near its aim (the landing's), as an upright one near the
        # vertical: dodging a ledge with its legs, the hexapod pitched 86 degrees mid-air
        aim = _WORLD_UP if upright else trunk[:, 2] if targets.exact_com else None
        self._tilt_row = self._tilt_bound(aim) if aim is not None else None
        free_chest = upright and not any(limb in self._chest_limbs for limb in in_use)
        self._chest_row = self._chest_bound() if free_chest else None
        stacked = np.concatenate(rows)  # 2-D blocks: vstack's result, without its checks
        hessian = stacked.T @ stacked
        linear = -(np.concatenate(errors) @ stacked)
        # the posture task's Jacobian is the identity on the joints: its terms are diagonal.
        # Each joint is pulled at most POSTURE_MAX_ERROR toward its posture per step: summed
        # over thirty joints, a far posture would otherwise outweigh the stance contacts
        joints = self._joints
        aim = q.copy()
        hessian += self._diagonal_terms
        # the constant diagonal holds the posture weights of ``_posture_weights`` (the torso's
        # firmer); a jump's posture-led step and a step's free limbs weigh otherwise
        base = self._posture_weights
        if targets.posture_led:
            aim[joints] = posture[joints]
            gain = tuning.TASK_GAIN
            weights = np.full(base.shape, tuning.JUMP_POSTURE_COST**2)
        else:
            reach = tuning.POSTURE_MAX_ERROR * share
            aim[joints] = q[joints] + np.minimum(
                np.maximum(posture[joints] - q[joints], -reach), reach
            )
            gain = 1.0 - (1.0 - tuning.POSTURE_GAIN) ** share
            weights = base.copy()
            weights[self._free - self._root_nv] = tuning.FREE_LIMB_POSTURE_COST**2
        np.einsum("ii->i", hessian)[self._root_nv :] += weights - base  # a view of the diagonal
        pull = pin.difference(model, aim, q)[self._root_nv :]
        linear[self._root_nv :] += weights * gain * pull
        self.scene.set_phase(frozenset(skipped), light)
        com_move = (jcom.copy(), targets.com - com) if targets.exact_com else None
        return StepQP(hessian, linear, held, com_move)

    def _tilt_bound(self, aim: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """The row (G (1, nv), h (1,)) keeping the trunk's tilt (its z axis from ``aim``
        (3,), a world unit axis: the vertical for an upright trunk) under ``MAX_TILT``,
        velocity-damper form on cos(tilt), at the kinematics of the last :meth:`objective`;
        None while the tilt is under ``TILT_WATCH``."""
        rotation = self.data.oMf[self._root_frame].rotation
        up = rotation.T @ aim  # the aimed axis in the trunk's frame
        cos_tilt = float(up[2])
        if cos_tilt > _COS_TILT_WATCH:
            return None
        row = np.zeros((1, self.model.nv))
        # d cos(tilt) = omega . (e_z x up), omega the trunk's angular step (its frame)
        row[0, 3:6] = -np.array([-up[1], up[0], 0.0])
        return row, np.array([tuning.TILT_GAIN * (cos_tilt - _COS_MAX_TILT)])

    def _chest_bound(self) -> tuple[FloatArray, FloatArray] | None:
        """The row (G (1, nv), h (1,)) keeping the chest's tilt from the vertical under
        ``MAX_CHEST_TILT`` as :meth:`_tilt_bound` keeps the trunk's (watched from as far
        under it); None without a chest or while it leans less. Asked for only while the
        trunk aims upright and no limb the chest carries holds or seeks a contact."""
        if self._chest is None:
            return None
        up = self.data.oMi[self._chest].rotation[2, :]  # the vertical in the chest's frame
        cos_tilt = float(up[2])
        if cos_tilt > _COS_CHEST_WATCH:
            return None
        local = pin.getJointJacobian(self.model, self.data, self._chest, pin.LOCAL)
        row = -np.array([-up[1], up[0], 0.0]) @ local[3:6]
        gain = tuning.TILT_GAIN * (cos_tilt - _COS_MAX_CHEST_TILT)
        return row[None, :], np.array([gain])

    def _held_target(self, pose: FloatArray) -> Any:
        """``pose`` (4, 4) as a pin.SE3, made once per stance placement (a phase holds the
        same contact placements for all its steps)."""
        hit = self._held.get(id(pose))
        if hit is None or hit[0] is not pose:
            if len(self._held) > 256:
                self._held.clear()
            hit = (pose, pin.SE3(pose[:3, :3], pose[:3, 3]))
            self._held[id(pose)] = hit
        return hit[1]

    def _frame_error(self, frame: int, target: Any) -> tuple[FloatArray, FloatArray]:
        """Jacobian (6, nv) and error (6,) of a frame task (pink's ``FrameTask``: the error
        is the twist, in the frame, from the frame's pose to the ``target`` pose (pin.SE3,
        world))."""
        here = self.data.oMf[frame]
        error = pin.log6(here.actInv(target)).vector
        local = pin.getFrameJacobian(self.model, self.data, frame, pin.LOCAL)
        jac = -pin.Jlog6(target.actInv(here)) @ local
        return jac, error

    def _frame_jacobian(self, frame: int, target: Any) -> FloatArray:
        """The Jacobian (6, nv) of :meth:`_frame_error`, without its error."""
        here = self.data.oMf[frame]
        local = pin.getFrameJacobian(self.model, self.data, frame, pin.LOCAL)
        return np.asarray(-pin.Jlog6(target.actInv(here)) @ local, dtype=np.float64)

    def inequalities(
        self, dt: float, dampers: bool, root_bounded: bool, smooth: bool = True
    ) -> tuple[FloatArray, FloatArray]:
        """``G dq <= h`` at the kinematics of the last :meth:`objective`: joint position
        limits (pink's ``ConfigurationLimit`` rows), speed limits (``VelocityLimit``), with
        ``smooth`` the free limbs' acceleration bound (``AccelerationLimit``,
        :meth:`_acceleration_window`), then with ``dampers`` the scene and self-collision
        dampers (``clearance``) and the trunk's tilt bound (:meth:`_tilt_bound`)."""
        q = self.q
        gain = self._config_gain
        h_config = np.concatenate(
            [
                gain * pin.difference(self.model, q, self._upper_limit)[self._config],
                -gain * pin.difference(self.model, q, self._lower_limit)[self._config],
            ]
        )
        speeds = self._speeds[root_bounded]
        g_blocks = [self._g_limits[root_bounded]]
        h_blocks = [h_config, dt * speeds, dt * speeds]
        window = (
            self._acceleration_window(dt, root_bounded, *self._limit_bounds(dt, root_bounded))
            if smooth
            else None
        )
        if window is not None:
            columns, low, high = window
            rows = np.zeros((len(columns), self.model.nv))
            rows[np.arange(len(columns)), columns] = 1.0
            g_blocks.append(np.vstack([rows, -rows]))
            h_blocks.append(np.concatenate([high, -low]))
        if dampers:
            for g, h in self._damper_rows():
                g_blocks.append(g)
                h_blocks.append(h)
        return np.vstack(g_blocks), np.concatenate(h_blocks)

    def _bounds(
        self, dt: float, root_bounded: bool, smooth: bool = True
    ) -> tuple[FloatArray, FloatArray]:
        """The joint position, speed and (``smooth``) acceleration limit rows of
        :meth:`inequalities` (rows of the identity) as bounds on dq: lower (nv,), upper (nv,),
        +-1e30 where unbounded."""
        lower, upper, room = self._limit_bounds(dt, root_bounded)
        window = self._acceleration_window(dt, root_bounded, lower, upper, room) if smooth else None
        if window is not None:
            columns, low, high = window
            lower[columns] = np.maximum(lower[columns], low)
            upper[columns] = np.minimum(upper[columns], high)
        return lower, upper

    def _acceleration_window(
        self,
        dt: float,
        root_bounded: bool,
        lower: FloatArray,
        upper: FloatArray,
        room: tuple[FloatArray, FloatArray],
    ) -> tuple[IntArray, FloatArray, FloatArray] | None:
        """The free limbs' acceleration bound on dq (pink's ``AccelerationLimit`` rows,
        braking at half the bound): their tangent indices (k,), and per index the lowest and
        highest step (k,), within ``FREE_LIMB_ACCELERATION`` dt^2 of the last step's
        (``velocity`` dt) and slow enough to brake before a position limit (``room``: the
        steps (nv,) up to the upper and down to the lower limits). Joints whose window misses
        their position and speed bounds ``lower``, ``upper`` (nv,) are left out (those
        bounds come first); None when the root is unbounded (a jump's fast phase) or no limb
        is free."""
        columns = self._free
        if not root_bounded or columns.size == 0:
            return None
        reach = tuning.FREE_LIMB_ACCELERATION * dt * dt
        previous = self.velocity[columns] * dt
        braking = self._braking[columns]
        up, down = room[0][columns], room[1][columns]
        # braking at half the bound (pink brakes at the bound): the position limit rows
        # (``ConfigurationLimit``, a share of the room per step) then slow the last stretch
        # at the bound at most; at the whole bound they cut in while the joint still moved
        # fast and stopped a Talos arm at 47 rad/s^2
        brake = tuning.FREE_LIMB_ACCELERATION
        up = np.where(braking, dt * np.sqrt(brake * np.maximum(up, 0.0)), np.inf)
        down = np.where(braking, dt * np.sqrt(brake * np.maximum(down, 0.0)), np.inf)
        high = np.minimum(reach + previous, up)
        low = -np.minimum(reach - previous, down)
        meets = (np.maximum(low, lower[columns]) <= np.minimum(high, upper[columns])) & (
            low <= high
        )
        if not meets.any():
            return None
        return columns[meets], low[meets], high[meets]

    def _limit_bounds(
        self, dt: float, root_bounded: bool
    ) -> tuple[FloatArray, FloatArray, tuple[FloatArray, FloatArray]]:
        """The joint position and speed limit rows of :meth:`inequalities` as bounds on dq:
        lower (nv,), upper (nv,), +-1e30 where unbounded; and the tangent steps (nv,) up to
        the upper and down to the lower position limits (the acceleration bound's braking
        reads them)."""
        q, model = self.q, self.model
        gain = self._config_gain
        step = dt * self._speeds[root_bounded]
        upper = self._unbounded.copy()
        lower = -upper
        speed = self._speed_index[root_bounded]
        upper[speed] = step
        lower[speed] = -step
        config = self._config
        room_up = pin.difference(model, q, self._upper_limit)
        room_down = pin.difference(model, q, self._lower_limit)
        upper[config] = np.minimum(upper[config], gain * room_up[config])
        lower[config] = np.maximum(lower[config], gain * room_down[config])
        return lower, upper, (room_up, -room_down)

    def offer_poses(self, q: FloatArray, poses: Poses) -> None:
        """The :func:`shape_poses` ``poses`` of the motion geometry at ``q`` (nq,), computed
        by the caller (the keyframe checker, where the next control step starts): a step
        from exactly ``q`` uses them instead of computing them again (the same arrays, so
        that the distance bounds see placements they already know)."""
        self._offered = (np.array(q, dtype=np.float64), poses)

    def _damper_rows(self) -> list[tuple[FloatArray, FloatArray]]:
        """The scene then self-collision damper rows (G, h) at the kinematics of the last
        :meth:`objective` (the shape placements computed once per step, or offered), then
        the trunk's tilt bound if it has one."""
        if self._placed != self._stamp:
            pin.updateGeometryPlacements(
                self.model, self.data, self.character.motion_geometry, self.geometry_data
            )
            offered = self._offered
            if offered is not None and np.array_equal(offered[0], self.q):
                self._poses = offered[1]
            else:
                self._poses = shape_poses(self.geometry_data)
            self._jacobians = PointJacobians(self.model, self.data, self._masks)
            self._placed = self._stamp
        out = []
        for rows in (
            self.scene.rows_at(self.data, self.geometry_data, self._poses, self._jacobians),
            self.self_clearance.rows_at(self.geometry_data, self._poses, self._jacobians),
            self._tilt_row,
            self._chest_row,
        ):
            if rows is not None:
                out.append(rows)
        return out

    def problem(
        self,
        qp: StepQP,
        dt: float,
        dampers: bool,
        root_bounded: bool,
        rigid: Sequence[str],
        smooth: bool = True,
    ) -> qpsolvers.Problem:
        """The QP of the step over dq: the cost ``qp``, :meth:`inequalities`, the ``rigid``
        limbs' stance held and a flight's COM moved exactly (:meth:`_equality_rows`)."""
        g, h = self.inequalities(dt, dampers, root_bounded, smooth)
        held = self._equality_rows(qp, rigid)
        a, b = held if held is not None else (None, None)
        return qpsolvers.Problem(qp.hessian, qp.linear, g, h, a, b)

    def _equality_rows(
        self, qp: StepQP, rigid: Sequence[str]
    ) -> tuple[FloatArray, FloatArray] | None:
        """A (k, nv), b (k,): the ``rigid`` limbs' stance held exactly, ``J_c dq = -e_c``
        (position rows only for a point contact), and a flight's COM moved exactly
        (``StepQP.com_move``); None when there are none."""
        blocks = []
        for limb in rigid:
            jac, err = qp.held[limb]
            keep = self._rigid_keep[limb]
            blocks.append((jac[keep], -tuning.TASK_GAIN * err[keep]))
        if qp.com_move is not None:
            blocks.append(qp.com_move)
        if not blocks:
            return None
        return np.vstack([a for a, _ in blocks]), np.concatenate([b for _, b in blocks])

    def _solve(
        self,
        qp: StepQP,
        dt: float,
        dampers: bool,
        root_bounded: bool,
        rigid: Sequence[str],
        smooth: bool = True,
    ) -> FloatArray | None:
        """The QP's velocity (nv,) rad/s or m/s, or None when it has no solution. With daqp,
        the QP of :meth:`problem` with its limit rows (rows of the identity) given as bounds
        on dq, which daqp handles without forming them."""
        if tuning.QP_SOLVER == "daqp":
            lower, upper = self._bounds(dt, root_bounded, smooth)
            rows = self._damper_rows() if dampers else []
            equalities = 0
            held = self._equality_rows(qp, rigid)
            if held is not None:
                rows.append(held)
                equalities = len(held[1])
            x = _solve_daqp(qp.hessian, qp.linear, lower, upper, rows, equalities)
        else:
            problem = self.problem(qp, dt, dampers, root_bounded, rigid, smooth)
            result = qpsolvers.solve_problem(problem, solver=tuning.QP_SOLVER)
            x = result.x if result.found else None
        if x is None:
            return None
        return np.asarray(x, dtype=np.float64) / dt


def _solve_daqp(
    hessian: FloatArray,
    linear: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    rows: Sequence[tuple[FloatArray, FloatArray]],
    equalities: int,
) -> FloatArray | None:
    """The minimiser x (n,) of 1/2 x' H x + c' x subject to ``lower <= x <= upper`` (n,) and
    G x <= h for each (G, h) of ``rows``, the last ``equalities`` of those rows equalities
    G x = h, by daqp; None when it finds none."""
    n = len(linear)
    if rows:
        constraints = np.concatenate([g for g, _ in rows])  # 2-D blocks, as vstack
        bound = np.concatenate([upper, *(h for _, h in rows)])
    else:
        constraints = np.zeros((0, n))
        bound = upper
    floor = np.full(len(bound), -1e30)
    floor[:n] = lower
    sense = np.zeros(len(bound), dtype=_DAQP_SENSE)
    if equalities:
        sense[len(bound) - equalities :] = _DAQP_EQUALITY
    x, _, exitflag, _ = daqp.solve(hessian, linear, constraints, bound, floor, sense)
    if exitflag <= 0:
        return None
    # daqp meets its bounds to its feasibility tolerance (about 1e-6): a joint at its speed
    # limit for a whole keyframe period came out 3e-6 over it, which the auditor counts
    return np.clip(np.asarray(x, dtype=np.float64), lower, upper)
