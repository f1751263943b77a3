"""Fixtures for the kinematics tests: a small URDF humanoid built in memory, and Talos from
example-robot-data when it is installed (tests using it are skipped otherwise)."""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _link(name: str, mass: float, com: str = "0 0 0") -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>'
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
    )


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, lo: float, hi: float) -> str:
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>'
        f'<limit lower="{lo}" upper="{hi}" effort="100" velocity="10"/></joint>'
    )


def _fixed(name: str, parent: str, child: str, xyz: str) -> str:
    return (
        f'<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/></joint>'
    )


def biped_urdf() -> str:
    """A torso with two 6-dof legs (hip z/x/y, knee y, ankle y/x) and two 4-dof arms."""
    parts = ['<robot name="gecko_test_biped">', _link("torso", 10.0, "0 0 0.2")]
    for side, y in (("left", 0.1), ("right", -0.1)):
        leg = [
            ("hip_z", "0 0 1", -0.8, 0.8, f"0 {y} -0.05"),
            ("hip_x", "1 0 0", -0.6, 0.6, "0 0 0"),
            ("hip_y", "0 1 0", -1.8, 0.6, "0 0 0"),
            ("knee", "0 1 0", 0.0, 2.4, "0 0 -0.4"),
            ("ankle_y", "0 1 0", -1.0, 1.0, "0 0 -0.4"),
            ("ankle_x", "1 0 0", -0.5, 0.5, "0 0 0"),
        ]
        parent = "torso"
        for joint, axis, lo, hi, xyz in leg:
            link = f"{side}_{joint}_link"
            parts += [
                _link(link, 1.0, "0 0 -0.15"),
                _joint(f"{side}_{joint}", parent, link, xyz, axis, lo, hi),
            ]
            parent = link
        parts += [
            _link(f"{side}_sole", 0.1),
            _fixed(f"{side}_sole_joint", parent, f"{side}_sole", "0 0 -0.08"),
        ]
        arm = [
            ("shoulder_y", "0 1 0", -2.5, 2.5, f"0 {2.2 * y} 0.45"),
            ("shoulder_x", "1 0 0", -1.5, 1.5, "0 0 0"),
            ("shoulder_z", "0 0 1", -1.5, 1.5, "0 0 0"),
            ("elbow", "0 1 0", -2.2, 0.0, "0 0 -0.3"),
        ]
        parent = "torso"
        for joint, axis, lo, hi, xyz in arm:
            link = f"{side}_{joint}_link"
            parts += [
                _link(link, 0.5, "0 0 -0.1"),
                _joint(f"{side}_{joint}", parent, link, xyz, axis, lo, hi),
            ]
            parent = link
        parts += [
            _link(f"{side}_hand", 0.1),
            _fixed(f"{side}_hand_joint", parent, f"{side}_hand", "0 0 -0.3"),
        ]
    parts.append("</robot>")
    return "".join(parts)


def biped_model() -> pin.Model:
    """The test biped with a free-flyer root: nq = 27, nv = 26."""
    return pin.buildModelFromXML(biped_urdf(), pin.JointModelFreeFlyer())


def biped_standing(model: pin.Model) -> FloatArray:
    """A standing configuration with bent knees, soles about at z = 0."""
    q = np.asarray(pin.neutral(model), dtype=np.float64).copy()
    q[2] = 0.9
    for side in ("left", "right"):
        for joint, value in (("hip_y", -0.4), ("knee", 0.8), ("ankle_y", -0.4), ("elbow", -0.5)):
            j = model.getJointId(f"{side}_{joint}")
            q[model.idx_qs[j]] = value
    return q


def talos_model() -> pin.Model | None:
    """Talos (reduced) from example-robot-data with a free flyer, or None when not installed."""
    try:
        files = importlib.metadata.files("example-robot-data") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        if str(f).endswith("talos_reduced.urdf"):
            path = Path(str(f.locate()))
            if path.exists():
                return pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    return None


def talos_half_sitting(model: pin.Model) -> FloatArray:
    """Talos half-sitting posture (legs bent, arms down), root at the usual height."""
    q = np.asarray(pin.neutral(model), dtype=np.float64).copy()
    q[2] = 1.02
    values = {
        "leg_left_3_joint": -0.411354,
        "leg_left_4_joint": 0.859395,
        "leg_left_5_joint": -0.448041,
        "leg_right_3_joint": -0.411354,
        "leg_right_4_joint": 0.859395,
        "leg_right_5_joint": -0.448041,
        "arm_left_1_joint": 0.25847,
        "arm_left_2_joint": 0.173046,
        "arm_left_4_joint": -0.525366,
        "arm_right_1_joint": -0.25847,
        "arm_right_2_joint": -0.173046,
        "arm_right_4_joint": -0.525366,
    }
    for name, value in values.items():
        q[model.idx_qs[model.getJointId(name)]] = value
    return q


def random_configuration(
    model: pin.Model, rng: np.random.Generator, around: FloatArray, spread: float
) -> FloatArray:
    """``around`` (nq,) with every bounded joint moved by up to ``spread`` of its range,
    clipped into the limits; the root is kept."""
    q = around.copy()
    for j in range(2, model.njoints):
        if model.nqs[j] != 1:
            continue
        i = model.idx_qs[j]
        lo, hi = model.lowerPositionLimit[i], model.upperPositionLimit[i]
        q[i] = np.clip(q[i] + spread * (hi - lo) * rng.uniform(-0.5, 0.5), lo, hi)
    return q


@dataclass(frozen=True)
class Robot:
    """A test model with its standing posture and limb names."""

    name: str
    model: pin.Model
    q_stand: FloatArray
    feet: tuple[str, str]
    leg_roots: tuple[str, str]
    hands: tuple[str, str]
    arm_roots: tuple[str, str]


@pytest.fixture(scope="session")
def biped() -> Robot:
    model = biped_model()
    return Robot(
        "biped",
        model,
        biped_standing(model),
        ("left_sole", "right_sole"),
        ("left_hip_z", "right_hip_z"),
        ("left_hand", "right_hand"),
        ("left_shoulder_y", "right_shoulder_y"),
    )


@pytest.fixture(scope="session")
def talos() -> Robot:
    model = talos_model()
    if model is None:
        pytest.skip("example-robot-data (Talos) is not installed")
    return Robot(
        "talos",
        model,
        talos_half_sitting(model),
        ("left_sole_link", "right_sole_link"),
        ("leg_left_1_joint", "leg_right_1_joint"),
        ("gripper_left_base_link", "gripper_right_base_link"),
        ("arm_left_1_joint", "arm_right_1_joint"),
    )


@pytest.fixture(params=["biped", "talos"])
def robot(request: pytest.FixtureRequest) -> Robot:
    """Each test using this runs on the biped and on Talos."""
    result: Robot = request.getfixturevalue(request.param)
    return result


Perturb = Callable[[pin.Model, np.random.Generator, FloatArray, float], FloatArray]


@pytest.fixture(scope="session")
def perturb() -> Perturb:
    """:func:`random_configuration` (test modules cannot import conftest in importlib mode)."""
    return random_configuration
