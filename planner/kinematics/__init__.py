"""Whole-body inverse kinematics over Pinocchio models with a free-flyer root.

``solve_ik`` (weighted damped least squares with joint limits), ``project_contact`` (one
limb onto a surface), swing arcs, forward
kinematics helpers and conversions between Pinocchio configurations and named joint values.
"""

from planner.kinematics.ik import IkProblem, IkResult, resolve_active, solve_ik
from planner.kinematics.keyframes import (
    clearing_swing_trajectory,
    keyframe_times,
    minimum_jerk,
    swing_arc,
    swing_trajectory,
)
from planner.kinematics.model import (
    borrowed_data,
    borrowed_geometry_data,
    bounded_dofs,
    clamp_to_limits,
    com_position,
    configuration_from,
    configuration_parts,
    frame_id,
    frame_placement,
    frame_placements,
    frame_support_dofs,
    has_free_flyer_root,
    joint_dofs,
    joint_id,
    limb_dofs,
    limb_reach,
    scratch_data,
    within_limits,
)
from planner.kinematics.projection import project_contact
from planner.kinematics.tasks import (
    TIER_WEIGHTS,
    ComTask,
    ContactNormalTask,
    FrameAxisTask,
    FramePlacementTask,
    FramePositionTask,
    PostureTask,
    Priority,
    TargetTask,
    Task,
)

__all__ = [
    "TIER_WEIGHTS",
    "ComTask",
    "ContactNormalTask",
    "FrameAxisTask",
    "FramePlacementTask",
    "FramePositionTask",
    "IkProblem",
    "IkResult",
    "PostureTask",
    "Priority",
    "TargetTask",
    "Task",
    "borrowed_data",
    "borrowed_geometry_data",
    "bounded_dofs",
    "clamp_to_limits",
    "clearing_swing_trajectory",
    "com_position",
    "configuration_from",
    "configuration_parts",
    "frame_id",
    "frame_placement",
    "frame_placements",
    "frame_support_dofs",
    "has_free_flyer_root",
    "joint_dofs",
    "joint_id",
    "keyframe_times",
    "limb_dofs",
    "limb_reach",
    "minimum_jerk",
    "project_contact",
    "resolve_active",
    "scratch_data",
    "solve_ik",
    "swing_arc",
    "swing_trajectory",
    "within_limits",
]
