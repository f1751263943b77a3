"""Whole-body motion: a motion described as data (``spec``) turned into checked keyframes by
one builder (``builder``), for plans, Twister steps and jumps alike.

``types`` holds the output records (keyframes, phases, COM segments) the planners share;
``tuning`` every gain, cost and tolerance.
"""

from planner.motion.types import ComSegment, Keyframe, Phase

__all__ = ["ComSegment", "Keyframe", "Phase"]
