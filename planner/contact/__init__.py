"""Reachability-based contact planning: root paths, contact states and sequences, one-step mode."""

from planner.contact.context import (
    ContactContext,
    ContactParams,
    FailureReason,
    character_obstacles,
    make_context,
)
from planner.contact.generation import (
    ContactAttempt,
    break_contact,
    create_contact,
    maintain,
    state_from_configuration,
)
from planner.contact.one_step import StepAction, StepFailure, StepResult, twister_step
from planner.contact.reachability import ReachabilityChecker, ground_limbs
from planner.contact.root_path import RootPath, plan_root_path
from planner.contact.root_sampler import OrientationBounds, sample_root_poses
from planner.contact.standing import StandingParams, standing_state, state_from_root_pose
from planner.contact.state import ContactState, LimbContact

__all__ = [
    "ContactAttempt",
    "ContactContext",
    "ContactParams",
    "ContactState",
    "FailureReason",
    "LimbContact",
    "OrientationBounds",
    "ReachabilityChecker",
    "RootPath",
    "StandingParams",
    "StepAction",
    "StepFailure",
    "StepResult",
    "break_contact",
    "character_obstacles",
    "create_contact",
    "ground_limbs",
    "maintain",
    "make_context",
    "plan_root_path",
    "sample_root_poses",
    "standing_state",
    "state_from_configuration",
    "state_from_root_pose",
    "twister_step",
]
