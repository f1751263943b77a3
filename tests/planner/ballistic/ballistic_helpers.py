"""Brute-force helpers and scenes shared by the ballistic tests (imported by name)."""

from __future__ import annotations

import numpy as np

from planner.ballistic.arc import arc_length, slerp
from planner.ballistic.steering import Jump
from planner.ballistic.synthetic import BoxWorld, Platforms
from planner.poses import quaternion_to_matrix

GAP = 0.05
"""Arc sampling gap used by the planners in these tests (m)."""


def dense_collides(
    jump: Jump, q0: np.ndarray, q1: np.ndarray, world: BoxWorld, step: float = 0.002
) -> bool:
    """Brute-force trunk check every ``step`` metres of flight time (nominal, uninflated)."""
    length = float(arc_length(jump.xdot, jump.v0[2], jump.duration, jump.g))
    n = max(2, int(np.ceil(length / step)) + 1)
    tau = np.linspace(0.0, jump.duration, n)
    pos = jump.position(tau)
    poses = np.zeros((n, 4, 4))
    poses[:, :3, :3] = quaternion_to_matrix(slerp(q0, q1, tau / jump.duration))
    poses[:, :3, 3] = pos
    poses[:, 3, 3] = 1.0
    return bool(world(poses).any())


def gap_scene() -> tuple[Platforms, BoxWorld]:
    """Three platforms (the middle one higher) with 1 m gaps, a pillar standing in the first gap
    (x in [2.4, 2.6], y in [0, 1], up to z = 1.2), and a 3-sphere trunk world."""
    plat = Platforms(lo=[[0, 0], [3, 0], [6, 0]], hi=[[2, 2], [5, 2], [8, 2]], top=[0, 0.6, 0])
    lo, hi = plat.boxes()
    lo = np.vstack([lo, [[2.4, 0.0, -1.0]]])
    hi = np.vstack([hi, [[2.6, 1.0, 1.2]]])
    world = BoxWorld(
        centres=[[-0.2, 0, 0], [0, 0, 0], [0.2, 0, 0]], radius=0.12, box_lo=lo, box_hi=hi
    )
    return plat, world
