"""Reachability-based contact planning: root paths, contact states and sequences, one-step mode."""

from planner.contact.reachability import ReachabilityChecker, ground_limbs
from planner.contact.root_path import RootPath, plan_root_path
from planner.contact.root_sampler import OrientationBounds, sample_root_poses
from planner.contact.standing import StandingParams, standing_state, state_from_root_pose
from planner.contact.state import ContactState, LimbContact

__all__ = [
    "ContactState",
    "LimbContact",
    "OrientationBounds",
    "ReachabilityChecker",
    "RootPath",
    "StandingParams",
    "ground_limbs",
    "plan_root_path",
    "sample_root_poses",
    "standing_state",
    "state_from_root_pose",
]
