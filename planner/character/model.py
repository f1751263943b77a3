"""Characters: a URDF plus a limb spec, loaded into a Pinocchio model with a free-flyer root.

Frames: the root frame is the free-flyer joint frame; limb quantities (effector placement,
workspace, sample database) are expressed in it. The reference configuration ``q_ref`` puts
the root above flat ground (z = 0) with the lowest limb contact point on the ground.
"""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character.collision import (
    add_contact_plates,
    add_trunk_shapes,
    capsule_geometry_model,
    drop_trunk_pairs,
    hull_geometry_model,
    set_collision_pairs,
)
from planner.character.spec import CharacterSpec, LimbSpec, SpecError, read_spec
from planner.poses import pose_matrix
from planner.shapes import Box, Capsule

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DATA_DIR = Path(__file__).with_name("data")
BUILTIN_IDS = ("humanoid", "quadruped", "hexapod")
REAL_ROBOT_IDS = ("talos", "hyq")
ERD_PREFIX = "package:example-robot-data/"


def _ro(array: Any, dtype: Any = np.float64) -> Any:
    out = np.array(array, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, slots=True)
class Limb:
    """A limb: the joints from ``root_joint`` to the effector frame, and its contact.

    half_size : (2,) m, patch half-sizes along the effector frame x, y (zeros for points).
    normal : (3,) unit contact normal in the effector frame (surface normal, pointing from the
    surface into the effector). offset : (3,) contact centre in the effector frame, m.
    joint_names : the limb's joints from root to tip; idx_q / idx_v : (n,) their indices in
    the full Pinocchio q / v; joint_ids : (n,) Pinocchio joint indices; frame_id : effector
    frame index. posture_weights : (n,) weights of the distance to the reference posture.
    """

    name: str
    root_joint: str
    effector_frame: str
    contact: str
    half_size: FloatArray
    normal: FloatArray
    offset: FloatArray
    mu: float
    joint_names: tuple[str, ...]
    idx_q: IntArray
    idx_v: IntArray
    joint_ids: IntArray
    frame_id: int
    posture_weights: FloatArray
    on_request: bool = False

    @property
    def n_joints(self) -> int:
        """Number of joints of the limb."""
        return len(self.joint_names)

    def contact_points(self) -> FloatArray:
        """(k, 3) contact points in the effector frame: 1 for ``point``, 4 corners for
        ``patch`` (around ``offset``, in the effector x-y plane)."""
        if self.contact == "point":
            return np.asarray(self.offset[None, :], dtype=np.float64)
        hx, hy = self.half_size
        corners = np.array([[hx, hy, 0.0], [hx, -hy, 0.0], [-hx, -hy, 0.0], [-hx, hy, 0.0]])
        return np.asarray(corners + self.offset, dtype=np.float64)


@dataclass(frozen=True, slots=True, eq=False)
class Character:
    """A loaded character.

    model : pin.Model with a free-flyer root (joint 1, ``root_joint``); geometry :
    pin.GeometryModel for self-collision (pairs declared, adjacent and reference-colliding
    pairs removed) of the planner's checks and offline data (in ``capsules`` mode, the
    capsules). motion_geometry : the body as the URDF models it (its ``<collision>`` shapes,
    meshes as their convex hulls; pairs declared the same way), which the whole-body motion
    keeps out of the scene and checks every keyframe against; ``geometry`` itself when the
    mode is ``urdf`` or the meshes cannot be read. joint_names : actuated joints in
    configuration order (free flyer excluded). q_ref : (nq,) reference standing
    configuration, root [x, y, z, qx, qy, qz, qw] then joints. lower / upper : (n,) joint
    limits, rad. trunk : W0 shapes in the root frame.
    """

    id: str
    spec_path: Path
    spec_text: str
    urdf_text: str
    spec: CharacterSpec
    model: Any
    geometry: Any
    motion_geometry: Any
    mass: float
    joint_names: tuple[str, ...]
    q_ref: FloatArray
    lower: FloatArray
    upper: FloatArray
    limbs: tuple[Limb, ...]
    trunk: tuple[Box | Capsule, ...]

    @property
    def n_joints(self) -> int:
        """Number of actuated joints (nq - 7)."""
        return len(self.joint_names)

    @property
    def q_ref_joints(self) -> FloatArray:
        """(n,) joint values of the reference posture."""
        return np.asarray(self.q_ref[7:], dtype=np.float64)

    @property
    def max_pitch(self) -> float:
        """How far (rad) the trunk may pitch while walking: about 0 for an upright humanoid;
        a multi-legged body climbing steps lies along them (spec ``max_pitch``)."""
        return float(self.spec.max_pitch)

    @property
    def default_limbs(self) -> tuple[Limb, ...]:
        """The limbs used unless asked otherwise: all but the ``on_request`` ones (the back of
        the thighs for sitting), which the Twister game and jumps leave alone."""
        return tuple(limb for limb in self.limbs if not limb.on_request)

    def limb(self, name: str) -> Limb:
        """The limb called ``name``; KeyError if absent."""
        for limb in self.limbs:
            if limb.name == name:
                return limb
        raise KeyError(f"character {self.id!r} has no limb {name!r}")


def example_robot_data_share() -> Path | None:
    """``<site-packages>/cmeel.prefix/share`` of example-robot-data, or None if missing."""
    try:
        files = importlib.metadata.files("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files or []:
        parts = Path(str(f)).parts
        if "example-robot-data" in parts and "share" in parts:
            located = Path(str(f.locate()))
            idx = len(parts) - parts.index("share") - 1
            return located.parents[idx - 1] if idx >= 1 else located
    return None


def resolve_urdf(spec: CharacterSpec, spec_path: Path) -> Path:
    """Absolute path of the spec's URDF (relative to the spec, or in example-robot-data)."""
    if spec.urdf.startswith(ERD_PREFIX):
        share = example_robot_data_share()
        if share is None:
            raise SpecError("urdf", "example-robot-data is not installed")
        path = share / "example-robot-data" / spec.urdf[len(ERD_PREFIX) :]
    else:
        path = (spec_path.parent / spec.urdf).resolve()
    if not path.is_file():
        raise SpecError("urdf", f"file not found: {path}")
    return path


def _trunk_shapes(spec: CharacterSpec) -> tuple[Box | Capsule, ...]:
    out: list[Box | Capsule] = []
    for shape in spec.trunk:
        rot = pin.rpy.rpyToMatrix(*shape.rpy)
        offset = pose_matrix(np.array(shape.position), np.asarray(rot, dtype=np.float64))
        if shape.kind == "box" and shape.half_extents is not None:
            out.append(Box(np.array(shape.half_extents), offset))
        elif shape.radius is not None and shape.half_length is not None:
            out.append(Capsule(shape.radius, shape.half_length, offset))
    return tuple(out)


def _limb(model: Any, spec: LimbSpec, i: int) -> Limb:
    where = f"limbs[{i}]"
    if not model.existJointName(spec.root_joint):
        raise SpecError(f"{where}.root_joint", f"no joint {spec.root_joint!r} in the URDF")
    if not model.existFrame(spec.effector_frame):
        raise SpecError(f"{where}.effector_frame", f"no frame {spec.effector_frame!r} in the URDF")
    root = model.getJointId(spec.root_joint)
    frame_id = model.getFrameId(spec.effector_frame)
    chain = []
    j = int(model.frames[frame_id].parentJoint)
    while j > 1 and j != root:
        chain.append(j)
        j = int(model.parents[j])
    if j != root:
        raise SpecError(
            f"{where}.root_joint",
            f"{spec.root_joint!r} is not an ancestor of {spec.effector_frame!r}",
        )
    chain.append(root)
    chain.reverse()
    names = tuple(str(model.names[j]) for j in chain)
    weights = np.ones(len(chain))
    for name, w in spec.posture_weights:
        if name not in names:
            raise SpecError(f"{where}.posture_weights.{name}", "not a joint of this limb")
        weights[names.index(name)] = w
    return Limb(
        name=spec.name,
        root_joint=spec.root_joint,
        effector_frame=spec.effector_frame,
        contact=spec.contact,
        half_size=_ro(spec.half_size),
        normal=_ro(spec.normal),
        offset=_ro(spec.offset),
        mu=spec.mu,
        joint_names=names,
        idx_q=_ro([model.joints[j].idx_q for j in chain], np.int64),
        idx_v=_ro([model.joints[j].idx_v for j in chain], np.int64),
        joint_ids=_ro(chain, np.int64),
        frame_id=int(frame_id),
        posture_weights=_ro(weights),
        on_request=spec.on_request,
    )


def _motion_geometry(model: Any, urdf_text: str, urdf_path: Path, q_ref: FloatArray) -> Any:
    """The URDF's collision geometry with mesh elements as convex hulls, its self-collision
    pairs declared as for ``geometry`` (see :func:`set_collision_pairs`); None when a mesh
    cannot be read (the caller keeps the capsules)."""
    dirs = [str(urdf_path.parent)]
    share = example_robot_data_share()
    if share is not None:
        dirs.insert(0, str(share))
    try:
        gmodel = hull_geometry_model(model, urdf_text, dirs)
    except (RuntimeError, ValueError, OSError):
        return None
    set_collision_pairs(model, gmodel, q_ref)
    return gmodel


def _lowest_contact_z(model: Any, limbs: tuple[Limb, ...], q: FloatArray) -> float:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    zs = []
    for limb in limbs:
        placement = data.oMf[limb.frame_id]
        pts = limb.contact_points() @ np.array(placement.rotation).T + placement.translation
        zs.append(float(pts[:, 2].min()))
    return min(zs)


def load_character(spec_path: str | Path) -> Character:
    """Load and validate a character from its limb spec file.

    Raises SpecError (a ValueError) naming the offending spec field.
    """
    path = Path(spec_path).resolve()
    spec, spec_text = read_spec(path)
    urdf_path = resolve_urdf(spec, path)
    urdf_text = urdf_path.read_text()
    try:
        model = pin.buildModelFromXML(urdf_text, pin.JointModelFreeFlyer())
    except Exception as exc:
        raise SpecError("urdf", f"cannot parse {urdf_path}: {exc}") from exc
    names = tuple(str(n) for n in model.names[2:])
    for j in range(2, model.njoints):
        if model.joints[j].nq != 1 or model.joints[j].nv != 1:
            raise SpecError("urdf", f"joint {model.names[j]!r} is not a 1-DoF joint")
    lower = np.array(model.lowerPositionLimit[7:], dtype=np.float64)
    upper = np.array(model.upperPositionLimit[7:], dtype=np.float64)
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower <= upper)):
        raise SpecError("urdf", "every joint needs finite position limits")
    q_names = {n: k for k, n in enumerate(names)}
    q = np.array(pin.neutral(model), dtype=np.float64)
    for name, value in spec.reference_posture:
        if name not in q_names:
            raise SpecError(f"reference_posture.{name}", "no such joint in the URDF")
        k = q_names[name]
        if not lower[k] - 1e-9 <= value <= upper[k] + 1e-9:
            raise SpecError(
                f"reference_posture.{name}",
                f"{value} outside the joint limits [{lower[k]}, {upper[k]}]",
            )
        q[7 + k] = value
    q[7:] = np.clip(q[7:], lower, upper)
    limbs = tuple(_limb(model, limb, i) for i, limb in enumerate(spec.limbs))
    q[2] = spec.root_height if spec.root_height is not None else -_lowest_contact_z(model, limbs, q)
    trunk = _trunk_shapes(spec)
    if spec.self_collision_mode == "urdf":
        geometry = pin.buildGeomFromUrdfString(model, urdf_text, pin.GeometryType.COLLISION)
    else:
        geometry = capsule_geometry_model(model, spec.self_collision_radius)
        add_contact_plates(
            model,
            geometry,
            [
                (lb.frame_id, lb.half_size, lb.normal, lb.offset)
                for lb in limbs
                if lb.contact == "patch"
            ],
        )
        add_trunk_shapes(geometry, trunk)
    set_collision_pairs(model, geometry, q)
    drop_trunk_pairs(geometry)
    motion_geometry = geometry
    if spec.self_collision_mode != "urdf":
        hulls = _motion_geometry(model, urdf_text, urdf_path, q)
        motion_geometry = geometry if hulls is None else hulls
    mass = float(sum(inertia.mass for inertia in model.inertias))
    return Character(
        id=spec.id,
        spec_path=path,
        spec_text=spec_text,
        urdf_text=urdf_text,
        spec=spec,
        model=model,
        geometry=geometry,
        motion_geometry=motion_geometry,
        mass=mass,
        joint_names=names,
        q_ref=_ro(q),
        lower=_ro(lower),
        upper=_ro(upper),
        limbs=limbs,
        trunk=trunk,
    )


def builtin_character_ids() -> tuple[str, ...]:
    """Ids of the characters authored in this repository."""
    return BUILTIN_IDS


def real_robot_ids() -> tuple[str, ...]:
    """Ids of the real robots available (those of example-robot-data, when installed)."""
    return REAL_ROBOT_IDS if example_robot_data_share() is not None else ()


def character_spec_path(character_id: str) -> Path:
    """Path of the limb spec of a built-in or real-robot character; KeyError if unknown."""
    if character_id in BUILTIN_IDS:
        return DATA_DIR / character_id / f"{character_id}.yaml"
    if character_id in REAL_ROBOT_IDS:
        return DATA_DIR / f"{character_id}.yaml"
    raise KeyError(f"unknown character id {character_id!r}")


@cache
def _cached(character_id: str) -> Character:
    return load_character(character_spec_path(character_id))


def get_character(character_id: str) -> Character:
    """Load a built-in or real-robot character by id (memoised per process)."""
    return _cached(character_id)
