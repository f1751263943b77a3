"""Root path planning over the reduced model (anchor section 3): RRT-Connect, then shortcuts.

Configurations are root poses (4, 4, world frame). Steering is straight: linear in position,
geodesic in rotation. The distance between two poses is ``max(|dp|, radius * angle)`` (m), with
``radius`` the trunk's reach from the root (``ReachabilityChecker.radius``), so it bounds how far
any trunk point moves. An edge is checked at ``ceil(d / step) + 1`` evenly spaced poses (both
ends included), with ``step`` <= 0.05 m by default; the same spacing is used everywhere, so an
edge of the returned path re-checked this way is valid.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.contact.reachability import ReachabilityChecker
from planner.contact.root_sampler import OrientationBounds, sample_root_poses
from planner.result import PlanResult, PlanStatus
from planner.termination import Termination

FloatArray = NDArray[np.float64]


def _rotation_log(rotation: FloatArray) -> FloatArray:
    """(3,) rotation vector of a (3, 3) rotation (angle in [0, pi])."""
    cos = float(np.clip((np.trace(rotation) - 1.0) / 2.0, -1.0, 1.0))
    angle = math.acos(cos)
    axis = np.array(
        [
            rotation[2, 1] - rotation[1, 2],
            rotation[0, 2] - rotation[2, 0],
            rotation[1, 0] - rotation[0, 1],
        ]
    )
    if angle < 1e-9:
        return 0.5 * axis
    if math.pi - angle < 1e-6:  # near pi: axis from the symmetric part
        sym = (rotation + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(sym)))
        v = sym[:, k] / math.sqrt(max(sym[k, k], 1e-300))
        return np.asarray(v / np.linalg.norm(v) * angle, dtype=np.float64)
    return np.asarray(axis * (angle / (2.0 * math.sin(angle))), dtype=np.float64)


def _rotation_exp(vectors: FloatArray) -> FloatArray:
    """(n, 3, 3) rotations of (n, 3) rotation vectors (Rodrigues)."""
    theta = np.linalg.norm(vectors, axis=1)
    small = theta < 1e-12
    safe = np.where(small, 1.0, theta)
    k = vectors / safe[:, None]
    kx = np.zeros((len(vectors), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2] = -k[:, 2], k[:, 1]
    kx[:, 1, 0], kx[:, 1, 2] = k[:, 2], -k[:, 0]
    kx[:, 2, 0], kx[:, 2, 1] = -k[:, 1], k[:, 0]
    s = np.where(small, 0.0, np.sin(theta))[:, None, None]
    c = np.where(small, 0.0, 1.0 - np.cos(theta))[:, None, None]
    return np.asarray(np.eye(3) + s * kx + c * (kx @ kx), dtype=np.float64)


def interpolate_poses(a: FloatArray, b: FloatArray, t: FloatArray) -> FloatArray:
    """(m, 4, 4) poses at fractions ``t`` (m,) in [0, 1] of the straight edge a -> b (4, 4)."""
    ts = np.asarray(t, dtype=np.float64).reshape(-1)
    log = _rotation_log(a[:3, :3].T @ b[:3, :3])
    out = np.zeros((len(ts), 4, 4))
    out[:, :3, :3] = a[:3, :3] @ _rotation_exp(ts[:, None] * log)
    out[:, :3, 3] = a[:3, 3] + ts[:, None] * (b[:3, 3] - a[:3, 3])
    out[:, 3, 3] = 1.0
    return out


def pose_distance(a: FloatArray, b: FloatArray, radius: float) -> float:
    """``max(|p_b - p_a|, radius * angle(R_a^T R_b))`` in metres."""
    cos = float(np.clip((np.sum(a[:3, :3] * b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0))
    return max(float(np.linalg.norm(b[:3, 3] - a[:3, 3])), radius * math.acos(cos))


def _distances(nodes: FloatArray, pose: FloatArray, radius: float) -> FloatArray:
    """(n,) pose_distance from (n, 4, 4) nodes to one pose."""
    cos = np.clip((np.einsum("nij,ij->n", nodes[:, :3, :3], pose[:3, :3]) - 1.0) / 2.0, -1, 1)
    linear = np.linalg.norm(nodes[:, :3, 3] - pose[:3, 3], axis=1)
    return np.asarray(np.maximum(linear, radius * np.arccos(cos)), dtype=np.float64)


def edge_poses(a: FloatArray, b: FloatArray, step: float, radius: float) -> FloatArray:
    """The (k + 1, 4, 4) poses at which the edge a -> b is checked, k = ceil(d / step) >= 1."""
    k = max(1, math.ceil(pose_distance(a, b, radius) / step - 1e-9))
    return interpolate_poses(a, b, np.linspace(0.0, 1.0, k + 1))


@dataclass(frozen=True, slots=True)
class RootPath:
    """A piecewise-straight root path.

    poses : (n, 4, 4) waypoints, world frame. lengths : (n,) cumulative pose distance (m) from
    the first waypoint (see the module docstring); ``lengths[-1]`` is the path length.
    radius : m, the rotation weight of the distance.
    """

    poses: FloatArray
    lengths: FloatArray
    radius: float = 1.0

    def __post_init__(self) -> None:
        poses = np.array(self.poses, dtype=np.float64)
        lengths = np.array(self.lengths, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) < 1:
            raise ValueError("poses must be (n, 4, 4) with n >= 1")
        if lengths.shape != (len(poses),) or np.any(np.diff(lengths) < 0):
            raise ValueError("lengths must be (n,) and non-decreasing")
        poses.flags.writeable = False
        lengths.flags.writeable = False
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "lengths", lengths)

    @staticmethod
    def from_poses(poses: FloatArray, radius: float) -> RootPath:
        """The path through (n, 4, 4) waypoints, lengths measured with ``radius``."""
        p = np.asarray(poses, dtype=np.float64)
        steps = [pose_distance(p[i], p[i + 1], radius) for i in range(len(p) - 1)]
        return RootPath(p, np.concatenate([[0.0], np.cumsum(steps)]), radius)

    @property
    def length(self) -> float:
        """Total length (m)."""
        return float(self.lengths[-1])

    def interpolate(self, s: float | FloatArray) -> FloatArray:
        """Pose(s) at arc length ``s`` (clipped to [0, length]): (4, 4) for a scalar, else
        (m, 4, 4) for (m,) values."""
        scalar = np.ndim(s) == 0
        values = np.clip(np.asarray(s, dtype=np.float64).reshape(-1), 0.0, self.length)
        out = np.zeros((len(values), 4, 4))
        if len(self.poses) == 1:
            out[:] = self.poses[0]
            return out[0] if scalar else out
        segment = np.clip(
            np.searchsorted(self.lengths, values, side="right") - 1, 0, len(self.poses) - 2
        )
        for i in np.unique(segment):
            rows = segment == i
            span = self.lengths[i + 1] - self.lengths[i]
            t = (values[rows] - self.lengths[i]) / span if span > 0 else np.zeros(rows.sum())
            out[rows] = interpolate_poses(self.poses[i], self.poses[i + 1], t)
        return out[0] if scalar else out

    def resample(self, step: float) -> FloatArray:
        """(m, 4, 4) poses every ``step`` m of arc length, both ends included."""
        k = max(1, math.ceil(self.length / step))
        return self.interpolate(np.linspace(0.0, self.length, k + 1))


@dataclass(slots=True)
class _Tree:
    poses: list[FloatArray]
    parents: list[int]
    stack: FloatArray = field(default_factory=lambda: np.zeros((0, 4, 4)))

    def add(self, pose: FloatArray, parent: int) -> int:
        self.poses.append(pose)
        self.parents.append(parent)
        return len(self.poses) - 1

    def nearest(self, pose: FloatArray, radius: float) -> int:
        if len(self.stack) != len(self.poses):
            self.stack = np.stack(self.poses)
        return int(np.argmin(_distances(self.stack, pose, radius)))

    def branch(self, index: int) -> list[FloatArray]:
        """Poses from the root to ``index``."""
        out = []
        while index >= 0:
            out.append(self.poses[index])
            index = self.parents[index]
        return out[::-1]


def _steer(
    checker: ReachabilityChecker, a: FloatArray, b: FloatArray, step: float, max_length: float
) -> tuple[FloatArray | None, bool]:
    """Walk the straight edge a -> b (cut at ``max_length``); (farthest valid pose reached along
    it with a valid canonical edge from ``a``, or None; whether ``b`` itself was reached)."""
    d = pose_distance(a, b, checker.radius)
    if d < 1e-9:
        return None, True
    target = b if d <= max_length else interpolate_poses(a, b, np.array([max_length / d]))[0]
    poses = edge_poses(a, target, step, checker.radius)
    first = first_invalid(checker, poses)
    if first == len(poses):
        return target, target is b
    last = first - 1  # poses[0] = a is valid, so last >= 0
    if last < 1:
        return None, False
    reached = poses[last]
    if not edge_valid(checker, a, reached, step):
        return None, False
    return reached, False


def first_invalid(checker: ReachabilityChecker, poses: FloatArray, stride: int = 8) -> int:
    """Index of the first of the (n, 4, 4) poses failing the condition, n if none does.

    Coarse to fine: every ``stride``-th pose first, then only the poses before the first
    coarse failure, so a blocked edge usually costs a fraction of a full check.
    """
    n = len(poses)
    coarse = np.arange(0, n, stride)
    bad = np.flatnonzero(~checker.valid(poses[coarse]))
    end = int(coarse[bad[0]]) if len(bad) else n
    rest = np.setdiff1d(np.arange(end), coarse)
    failing = rest[~checker.valid(poses[rest])] if len(rest) else rest
    return int(failing[0]) if len(failing) else end


def edge_valid(checker: ReachabilityChecker, a: FloatArray, b: FloatArray, step: float) -> bool:
    """Whether every pose of the straight edge from root pose ``a`` to ``b`` (4, 4), checked
    every ``step`` m, meets the reachability condition."""
    poses = edge_poses(a, b, step, checker.radius)
    return first_invalid(checker, poses) == len(poses)


def shortcut(
    checker: ReachabilityChecker,
    path: RootPath,
    *,
    rng: np.random.Generator,
    until: Termination,
    step: float = 0.05,
    iterations: int = 40,
    patience: int = 15,
) -> RootPath:
    """Shorten a valid path: first skip waypoints greedily (from each kept waypoint, the
    farthest one joined by a valid straight edge), then random shortcuts: replace the stretch
    between two random arc lengths by a straight edge when that edge (and the two cut edges)
    are valid and it is shorter; stop after ``iterations`` tries or ``patience`` failures in a
    row."""
    poses = _skip_waypoints(checker, list(path.poses), step, until)
    current = RootPath.from_poses(np.stack(poses), checker.radius)
    misses = 0
    for _ in range(iterations):
        if until() or current.length < 1e-6 or len(poses) < 3 or misses >= patience:
            break
        misses += 1
        s1, s2 = np.sort(rng.uniform(0.0, current.length, size=2))
        if s2 - s1 < 2 * step:
            continue
        i1 = int(np.searchsorted(current.lengths, s1, side="right") - 1)
        i2 = int(np.searchsorted(current.lengths, s2, side="left"))
        if i2 - i1 < 2:
            continue
        pa, pb = current.interpolate(s1), current.interpolate(s2)
        if pose_distance(pa, pb, checker.radius) >= s2 - s1 - 1e-6:
            continue
        new = [*poses[: i1 + 1], pa, pb, *poses[i2:]]
        if not (
            edge_valid(checker, pa, pb, step)
            and edge_valid(checker, poses[i1], pa, step)
            and edge_valid(checker, pb, poses[i2], step)
        ):
            continue
        poses = new
        current = RootPath.from_poses(np.stack(poses), checker.radius)
        misses = 0
    return current


def _skip_waypoints(
    checker: ReachabilityChecker, poses: list[FloatArray], step: float, until: Termination
) -> list[FloatArray]:
    out = [poses[0]]
    i = 0
    while i < len(poses) - 1:
        j = i + 1
        if not until():
            for k in range(len(poses) - 1, i + 1, -1):
                if edge_valid(checker, poses[i], poses[k], step):
                    j = k
                    break
        out.append(poses[j])
        i = j
    return out


def plan_root_path(
    checker: ReachabilityChecker,
    start: FloatArray,
    goal: FloatArray,
    *,
    rng: np.random.Generator,
    until: Termination,
    step: float = 0.05,
    max_iterations: int = 20_000,
    max_extension: float = 1.0,
    orientation_bounds: OrientationBounds | None = None,
    shortcut_iterations: int = 40,
) -> PlanResult[RootPath]:
    """Bidirectional RRT (RRT-Connect) from ``start`` to ``goal`` (4, 4 root poses, world).

    Samples come from :func:`sample_root_poses` within ``orientation_bounds``; trees alternate,
    each extension goes at most ``max_extension`` m toward the sample and the other tree then
    tries to connect to the new node. Edges are checked every ``step`` m (<= 0.05 m by
    default). The solution is then shortened by :func:`shortcut` (``shortcut_iterations``
    random tries). Statuses: INVALID_START / INVALID_GOAL when an endpoint fails the
    reachability condition, TIMEOUT when ``until`` fires or ``max_iterations`` run out first,
    INFEASIBLE when no sample can be drawn, SOLVED with the path otherwise. ``until`` is polled
    once per iteration; ``stats`` has iterations, nodes, raw_length, length, waypoints and
    seconds.
    """
    clock = time.perf_counter()
    a = np.asarray(start, dtype=np.float64).reshape(4, 4)
    b = np.asarray(goal, dtype=np.float64).reshape(4, 4)
    if not checker.is_valid(a):
        return PlanResult(PlanStatus.INVALID_START, None, message="start fails reachability")
    if not checker.is_valid(b):
        return PlanResult(PlanStatus.INVALID_GOAL, None, message="goal fails reachability")
    radius = checker.radius
    trees = (_Tree([a], [-1]), _Tree([b], [-1]))
    pool: list[FloatArray] = []
    empty_refills = 0
    found: tuple[int, int] | None = None
    if edge_valid(checker, a, b, step):
        found = (0, 0)
    iteration = 0
    while found is None:
        if until() or iteration >= max_iterations:
            partial: dict[str, float | int | str] = {
                "iterations": iteration,
                "nodes": sum(len(t.poses) for t in trees),
                "seconds": time.perf_counter() - clock,
            }
            return PlanResult(PlanStatus.TIMEOUT, None, partial, "no path within the budget")
        if not pool:
            pool = list(
                sample_root_poses(
                    checker, 16, rng=rng, orientation_bounds=orientation_bounds, max_rounds=4
                )[::-1]
            )
            if not pool:
                empty_refills += 1
                if empty_refills >= 5:
                    return PlanResult(
                        PlanStatus.INFEASIBLE,
                        None,
                        {"iterations": iteration},
                        "no valid root sample found",
                    )
                continue
        target = pool.pop()
        grow, other = (trees[0], trees[1]) if iteration % 2 == 0 else (trees[1], trees[0])
        iteration += 1
        near = grow.nearest(target, radius)
        new, _ = _steer(checker, grow.poses[near], target, step, max_extension)
        if new is None:
            continue
        new_index = grow.add(new, near)
        # connect: the other tree greedily extends toward the new node, without length cut
        near_other = other.nearest(new, radius)
        reached, hit = _steer(checker, other.poses[near_other], new, step, math.inf)
        if hit:
            found = (new_index, near_other) if grow is trees[0] else (near_other, new_index)
        elif reached is not None:
            other.add(reached, near_other)
    first = trees[0].branch(found[0])
    second = trees[1].branch(found[1])[::-1]
    raw = RootPath.from_poses(np.stack([*first, *second]), radius)
    final = shortcut(checker, raw, rng=rng, until=until, step=step, iterations=shortcut_iterations)
    stats: dict[str, float | int | str] = {
        "iterations": iteration,
        "nodes": sum(len(t.poses) for t in trees),
        "raw_length": raw.length,
        "length": final.length,
        "waypoints": len(final.poses),
        "seconds": time.perf_counter() - clock,
    }
    return PlanResult(PlanStatus.SOLVED, final, stats)
