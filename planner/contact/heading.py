"""A searched root path turned to face the way it goes.

The root path search (``root_path``) samples each waypoint's yaw at random, so a path found
by search may carry the body crabwise: on Talos' stair_bauzil flight its guide turned 30 to
56 degrees off the direction of travel, the feet kept facing the steps, and the hips ran
into their yaw and roll limits (the motion then folded the chest over to keep up with the
COM). A body walks facing where it goes: each pose of such a path is turned about the
vertical to within a tolerance of the direction of travel there, where the reduced model
accepts it, easing in from the start's heading and out to the goal's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.contact.reachability import ReachabilityChecker
from planner.poses import yaw_matrix

FloatArray = NDArray[np.float64]

TRAVEL_WINDOW_M = 0.3
"""m of path either side of a pose over which its direction of travel is taken (about a
stride: the sway of a searched path within a stride is not a change of direction)."""
EASE_M = 0.5
"""m of path over which the heading eases from the start's to the travel's (and from the
travel's to the goal's at the end)."""
MIN_TRAVEL_SHARE = 0.5
"""A pose whose horizontal travel over its window is under this share of the window's
length keeps its own yaw (the path climbs or turns on the spot there: no direction to
face)."""
TOLERANCE = np.radians(15.0)
"""rad: a body may walk this far off the direction it goes (a slight crab on a stair or
beside a rail); a pose further off is turned to this (within Talos' hip yaw of 20 degrees,
whose feet face the steps while its pelvis faces the path)."""
TURN_FRACTIONS = (1.0, 0.5)
"""Fractions of the turn toward the travel's direction tried in turn where the whole turn
is refused by the reduced model (a trunk that fits only sideways keeps its own yaw)."""


def _wrap(angle: FloatArray) -> FloatArray:
    return np.asarray((angle + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def _yaws(poses: FloatArray) -> FloatArray:
    """(n,) heading (rad) of the root's x axis in the horizontal plane."""
    return np.asarray(np.arctan2(poses[:, 1, 0], poses[:, 0, 0]), dtype=np.float64)


def _ease(s: FloatArray, length: float) -> FloatArray:
    """(n,) weight of the travel's heading at arc lengths ``s``: 0 at both ends, 1 past
    ``EASE_M`` from either, smooth (cubic) between."""
    near = np.minimum(s, length - s) / EASE_M
    x = np.clip(near, 0.0, 1.0)
    return np.asarray(x * x * (3.0 - 2.0 * x), dtype=np.float64)


def face_the_way(checker: ReachabilityChecker, poses: FloatArray, spacing: float) -> FloatArray:
    """``poses`` (n, 4, 4), evenly ``spacing`` m apart along a root path, each more than
    ``TOLERANCE`` off the direction of travel there turned about the world vertical to within
    it (positions, pitch and roll kept; the first and last poses unchanged); a pose the
    reduced model refuses so turned is turned by less, or not at all. A path shorter than two
    ease lengths is returned as is."""
    poses = np.asarray(poses, dtype=np.float64)
    n = len(poses)
    length = spacing * (n - 1)
    if n < 3 or length < 2.0 * EASE_M:
        return poses.copy()
    reach = max(1, round(TRAVEL_WINDOW_M / spacing))
    ahead = np.minimum(np.arange(n) + reach, n - 1)
    behind = np.maximum(np.arange(n) - reach, 0)
    travel = poses[ahead, :2, 3] - poses[behind, :2, 3]
    moving = np.linalg.norm(travel, axis=1) >= MIN_TRAVEL_SHARE * spacing * (ahead - behind)
    own = _yaws(poses)
    off = np.where(moving, _wrap(np.arctan2(travel[:, 1], travel[:, 0]) - own), 0.0)
    turn = np.sign(off) * np.maximum(np.abs(off) - TOLERANCE, 0.0)
    turn *= _ease(spacing * np.arange(n, dtype=np.float64), length)
    out = poses.copy()
    pending = np.flatnonzero(np.abs(turn) > 1e-9)
    for fraction in TURN_FRACTIONS:
        if len(pending) == 0:
            break
        turned = poses[pending].copy()
        turned[:, :3, :3] = yaw_matrix(fraction * turn[pending]) @ poses[pending, :3, :3]
        accepted = checker.valid(turned)
        out[pending[accepted]] = turned[accepted]
        pending = pending[~accepted]
    return out
