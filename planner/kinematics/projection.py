"""Contact projection: put one limb's effector on a surface point, the rest of the body fixed.

Anchor: the RB-PRM projection step (contact-planner-anchor section 4): the effector goes to the
target point with its contact normal along the surface normal, by inverse kinematics over the
limb's joints only (tolerance 1e-4 m, at most 100 iterations), with an optional pull toward a
reference posture.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from planner.kinematics.ik import IkResult, solve_ik
from planner.kinematics.model import limb_dofs
from planner.kinematics.tasks import (
    ContactNormalTask,
    FramePlacementTask,
    PostureTask,
    Priority,
    TargetTask,
    Task,
)

FloatArray = NDArray[np.float64]


def project_contact(
    model: pin.Model,
    q: ArrayLike,
    root_joint: int | str,
    effector_frame: int | str,
    target: ArrayLike,
    surface_normal: ArrayLike,
    *,
    contact_normal: ArrayLike = (0.0, 0.0, 1.0),
    contact_offset: ArrayLike = (0.0, 0.0, 0.0),
    orientation: ArrayLike | None = None,
    clearance: float = 0.0,
    hold: Sequence[TargetTask] = (),
    reference: ArrayLike | None = None,
    posture_weight: float = 1.0,
    data: pin.Data | None = None,
    max_iterations: int = 100,
    tolerance: float = 1e-4,
    angular_tolerance: float = 1e-3,
) -> IkResult:
    """Move only the limb ``root_joint`` -> ``effector_frame`` so that its contact point lands on
    ``target`` (3,) (world, m) with the frame axis ``contact_normal`` (3,) (frame coordinates)
    along ``surface_normal`` (3,) (world, pointing out of the surface); yaw about the normal is
    left free.

    ``contact_offset`` (3,) is the contact point in the effector frame. With ``orientation``
    (3, 3) the full effector rotation is imposed instead (6D placement of the frame, the offset
    applied in that rotation). ``clearance`` (m) lifts the target along the normal (the anchor
    uses 1e-3). ``hold`` are tasks that must keep holding (other contacts: only matters when
    they share joints with the limb). ``reference`` (nq,) pulls the limb toward a posture with
    weight ``posture_weight`` in [0, 1]. Root and other limbs stay exactly where ``q`` puts
    them. Returns the :class:`IkResult`; ``success`` says whether the contact was made.

    Raises ValueError on malformed input or when ``root_joint`` does not move the effector.
    """
    dofs = limb_dofs(model, root_joint, effector_frame)
    normal = np.asarray(surface_normal, dtype=np.float64)
    point = np.asarray(target, dtype=np.float64)
    if normal.shape != (3,) or point.shape != (3,) or np.linalg.norm(normal) < 1e-9:
        raise ValueError("target and surface_normal must be (3,), the normal non-zero")
    normal = normal / np.linalg.norm(normal)
    goal = point + clearance * normal
    tasks: list[Task] = []
    if orientation is None:
        tasks.append(
            ContactNormalTask(
                effector_frame,
                goal,
                normal,
                np.asarray(contact_normal),
                np.asarray(contact_offset),
                Priority.CONTACT,
            )
        )
    else:
        rotation = np.asarray(orientation, dtype=np.float64)
        pose = np.eye(4)
        pose[:3, :3] = rotation
        pose[:3, 3] = goal - rotation @ np.asarray(contact_offset, dtype=np.float64)
        tasks.append(FramePlacementTask(effector_frame, pose, Priority.CONTACT))
    tasks.extend(hold)
    if reference is not None:
        weights = np.zeros(model.nv)
        weights[dofs] = posture_weight
        tasks.append(PostureTask(np.asarray(reference, dtype=np.float64), weights, gain=0.3))
    return solve_ik(
        model,
        q,
        tasks,
        data=data,
        active=dofs,
        max_iterations=max_iterations,
        tolerance=tolerance,
        angular_tolerance=angular_tolerance,
    )
