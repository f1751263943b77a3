"""Batched forward kinematics of a character's joint tree in numpy (root frame).

Pinocchio costs ~1-2 us per call but a Python loop around it ~5 us per sample; the offline
builds need millions of placements, so this module re-implements forward kinematics,
frame placements, centre of mass and frame Jacobians for a batch of configurations at once.
Everything is expressed in the ROOT frame: the free-flyer root joint sits at the identity.
It supports 1-DoF revolute joints (Pinocchio RX, RY, RZ and revolute-unaligned), which
``planner.character.model`` checks when it loads a character. Tests compare with Pinocchio.

Glossary: N batch size, J number of Pinocchio joints (universe and root included),
n number of actuated joints (``q_joints`` columns, configuration order after the free flyer).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_AXES = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}


def _ro(array: Any, dtype: Any = np.float64) -> Any:
    out = np.array(array, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True)
class TreeKinematics:
    """Constant data of the joint tree, extracted once from a Pinocchio model.

    parents : (J,) parent joint index (-1 for the universe).
    placement_R, placement_t : (J, 3, 3), (J, 3) joint placement in its parent joint frame.
    axes : (J, 3) unit rotation axis in the joint frame (zero for universe/root).
    q_col : (J,) column of the joint in ``q_joints`` (-1 for universe/root).
    masses : (J,) kg; levers : (J, 3) body COM in the joint frame.
    """

    parents: IntArray
    placement_R: FloatArray
    placement_t: FloatArray
    axes: FloatArray
    q_col: IntArray
    masses: FloatArray
    levers: FloatArray

    @property
    def n_joints(self) -> int:
        """Number of Pinocchio joints J (universe and root included)."""
        return len(self.parents)

    @staticmethod
    def from_model(model: Any) -> TreeKinematics:
        """Extract the tree of a Pinocchio model whose joint 1 is the free-flyer root."""
        nj = model.njoints
        parents = np.full(nj, -1, dtype=np.int64)
        rot = np.tile(np.eye(3), (nj, 1, 1))
        trans = np.zeros((nj, 3))
        axes = np.zeros((nj, 3))
        q_col = np.full(nj, -1, dtype=np.int64)
        masses = np.zeros(nj)
        levers = np.zeros((nj, 3))
        for j in range(1, nj):
            parents[j] = model.parents[j]
            rot[j] = model.jointPlacements[j].rotation
            trans[j] = model.jointPlacements[j].translation
            masses[j] = model.inertias[j].mass
            levers[j] = model.inertias[j].lever
            if j >= 2:
                joint = model.joints[j]
                name = joint.shortname()
                if name in _AXES:
                    axes[j] = _AXES[name]
                elif name == "JointModelRevoluteUnaligned":
                    axes[j] = np.asarray(joint.extract().axis, dtype=np.float64)
                else:
                    raise ValueError(
                        f"joint {model.names[j]!r}: unsupported type {name} (only 1-DoF "
                        "bounded revolute joints are supported)"
                    )
                q_col[j] = joint.idx_q - 7
        return TreeKinematics(
            _ro(parents, np.int64),
            _ro(rot),
            _ro(trans),
            _ro(axes),
            _ro(q_col, np.int64),
            _ro(masses),
            _ro(levers),
        )


def _rotations(axis: FloatArray, angles: FloatArray) -> FloatArray:
    """(N, 3, 3) rotations of ``angles`` (N,) rad about the unit ``axis`` (3,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s = np.sin(angles)[:, None, None]
    c = (1.0 - np.cos(angles))[:, None, None]
    return np.asarray(np.eye(3) + s * k + c * (k @ k), dtype=np.float64)


def _placed_rotations(placement: FloatArray, axis: FloatArray, angles: FloatArray) -> FloatArray:
    """(N, 3, 3) products placement @ Rot(axis, angle): P + sin P K + (1 - cos) P K^2."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    pk = placement @ k
    s = np.sin(angles)[:, None, None]
    c = (1.0 - np.cos(angles))[:, None, None]
    return np.asarray(placement + s * pk + c * (pk @ k), dtype=np.float64)


def joint_placements(
    kin: TreeKinematics,
    q_joints: FloatArray,
    moving: NDArray[np.bool_] | None = None,
    base: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Placements of every joint frame in the root frame.

    q_joints : (N, n) joint values, rad. With ``moving`` (J,) and ``base`` (the (1, J, 3, 3),
    (1, J, 3) placements of a configuration that agrees with every row of ``q_joints`` on the
    joints outside ``moving``), only the moving joints are recomputed (``moving`` must contain
    the descendants of its joints).
    Returns R (N, J, 3, 3) and t (N, J, 3).
    """
    q = np.asarray(q_joints, dtype=np.float64)
    n_batch = q.shape[0]
    nj = kin.n_joints
    if base is not None and moving is not None:
        rot = np.repeat(base[0], n_batch, axis=0)
        trans = np.repeat(base[1], n_batch, axis=0)
        needed = moving
    else:
        rot = np.zeros((n_batch, nj, 3, 3))
        rot[:, :] = np.eye(3)
        trans = np.zeros((n_batch, nj, 3))
        needed = np.ones(nj, dtype=bool)
    for j in range(2, nj):
        if not needed[j]:
            continue
        p = int(kin.parents[j])
        local = _placed_rotations(kin.placement_R[j], kin.axes[j], q[:, kin.q_col[j]])
        if p <= 1:
            rot[:, j] = local
            trans[:, j] = kin.placement_t[j]
        else:
            r_p = rot[:, p]
            rot[:, j] = r_p @ local
            trans[:, j] = trans[:, p] + r_p @ kin.placement_t[j]
    return rot, trans


def frame_placement(
    rot: FloatArray, trans: FloatArray, joint: int, frame_R: FloatArray, frame_t: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(N, 3, 3), (N, 3) placement in the root frame of a frame fixed to ``joint`` at
    (frame_R, frame_t)."""
    r_j = rot[:, joint]
    return r_j @ frame_R, trans[:, joint] + r_j @ frame_t


def center_of_mass(kin: TreeKinematics, rot: FloatArray, trans: FloatArray) -> FloatArray:
    """(N, 3) whole-body COM in the root frame from full joint placements."""
    world_levers = np.einsum("njab,jb->nja", rot[:, 1:], kin.levers[1:]) + trans[:, 1:]
    weighted = np.einsum("nja,j->na", world_levers, kin.masses[1:])
    return np.asarray(weighted / kin.masses.sum(), dtype=np.float64)


def frame_jacobian(
    kin: TreeKinematics,
    rot: FloatArray,
    trans: FloatArray,
    chain: IntArray,
    point: FloatArray,
) -> FloatArray:
    """(N, 6, len(chain)) Jacobian [linear; angular] of a point of a frame, root-frame axes.

    chain : joint indices (revolute) whose columns are wanted; point : (N, 3) position of the
    frame origin in the root frame. Equals Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian
    with the root at the identity.
    """
    cols = []
    for j in np.asarray(chain):
        axis = rot[:, int(j)] @ kin.axes[int(j)]
        lever = point - trans[:, int(j)]
        cols.append(np.concatenate([np.cross(axis, lever), axis], axis=1))
    return np.asarray(np.stack(cols, axis=2), dtype=np.float64)
