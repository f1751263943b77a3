"""The tracker's QP rebuilt with pink's task objects and ``build_ik``: the reference the
tracker's own assembly (``WholeBodyTracker.objective`` / ``problem``) is compared to, in
``test_tracker_qp.py`` and ``bench/tracker.py``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin
import qpsolvers
from pink import Configuration, build_ik
from pink.limits import AccelerationLimit, ConfigurationLimit, VelocityLimit
from pink.tasks import ComTask, FrameTask, PostureTask

from planner.motion import tuning
from planner.motion.tracker import (
    StepTargets,
    WholeBodyTracker,
    _saturated,
    speed_limits,
    trunk_orientation_cost,
)


class _HalfBraking(AccelerationLimit):
    """pink's acceleration limit braking before a position limit at half the bound (the
    tracker's choice: pink's ``ConfigurationLimit`` rows then slow the last stretch within
    the bound): pink's own braking rows at half the bound, its window rows at the whole."""

    def compute_qp_inequalities(self, configuration: Any, dt: float) -> Any:
        if self.projection_matrix is None:
            return None
        whole, previous = self.a_max, self.Delta_q_prev
        k = len(whole)
        self.a_max = whole / 2.0
        try:
            # an infinite last step leaves only the braking term in each block of rows
            self.Delta_q_prev = np.full(k, np.inf)
            g, upper = super().compute_qp_inequalities(configuration, dt)
            self.Delta_q_prev = np.full(k, -np.inf)
            _, lower = super().compute_qp_inequalities(configuration, dt)
        finally:
            self.a_max, self.Delta_q_prev = whole, previous
        braking = np.concatenate([upper[:k], lower[k:]])
        window = np.concatenate([whole * dt * dt + previous, whole * dt * dt - previous])
        return g, np.minimum(window, braking)


class PinkReference:
    """pink tasks and limits mirroring a :class:`WholeBodyTracker`'s; ``dampers`` is the
    (scene, self) limit pair pink reads (give a second tracker's, so that their memory
    evolves as the first one's)."""

    def __init__(self, tracker: WholeBodyTracker, dampers: tuple[Any, Any]) -> None:
        self.tracker = tracker
        model = tracker.model
        self.data = model.createData()
        self.configuration = Configuration(model, self.data, pin.neutral(model), copy_data=False)
        trunk_cost = trunk_orientation_cost(tracker.character)
        self.com = ComTask(cost=tuning.COM_COST, gain=tuning.TASK_GAIN)
        self.trunk = FrameTask(
            str(model.frames[1].name),
            position_cost=[0.0, 0.0, tuning.TRUNK_HEIGHT_COST],
            orientation_cost=[trunk_cost, trunk_cost, 0.0],
            gain=tuning.TRUNK_GAIN,
        )
        self.posture = PostureTask(cost=tuning.POSTURE_COST, gain=tuning.POSTURE_GAIN)
        self.stance: dict[str, FrameTask] = {}
        self.swing: dict[str, FrameTask] = {}
        for limb in tracker.character.limbs:
            patch = limb.contact == "patch"
            self.stance[limb.name] = FrameTask(
                limb.effector_frame,
                position_cost=tuning.STANCE_COST,
                orientation_cost=tuning.STANCE_COST if patch else 0.0,
                gain=tuning.TASK_GAIN,
            )
            self.swing[limb.name] = FrameTask(
                limb.effector_frame,
                position_cost=tuning.SWING_POSITION_COST,
                orientation_cost=tuning.SWING_ORIENTATION_COST if patch else 0.0,
                gain=tuning.TASK_GAIN,
            )
        self.dampers = dampers
        self.limits = {
            bounded: [
                ConfigurationLimit(model),
                VelocityLimit(model, speed_limits(model, root_bounded=bounded)),
            ]
            for bounded in (False, True)
        }

    def tasks(self, q: Any, targets: StepTargets, share: float = 1.0) -> list[Any]:
        """pink's tasks of the step at ``q`` (nq,) toward ``targets`` (the configuration
        updated to ``q``)."""
        self.configuration.update(q)
        out: list[Any] = []
        for limb, pose in targets.stance:
            task = self.stance[limb]
            task.set_target(pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy()))
            out.append(task)
        moving = [] if targets.swing is None else [targets.swing]
        for n, (limb, pose) in enumerate([*moving, *targets.carried]):
            task = self.swing[limb]
            here = self.data.oMf[self.tracker.character.limb(limb).frame_id].translation
            # the landing settle: the swing's cost raised toward SETTLE_COST, by the share
            # of the settle gone by and as the effector nears its landing
            share_settle = 0.0
            if n == 0 and moving and targets.swing_settle > 0.0:
                near = max(
                    0.0, 1.0 - float(np.linalg.norm(here - pose[:3, 3])) / tuning.SETTLE_REACH
                )
                share_settle = min(1.0, targets.swing_settle) * near
            patch = self.tracker.character.limb(limb).contact == "patch"
            position = tuning.SWING_POSITION_COST
            orientation = tuning.SWING_ORIENTATION_COST if patch else 0.0
            settled = tuning.SETTLE_COST
            task.set_position_cost(position + share_settle * (settled - position))
            if patch:
                task.set_orientation_cost(orientation + share_settle * (settled - orientation))
            goal = _saturated(here, pose[:3, 3], tuning.SWING_MAX_ERROR)
            task.set_target(pin.SE3(pose[:3, :3].copy(), goal))
            out.append(task)
        com = pin.centerOfMass(self.tracker.model, self.data, q, False)
        self.com.set_target(_saturated(com, np.asarray(targets.com), targets.com_reach))
        out.append(self.com)
        posture = np.asarray(targets.posture, dtype=np.float64)
        trunk = self.tracker.trunk_rotation(posture, targets.level_trunk)
        self.trunk.set_target(pin.SE3(trunk, posture[:3].copy()))
        self.trunk.gain = 1.0 - (1.0 - tuning.TRUNK_GAIN) ** share
        self.posture.gain = 1.0 - (1.0 - tuning.POSTURE_GAIN) ** share
        out.append(self.trunk)
        reach = tuning.POSTURE_MAX_ERROR * share
        joints = slice(7, None)
        goal = np.array(q, dtype=np.float64)
        goal[joints] = q[joints] + np.clip(posture[joints] - q[joints], -reach, reach)
        self.posture.set_target(goal)
        self.posture.cost = self._posture_costs(targets)
        out.append(self.posture)
        return out

    def _free_columns(self, targets: StepTargets) -> list[int]:
        """Tangent indices of the joints of the limbs the step leaves free (neither in stance
        nor moving, nor sharing a joint with one that is)."""
        in_use = {limb for limb, _ in targets.stance} | {limb for limb, _ in targets.carried}
        if targets.swing is not None:
            in_use.add(targets.swing[0])
        character = self.tracker.character
        used = {int(i) for limb in in_use for i in character.limb(limb).idx_v}
        return [
            int(i)
            for limb in character.limbs
            if limb.name not in in_use
            for i in limb.idx_v
            if int(i) not in used
        ]

    def _posture_costs(self, targets: StepTargets) -> np.ndarray:
        """The posture task's cost per joint (nv - 6,): the torso's (joints of no limb) and
        the free limbs' their own."""
        character = self.tracker.character
        nv = self.tracker.model.nv
        costs = np.full(nv, tuning.TORSO_POSTURE_COST)
        for limb in character.limbs:
            costs[limb.idx_v] = tuning.POSTURE_COST
        costs[self._free_columns(targets)] = tuning.FREE_LIMB_POSTURE_COST
        return costs[6:]

    def _free_limbs_acceleration(self, targets: StepTargets, dt: float) -> AccelerationLimit:
        """pink's acceleration limit on the joints of the limbs the step leaves free (neither
        in stance nor moving, nor sharing a joint with one that is), from the tracker's last
        velocity."""
        bound = np.full(self.tracker.model.nv, np.inf)
        bound[self._free_columns(targets)] = tuning.FREE_LIMB_ACCELERATION
        limit = _HalfBraking(self.tracker.model, bound)
        limit.set_last_integration(self.tracker.velocity, dt)
        return limit

    def problem(
        self,
        q: Any,
        targets: StepTargets,
        dt: float,
        share: float = 1.0,
        dampers: bool = True,
        rigid: Sequence[str] = (),
    ) -> qpsolvers.Problem:
        """pink's ``build_ik`` problem of the step (rigid limbs' stance as equalities)."""
        tasks = self.tasks(q, targets, share)
        limits = list(self.limits[targets.root_bounded])
        if targets.root_bounded:
            limits.append(self._free_limbs_acceleration(targets, dt))
        if dampers:
            limits += list(self.dampers)
        problem = build_ik(self.configuration, tasks, dt, damping=tuning.DAMPING, limits=limits)
        if rigid:
            rows, values = [], []
            for limb in rigid:
                task = self.stance[limb]
                patch = self.tracker.character.limb(limb).contact == "patch"
                keep = slice(0, 6) if patch else slice(0, 3)
                rows.append(task.compute_jacobian(self.configuration)[keep])
                values.append(-task.gain * task.compute_error(self.configuration)[keep])
            problem.A = np.vstack(rows)
            problem.b = np.concatenate(values)
        return problem
