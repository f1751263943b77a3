"""A root path laid along the terrain's slope, for legged bodies that climb pitched.

The root path planner draws orientations at random within their bounds, so a path allowed to
pitch pitches anyhow. Here every pose gets the pitch of the ground under the trunk (a line
fitted to the terrain heights along the heading, smoothed along the path) and stands the
character's standing height above that line; a pose whose trunk would then collide is lifted
until it clears, and kept as it was when it cannot. A clear pose is raised a little more when
it can be: step nosings stand above the fitted line, and a walking body sags below its guide.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from planner.contact.reachability import ReachabilityChecker, ground_limbs, reference_offsets
from planner.contact.root_sampler import euler_matrices
from planner.scene import Scene

FloatArray = NDArray[np.float64]

LEVEL_PITCH = 0.05  # rad: pitch bounds up to this keep the trunk level (the default)
_SAMPLES_ALONG = 9  # terrain samples along the heading
_LIFT_STEP = 0.02  # m between lifts of a colliding pose
_CLEARANCE = 0.06  # m added above the lowest valid lift, when still valid (less, and the
# hexapod's trunk scrapes the 0.05 m jitter of the climbing wall's rows when it shifts)
_CEILING = 0.3  # m above the guide pose under which the terrain is looked for
_ROUGH_GROUND = 0.01
"""m: ground whose terrain samples stray further than this from their fitted line (steps,
blocks, rocks), or where the trunk had to be lifted, gets the ``_CLEARANCE``; on even ground
the guide stays at standing height: 6 cm over it, the hexapod's body rose to the guide at
every advance and sank 9 cm at every step on flat ground (its COM between 0.10 and 0.17 m)."""


def body_span(checker: ReachabilityChecker) -> tuple[float, float, float]:
    """(half length, half width, standing height) in m of the character's stance at the
    reference posture: the feet's extent in the root frame (the length 0.1 m longer, and
    at least 0.3 m, so the slope is measured over about a stride), and the root's height
    above them."""
    offsets = reference_offsets(checker.character)
    feet = np.array([offsets[x] for x in ground_limbs(checker.character)] or [np.zeros(3)])
    half_length = max(0.3, float(np.max(np.abs(feet[:, 0]))) + 0.1)
    half_width = float(np.max(np.abs(feet[:, 1])))
    return half_length, half_width, float(-np.mean(feet[:, 2]))


def terrain_line(
    scene: Scene, pose: FloatArray, half_length: float, half_width: float
) -> tuple[float, float] | None:
    """(height m, slope dz/ds) of the line fitted to the terrain under the pose (4, 4)
    along its heading, over ``half_length`` m either way, taking the highest ground across
    ``half_width`` m either side; None when no ground is under it."""
    fit = terrain_fit(scene, pose, half_length, half_width)
    return None if fit is None else (fit[0], fit[1])


def terrain_fit(
    scene: Scene, pose: FloatArray, half_length: float, half_width: float
) -> tuple[float, float, float] | None:
    """:func:`terrain_line`'s (height m, slope dz/ds) and the terrain's roughness: the
    largest distance (m) of a terrain sample from that line; None when no ground is under
    the pose."""
    yaw = math.atan2(pose[1, 0], pose[0, 0])
    ahead = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    side = np.array([-ahead[1], ahead[0], 0.0])
    top = pose[:3, 3] + np.array([0.0, 0.0, _CEILING])
    us = np.linspace(-half_length, half_length, _SAMPLES_ALONG)
    across = np.array([-half_width, 0.0, half_width])
    # (samples along, 3 across): the highest ground across at each sample along
    points = (top + us[:, None, None] * ahead) + across[None, :, None] * side
    found = scene.heights_below(points.reshape(-1, 3)).reshape(len(us), len(across))
    known = ~np.isnan(found).all(axis=1)
    if int(known.sum()) < 2:
        return None
    along = us[known]
    heights = np.nanmax(found[known], axis=1)
    slope, height = np.polyfit(along, heights, 1)
    residue = heights - (height + slope * along)
    return float(height), float(slope), float(np.max(np.abs(residue)))


def along_slope(yaw: float, slope: float, max_pitch: float) -> tuple[FloatArray, float]:
    """(3, 3) rotation facing ``yaw`` (rad) with the nose raised along ground of ``slope``
    (dz/ds), and that pitch (rad, within ``max_pitch``); R = Rz(yaw) Ry(-pitch)."""
    pitch = float(np.clip(math.atan(slope), -max_pitch, max_pitch))
    rotation = euler_matrices(np.array([yaw]), np.array([-pitch]), np.zeros(1))[0]
    return np.asarray(rotation, dtype=np.float64), pitch


def _settle(
    checker: ReachabilityChecker,
    poses: FloatArray,
    max_pitch: float,
    window: float,
    max_lift: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """``poses`` (n, 4, 4) facing along the path, pitched along the terrain and at standing
    height above it, and whether each settled pose is valid (an invalid one is returned
    unchanged). The ends are kept."""
    half_length, half_width, stand = body_span(checker)
    xyz = poses[:, :3, 3]
    lines = [terrain_fit(checker.scene, p, half_length, half_width) for p in poses]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
    out = poses.copy()
    valid = np.ones(len(poses), dtype=bool)
    for i in range(1, len(poses) - 1):
        near = [
            line
            for j, line in enumerate(lines)
            if line is not None and abs(arc[j] - arc[i]) <= window
        ]
        ahead = xyz[min(i + 2, len(poses) - 1), :2] - xyz[max(i - 2, 0), :2]
        if not near or float(np.linalg.norm(ahead)) < 1e-6:
            valid[i] = checker.is_valid(poses[i])
            continue
        yaw = math.atan2(ahead[1], ahead[0])
        height = float(np.mean([h for h, _, _ in near]))
        slope = float(np.mean([s for _, s, _ in near]))
        # raised over rough ground only: on even ground the legs walk at standing height
        rough = max(r for _, _, r in near) > _ROUGH_GROUND
        pose = np.eye(4)
        pose[:3, :3], pitch = along_slope(yaw, slope, max_pitch)
        pose[:3, 3] = (*poses[i, :2, 3], height + stand / math.cos(pitch))
        for lift in np.arange(0.0, max_lift + 1e-9, _LIFT_STEP):
            lifted = pose.copy()
            lifted[2, 3] += lift
            if checker.is_valid(lifted):
                out[i] = lifted
                if rough or lift > 0.0:
                    lifted = lifted.copy()
                    lifted[2, 3] += _CLEARANCE
                    if checker.is_valid(lifted):
                        out[i] = lifted
                break
        else:
            valid[i] = checker.is_valid(poses[i])
    return out, valid


def follow_slope(
    checker: ReachabilityChecker,
    poses: FloatArray,
    *,
    max_pitch: float,
    window: float = 0.3,
    max_lift: float = 0.2,
) -> FloatArray:
    """``poses`` (n, 4, 4, world) facing along the path, pitched along the terrain (at most
    ``max_pitch`` rad) and each at the standing height above the terrain line, lines
    averaged over ``window`` m of path either way. The ends stay as given (they are the
    start and goal states' roots); a pose whose trunk collides or whose limbs reach nothing
    at every lift up to ``max_lift`` m keeps its own pose."""
    poses = np.asarray(poses, dtype=np.float64)
    if len(poses) < 3:
        return poses.copy()
    return _settle(checker, poses, max_pitch, window, max_lift)[0]


def straight_slope_path(
    checker: ReachabilityChecker,
    start: FloatArray,
    goal: FloatArray,
    *,
    spacing: float,
    max_pitch: float,
    window: float = 0.3,
    max_lift: float = 0.2,
) -> FloatArray | None:
    """The straight line over the terrain from root pose ``start`` to ``goal`` (4, 4), as
    poses (n, 4, 4) ``spacing`` m apart laid by :func:`follow_slope`; None unless every pose
    is valid (a climb up a wall or a staircase needs no search)."""
    a, b = (np.asarray(x, dtype=np.float64).reshape(4, 4) for x in (start, goal))
    n = max(3, math.ceil(float(np.linalg.norm(b[:2, 3] - a[:2, 3])) / spacing) + 1)
    line = np.repeat(a[None], n, axis=0)
    line[:, :3, 3] = np.linspace(a[:3, 3], b[:3, 3], n)
    line[-1] = b
    settled, valid = _settle(checker, line, max_pitch, window, max_lift)
    if not (checker.is_valid(a) and checker.is_valid(b) and bool(np.all(valid))):
        return None
    return settled
