"""Whole-body tracking as a constrained QP per control step (differential IK with pink).

Each step solves, over the configuration step ``dq`` (tangent space),

    min  sum of weighted task errors after the step  +  DAMPING |dq|^2
    s.t. joint position limits, joint speeds <= min(URDF limit, MAX_JOINT_SPEED),
         the root's speed <= ROOT_LINEAR_SPEED, ROOT_ANGULAR_SPEED per axis of its frame
         (outside a jump's fast phases, ``StepTargets.root_bounded``),
         collision dampers against the scene and between body parts (``clearance``)

with the tasks, by cost: stance contacts held (dominant), the COM on its curve, the swing
effector on its arc, the trunk's roll and pitch at the planned orientation, and a posture
pull toward the phase's planned configuration. With ``StepTargets.rigid_stance`` (a jump's
stance phases, where the COM moves fast, and a plan's dynamic COM) the stance contacts are
equality constraints instead, ``J_c dq = -e_c`` (position for a point contact, full
placement for a patch): the COM then lags its curve rather than drag a contact. The QP
backend is daqp through qpsolvers. When the QP has no solution (a damper that cannot be met
within the speed limits), the step is retried without the dampers, then (rigid stance) with
the contacts back in the cost, then skipped (the body holds still).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
import qpsolvers
from numpy.typing import NDArray
from pink import Configuration, build_ik
from pink.limits import ConfigurationLimit, VelocityLimit
from pink.tasks import ComTask, FrameTask, PostureTask
from scipy.spatial.transform import Rotation

from planner.character import Character
from planner.motion import tuning
from planner.motion.clearance import SceneClearance, SelfClearance

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StepTargets:
    """What one control step aims at (world frame).

    stance : (limb, effector pose (4, 4)) held. com : (3,) m. swing : (limb, pose (4, 4))
    or None. posture : (nq,) pulled toward; its root orientation is the trunk target.
    swing_guarded : whether the swinging effector's own shapes are kept off the scene (a last
    resort lets a swing that cannot land otherwise through: the checker still counts it).
    level_trunk : the trunk aims at the posture's yaw only (and its pitch for a character
    whose trunk may pitch); otherwise at the posture's own roll and pitch.
    carried : (limb, pose (4, 4)) effectors carried through a flight (swing cost, guarded
    like a swing). exact_com : a flight: the whole body is translated so that its COM is
    exactly ``com`` before and after the QP (the QP then only shapes the body).
    com_reach : m, the COM target is pulled in to this distance from the COM
    (``COM_MAX_ERROR``; unbounded for a fast COM). rigid_stance : the stance contacts are
    equality constraints of the QP, not costs.
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


def effector_geometries(character: Character) -> dict[str, frozenset[int]]:
    """Per limb, the collision shapes (geometry indices) of its effector: those on the
    effector frame's joint and its descendants (they touch the surface in contact)."""
    model = character.model
    out = {}
    for limb in character.limbs:
        joint = int(model.frames[limb.frame_id].parentJoint)
        subtree = {joint}
        for j in range(joint + 1, model.njoints):
            if int(model.parents[j]) in subtree:
                subtree.add(j)
        out[limb.name] = frozenset(
            i
            for i, o in enumerate(character.motion_geometry.geometryObjects)
            if o.parentJoint in subtree
        )
    return out


def speed_limits(model: Any, root_bounded: bool = False) -> FloatArray:
    """(nv,) rad/s: each joint's URDF velocity limit capped at ``MAX_JOINT_SPEED`` (joints
    without a limit get the cap). The free-flyer root (its local frame) is left unbounded,
    or with ``root_bounded`` held to ``ROOT_LINEAR_SPEED`` m/s and ``ROOT_ANGULAR_SPEED``
    rad/s per axis."""
    limits = np.array(model.velocityLimit, dtype=np.float64)
    root = int(model.joints[1].nv) if model.njoints > 1 and model.joints[1].nq == 7 else 0
    joints = limits[root:]
    joints[~(joints > 0)] = tuning.MAX_JOINT_SPEED
    limits[root:] = np.minimum(joints, tuning.MAX_JOINT_SPEED)
    if root:
        limits[:3] = tuning.ROOT_LINEAR_SPEED if root_bounded else np.inf
        limits[3:6] = tuning.ROOT_ANGULAR_SPEED if root_bounded else np.inf
    return limits


def _saturated(here: FloatArray, target: FloatArray, reach: float) -> FloatArray:
    """``target`` (3,) moved toward ``here`` (3,) to at most ``reach`` m from it."""
    gap = np.asarray(target, dtype=np.float64) - here
    norm = float(np.linalg.norm(gap))
    if norm <= reach:
        return np.array(target, dtype=np.float64)
    return np.asarray(here + gap * (reach / norm), dtype=np.float64)


class WholeBodyTracker:
    """One character in one scene; :meth:`step` moves a configuration one control step.

    ``obstacles`` are (coal geometry, coal.Transform3s) pairs the body avoids besides the
    scene (other characters). Not thread-safe: one per thread.
    """

    def __init__(
        self,
        character: Character,
        scene_bvh: Any,
        obstacles: Sequence[tuple[Any, Any]] = (),
    ) -> None:
        self.character = character
        model = character.model
        self.model = model
        self.data = model.createData()
        self.effectors = effector_geometries(character)
        self.com_task = ComTask(cost=tuning.COM_COST, gain=tuning.TASK_GAIN)
        root_frame = str(model.frames[1].name)
        self.trunk_task = FrameTask(
            root_frame,
            position_cost=[0.0, 0.0, tuning.TRUNK_HEIGHT_COST],
            orientation_cost=[tuning.TRUNK_COST, tuning.TRUNK_COST, 0.0],
            gain=tuning.TRUNK_GAIN,
        )
        self.posture_task = PostureTask(cost=tuning.POSTURE_COST, gain=tuning.POSTURE_GAIN)
        self.stance_tasks: dict[str, FrameTask] = {}
        self.swing_tasks: dict[str, FrameTask] = {}
        for limb in character.limbs:
            patch = limb.contact == "patch"
            self.stance_tasks[limb.name] = FrameTask(
                limb.effector_frame,
                position_cost=tuning.STANCE_COST,
                orientation_cost=tuning.STANCE_COST if patch else 0.0,
                gain=tuning.TASK_GAIN,
            )
            self.swing_tasks[limb.name] = FrameTask(
                limb.effector_frame,
                position_cost=tuning.SWING_POSITION_COST,
                orientation_cost=tuning.SWING_ORIENTATION_COST if patch else 0.0,
                gain=tuning.TASK_GAIN,
            )
        self.scene = SceneClearance(model, character.motion_geometry, scene_bvh, obstacles)
        self.self_clearance = SelfClearance(model, character.motion_geometry)
        self.free_limits = [
            ConfigurationLimit(model),
            VelocityLimit(model, speed_limits(model)),
        ]
        self.limits = [
            ConfigurationLimit(model),
            VelocityLimit(model, speed_limits(model, root_bounded=True)),
        ]
        self.configuration = Configuration(model, self.data, pin.neutral(model), copy_data=False)
        self.fallbacks = 0
        self._lift_off: dict[str, dict[int, float]] = {}
        self._trunk_cache: dict[bytes, FloatArray] = {}
        root_nq = 7 if model.joints[1].nq == 7 else 0
        self._bounded = np.arange(root_nq, model.nq)
        self._lower = np.asarray(model.lowerPositionLimit[root_nq:], dtype=np.float64)
        self._upper = np.asarray(model.upperPositionLimit[root_nq:], dtype=np.float64)

    def trunk_rotation(self, posture: FloatArray, level: bool = True) -> FloatArray:
        """(3, 3) trunk orientation aimed at from a planned configuration (nq,): with
        ``level``, its yaw, and its pitch only for a character whose trunk may pitch (a
        hexapod on a slope), never a roll; otherwise its own orientation. Memoised per
        posture (a phase keeps its posture for many steps)."""
        rotation = pin.Quaternion(posture[3:7]).toRotationMatrix()
        if not level:
            return np.asarray(rotation, dtype=np.float64)
        key = posture[3:7].tobytes()
        cached = self._trunk_cache.get(key)
        if cached is None:
            yaw, pitch, _ = Rotation.from_matrix(rotation).as_euler("ZYX")
            if self.character.max_pitch <= tuning.LEVEL_TRUNK_PITCH:
                pitch = 0.0
            cached = np.asarray(
                Rotation.from_euler("ZY", [yaw, pitch]).as_matrix(), dtype=np.float64
            )
            if len(self._trunk_cache) > 4096:
                self._trunk_cache.clear()
            self._trunk_cache[key] = cached
        return cached

    def reset(self) -> None:
        """Forget what earlier steps left (remembered witnesses, the lift-off depths): the
        next step starts a fresh track."""
        self.scene.memory.clear()
        self._lift_off = {}

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
                depths = self.scene.depths(self.configuration.data, self.effectors[limb])
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
        config = self.configuration
        q = np.array(q, dtype=np.float64)
        q[self._bounded] = np.clip(q[self._bounded], self._lower, self._upper)
        if targets.exact_com:
            q = self._onto_com(q, targets.com)
        config.update(q)
        tasks: list[Any] = []
        skipped: set[int] = set()
        for limb, pose in targets.stance:
            task = self.stance_tasks[limb]
            task.set_target(pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy()))
            tasks.append(task)
            skipped |= self.effectors[limb]
        moving = [] if targets.swing is None else [targets.swing]
        moving += list(targets.carried)
        for limb, pose in moving:
            task = self.swing_tasks[limb]
            here = self.data.oMf[self.character.limb(limb).frame_id].translation
            goal = _saturated(here, pose[:3, 3], tuning.SWING_MAX_ERROR)
            task.set_target(pin.SE3(pose[:3, :3].copy(), goal))
            tasks.append(task)
        guarded = [limb for limb, _ in targets.carried]
        if targets.swing is not None:
            if targets.swing_guarded:
                guarded.insert(0, targets.swing[0])
            else:
                skipped |= self.effectors[targets.swing[0]]
        light = self._swing_security(guarded)
        com = pin.centerOfMass(self.model, self.data, q, False)
        goal = _saturated(com, np.asarray(targets.com, dtype=np.float64), targets.com_reach)
        self.com_task.set_target(goal)
        tasks.append(self.com_task)
        posture = np.asarray(targets.posture, dtype=np.float64)
        trunk = self.trunk_rotation(posture, targets.level_trunk)
        self.trunk_task.set_target(pin.SE3(trunk, posture[:3].copy()))
        self.trunk_task.gain = 1.0 - (1.0 - tuning.TRUNK_GAIN) ** share
        self.posture_task.gain = 1.0 - (1.0 - tuning.POSTURE_GAIN) ** share
        tasks.append(self.trunk_task)
        # each joint pulled at most POSTURE_MAX_ERROR toward its posture per step: summed
        # over thirty joints, a far posture would otherwise outweigh the stance contacts
        reach = tuning.POSTURE_MAX_ERROR * share
        joints = slice(self._bounded[0], None)
        goal = q.copy()
        goal[joints] = q[joints] + np.clip(posture[joints] - q[joints], -reach, reach)
        self.posture_task.set_target(goal)
        tasks.append(self.posture_task)
        self.scene.set_phase(frozenset(skipped), light)
        rigid = [limb for limb, _ in targets.stance] if targets.rigid_stance else []
        bounds = self.limits if targets.root_bounded else self.free_limits
        attempts: list[tuple[list[Any], bool]] = [
            ([*bounds, self.scene, self.self_clearance], True),
            (bounds, True),
        ]
        if rigid:
            attempts += [
                ([*bounds, self.scene, self.self_clearance], False),
                (bounds, False),
            ]
        for limits, hard in attempts:
            velocity = self._solve(tasks, dt, limits, rigid if hard else [])
            if velocity is None:
                self.fallbacks += 1
                continue
            q = np.asarray(pin.integrate(self.model, q, velocity * dt), dtype=np.float64)
            return self._onto_com(q, targets.com) if targets.exact_com else q
        return np.array(q, dtype=np.float64)

    def _solve(
        self, tasks: Sequence[Any], dt: float, limits: Sequence[Any], rigid: Sequence[str]
    ) -> FloatArray | None:
        """The QP's velocity (nv,) rad/s or m/s, or None when it has no solution. ``rigid``
        limbs' stance tasks (targets already set) are also equality constraints: the
        effector's error is corrected in this step, exactly (position rows only for a
        point contact)."""
        config = self.configuration
        problem = build_ik(config, tasks, dt, damping=tuning.DAMPING, limits=limits)
        if rigid:
            rows, values = [], []
            for limb in rigid:
                task = self.stance_tasks[limb]
                keep = slice(0, 6) if self.character.limb(limb).contact == "patch" else slice(0, 3)
                rows.append(task.compute_jacobian(config)[keep])
                values.append(-task.gain * task.compute_error(config)[keep])
            problem.A = np.vstack(rows)
            problem.b = np.concatenate(values)
        result = qpsolvers.solve_problem(problem, solver=tuning.QP_SOLVER)
        if not result.found or result.x is None:
            return None
        return np.asarray(result.x, dtype=np.float64) / dt
