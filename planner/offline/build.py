"""Computation of a character's offline data (workspaces, sample databases, COM constraints).

Pure functions of (character, params, rng seed) returning plain arrays; :mod:`planner.offline.
data` wraps them into frozen values and caches them on disk.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from planner.character.batch_fk import (
    TreeKinematics,
    center_of_mass,
    frame_jacobian,
    frame_placement,
    joint_placements,
)
from planner.character.collision import SelfCollisionChecker
from planner.character.model import Character, Limb

FloatArray = NDArray[np.float64]
Arrays = dict[str, FloatArray]
Progress = Callable[[int], object]


@dataclass(frozen=True, slots=True)
class OfflineParams:
    """Sizes of the offline data. Defaults are the production sizes (issue 2).

    workspace_samples : collision-free limb samples whose effector positions span Wk.
    database_samples : samples kept in each limb's database (the first ones drawn).
    com_samples : collision-free whole-body samples for the COM constraints.
    voxel_size : edge of the database's voxel hash, m. chunk_size : batch size.
    max_attempts_factor : give up after this many times the requested samples were drawn.
    """

    workspace_samples: int = 100_000
    database_samples: int = 10_000
    com_samples: int = 100_000
    voxel_size: float = 0.05
    chunk_size: int = 10_000
    max_attempts_factor: int = 20

    def __post_init__(self) -> None:
        for name in ("workspace_samples", "com_samples"):
            if getattr(self, name) < 10:
                raise ValueError(f"{name} must be >= 10")
        if not 1 <= self.database_samples <= self.workspace_samples:
            raise ValueError("database_samples must be in [1, workspace_samples]")
        if self.voxel_size <= 0 or self.chunk_size < 1 or self.max_attempts_factor < 1:
            raise ValueError("voxel_size, chunk_size and max_attempts_factor must be positive")

    def as_dict(self) -> dict[str, float]:
        """Parameters as a JSON-friendly mapping (part of the cache key)."""
        return dict(asdict(self))


def _moving_joints(kin: TreeKinematics, limb: Limb) -> NDArray[np.bool_]:
    """(J,) mask of the joints whose placement depends on the limb's joints."""
    moving = np.zeros(kin.n_joints, dtype=bool)
    moving[np.asarray(limb.joint_ids)] = True
    for j in range(2, kin.n_joints):  # parents precede children in Pinocchio's order
        if moving[kin.parents[j]]:
            moving[j] = True
    return moving


def _limb_pairs(
    kin: TreeKinematics,
    checker: SelfCollisionChecker,
    limb: Limb,
    moving: NDArray[np.bool_],
    base: tuple[FloatArray, FloatArray],
) -> NDArray[np.bool_]:
    """(p,) mask of the pairs that can collide when only the limb moves: at least one
    geometry moves, and a static one is not out of reach of the moving one. The reach of a
    moving geometry bounds its distance to the limb root joint origin in any configuration
    (sum of the link offsets below the root plus the farthest capsule point)."""
    root = int(limb.joint_ids[0])
    origin = base[1][0, root]
    reach = np.zeros(len(checker.joint))
    for g, j in enumerate(checker.joint):
        if not moving[j]:
            continue
        length = 0.0
        k = int(j)
        while k != root:
            length += float(np.linalg.norm(kin.placement_t[k]))
            k = int(kin.parents[k])
        ends = max(np.linalg.norm(checker.cap_a[g]), np.linalg.norm(checker.cap_b[g]))
        reach[g] = length + float(ends) + float(checker.cap_r[g])
    keep = np.zeros(len(checker.pairs), dtype=bool)
    rot0, trans0 = base[0][0], base[1][0]
    for p, (ga, gb) in enumerate(checker.pairs):
        move_a, move_b = moving[checker.joint[ga]], moving[checker.joint[gb]]
        if move_a and move_b:
            keep[p] = True
        elif move_a or move_b:
            g_move, g_static = (ga, gb) if move_a else (gb, ga)
            j = checker.joint[g_static]
            end_a = rot0[j] @ checker.cap_a[g_static] + trans0[j]
            end_b = rot0[j] @ checker.cap_b[g_static] + trans0[j]
            seg = end_b - end_a
            t = np.clip(np.dot(origin - end_a, seg) / max(np.dot(seg, seg), 1e-12), 0.0, 1.0)
            gap = np.linalg.norm(end_a + t * seg - origin) - checker.cap_r[g_static]
            keep[p] = gap <= reach[g_move]
    return keep


def _collect(
    draw: Callable[[int], FloatArray],
    checker: SelfCollisionChecker,
    kin: TreeKinematics,
    need: int,
    params: OfflineParams,
    what: str,
    progress: Progress | None,
    keep: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    moving: NDArray[np.bool_] | None = None,
    base: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[list[FloatArray], list[FloatArray]]:
    """Draw chunks of joint samples until ``need`` are collision-free; returns the kept joint
    rows and whatever ``keep(q, R, t)`` extracts from them, both in chunks."""
    qs: list[FloatArray] = []
    out: list[FloatArray] = []
    have = 0
    drawn = 0
    while have < need:
        if drawn >= need * params.max_attempts_factor:
            raise RuntimeError(
                f"{what}: only {have} of {need} collision-free samples after {drawn} draws"
            )
        q = draw(params.chunk_size)
        drawn += len(q)
        rot, trans = joint_placements(kin, q, moving, base)
        free = ~checker.colliding(rot, trans, moving)
        take = np.nonzero(free)[0][: need - have]
        if len(take):
            qs.append(q[take])
            out.append(keep(q[take], rot[take], trans[take]))
            have += len(take)
            if progress is not None:
                progress(len(take))
    return qs, out


def build_limb(
    character: Character,
    limb_index: int,
    kin: TreeKinematics,
    checker: SelfCollisionChecker,
    params: OfflineParams,
    rng: np.random.Generator,
    progress: Progress | None = None,
) -> Arrays:
    """Workspace points and database of one limb; the other joints stay at the reference.

    Returns arrays ``positions`` (workspace_samples, 3) and ``db_q``, ``db_positions``,
    ``db_rotations``, ``db_jacobians``, ``db_cost`` (database_samples, ...), root frame.
    """
    limb = character.limbs[limb_index]
    cols = np.asarray(limb.idx_q) - 7
    lo, hi = character.lower[cols], character.upper[cols]
    base = character.q_ref_joints
    frame = character.model.frames[limb.frame_id]
    f_joint = int(frame.parentJoint)
    f_rot = np.array(frame.placement.rotation)
    f_trans = np.array(frame.placement.translation)
    moving = _moving_joints(kin, limb)
    base_placements = joint_placements(kin, base[None, :])
    limb_checker = checker.subset(_limb_pairs(kin, checker, limb, moving, base_placements))

    def draw(n: int) -> FloatArray:
        q = np.tile(base, (n, 1))
        q[:, cols] = rng.uniform(lo, hi, size=(n, len(cols)))
        return q

    def keep(q: FloatArray, rot: FloatArray, trans: FloatArray) -> FloatArray:
        r_f, t_f = frame_placement(rot, trans, f_joint, f_rot, f_trans)
        return np.concatenate([t_f, r_f.reshape(-1, 9)], axis=1)

    qs, kept = _collect(
        draw,
        limb_checker,
        kin,
        params.workspace_samples,
        params,
        f"limb {limb.name}",
        progress,
        keep,
        moving,
        base_placements,
    )
    q_all = np.concatenate(qs)[:, cols]
    placements = np.concatenate(kept)
    n_db = params.database_samples
    db_q_full = np.tile(base, (n_db, 1))
    db_q_full[:, cols] = q_all[:n_db]
    rot, trans = joint_placements(kin, db_q_full, moving, base_placements)
    r_f, t_f = frame_placement(rot, trans, f_joint, f_rot, f_trans)
    jac = frame_jacobian(kin, rot, trans, np.asarray(limb.joint_ids), t_f)
    diff = q_all[:n_db] - base[cols]
    cost = np.sqrt(np.sum(np.asarray(limb.posture_weights) * diff * diff, axis=1))
    return {
        "positions": placements[:, :3].copy(),
        "db_q": q_all[:n_db].copy(),
        "db_positions": t_f,
        "db_rotations": r_f,
        "db_jacobians": jac,
        "db_cost": cost,
    }


def build_com(
    character: Character,
    kin: TreeKinematics,
    checker: SelfCollisionChecker,
    params: OfflineParams,
    rng: np.random.Generator,
    progress: Progress | None = None,
) -> FloatArray:
    """(com_samples, L, 3) whole-body COM of collision-free samples (all joints uniform within
    limits) relative to each of the L limbs' effectors: in the effector frame for patch
    contacts, along the root frame's axes for point contacts (whose frame orientation is
    arbitrary; see ``planner.contact.checks.make_contact``)."""
    lo, hi = character.lower, character.upper
    frames = [character.model.frames[limb.frame_id] for limb in character.limbs]
    f_joints = [int(f.parentJoint) for f in frames]
    f_rots = [np.array(f.placement.rotation) for f in frames]
    f_trans = [np.array(f.placement.translation) for f in frames]

    def draw(n: int) -> FloatArray:
        return np.asarray(rng.uniform(lo, hi, size=(n, len(lo))), dtype=np.float64)

    points = [limb.contact == "point" for limb in character.limbs]

    def keep(q: FloatArray, rot: FloatArray, trans: FloatArray) -> FloatArray:
        com = center_of_mass(kin, rot, trans)
        per_limb = []
        for j, fr, ft, point in zip(f_joints, f_rots, f_trans, points, strict=True):
            r_f, t_f = frame_placement(rot, trans, j, fr, ft)
            if point:  # a point contact has no orientation: axes of the root frame
                per_limb.append(com - t_f)
            else:
                per_limb.append(np.einsum("nba,nb->na", r_f, com - t_f))
        return np.stack(per_limb, axis=1)

    _, kept = _collect(draw, checker, kin, params.com_samples, params, "whole body", progress, keep)
    return np.concatenate(kept)


def build_all(
    character: Character,
    params: OfflineParams,
    seed: int,
    progress: Progress | None = None,
) -> tuple[list[Arrays], FloatArray]:
    """Every limb's arrays and the COM samples. Limb i uses the generator seeded with
    [seed, i], the whole body [seed, 1000]: results do not depend on the limb order of
    evaluation."""
    kin = TreeKinematics.from_model(character.model)
    checker = SelfCollisionChecker.from_geometry_model(character.geometry)
    limbs = [
        build_limb(character, i, kin, checker, params, np.random.default_rng([seed, i]), progress)
        for i in range(len(character.limbs))
    ]
    com = build_com(character, kin, checker, params, np.random.default_rng([seed, 1000]), progress)
    return limbs, com
