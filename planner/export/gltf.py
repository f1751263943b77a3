"""glTF 2.0 (binary, GLB) export of a character's motion and of scene meshes.

Frames: Gecko's world is z up; glTF's is y up (metres, right-handed, +z toward the viewer).
The one conversion is :data:`Z_UP_TO_Y_UP`, applied to world-frame quantities only: scene
vertices, overlay points, and the root link's placement. Link frames are carried along
unchanged, so every node below the root keeps its URDF-local transform.

A motion GLB holds the character as one node per URDF link (parent to child as in the URDF;
a link rigidly fixed to its parent is a node with a constant transform), each link's visual
geometry as meshes on child nodes, and one animation ``motion`` with the root link's
translation and rotation and every moving link's rotation (translation for prismatic joints)
sampled at the keyframe times (linear interpolation; glTF's linear rotation is a slerp).
Optional extra nodes: ``scene`` (the scene mesh), ``com`` (line strips: the COM curve, jump
parabolas) and ``contacts`` (one child per contact phase holding its contact points, and a
child ``equilibrium_k`` with the line loop of its static-equilibrium COM region).
"""

from __future__ import annotations

import dataclasses
import json
import struct
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
import pinocchio as pin
import pygltflib
import trimesh
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from planner.character import Character
from planner.character.model import example_robot_data_share, resolve_urdf

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

Z_UP_TO_Y_UP: FloatArray = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rotation taking Gecko's z-up world to glTF's y-up world: (x, y, z) -> (x, z, -y).

That is -90 degrees about +x: Gecko's up (+z) becomes glTF's up (+y), Gecko's +y (left of
a character facing +x) becomes glTF's -z. Lengths stay in metres."""
Z_UP_TO_Y_UP.flags.writeable = False

MAX_KEYFRAMES = 100_000
MAX_SCENE_TRIANGLES = 5_000_000
CYLINDER_SECTIONS = 24
SPHERE_SUBDIVISIONS = 2
PRIMITIVE_MESHES = ("BOX", "CYLINDER", "SPHERE")
_LINEAR_TYPES = {
    "JointModelRX": (np.array([1.0, 0.0, 0.0]), False),
    "JointModelRY": (np.array([0.0, 1.0, 0.0]), False),
    "JointModelRZ": (np.array([0.0, 0.0, 1.0]), False),
    "JointModelPX": (np.array([1.0, 0.0, 0.0]), True),
    "JointModelPY": (np.array([0.0, 1.0, 0.0]), True),
    "JointModelPZ": (np.array([0.0, 0.0, 1.0]), True),
}


class ExportError(ValueError):
    """The motion or mesh cannot be exported (names the offending input)."""


@dataclass(frozen=True, slots=True)
class PhaseMarks:
    """A contact phase drawn in the file: [t0, t1] s, its limbs, its contact points and the
    outline of its static-equilibrium COM region.

    points : (k, 3) contact points; equilibrium : (m, 3) closed outline, (0, 3) when not
    drawn. World frame (z up), metres.
    """

    t0: float
    t1: float
    limbs: tuple[str, ...]
    points: FloatArray
    equilibrium: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))


@dataclass(frozen=True, slots=True)
class Overlays:
    """What a viewer draws beside the body. polylines : each (m, 3), world frame (z up), m."""

    polylines: tuple[FloatArray, ...] = ()
    phases: tuple[PhaseMarks, ...] = ()


@dataclass(frozen=True, slots=True)
class SceneMesh:
    """A triangle mesh in Gecko's world frame: vertices (n, 3) m, z up; faces (m, 3)."""

    vertices: FloatArray
    faces: IntArray
    name: str = "scene"


# -- the character's link tree --------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Link:
    """One URDF link: its BODY frame, the link it hangs from, and how it moves.

    left, right : (4, 4) constant transforms; the link's placement in its parent link (the
    root link's: in glTF's world, :data:`Z_UP_TO_Y_UP` included) is ``left @ motion(q) @
    right``, where motion is the joint's own transform (identity for a link fixed to its
    parent). joint : Pinocchio joint index when the link moves, else 0. quat_left,
    quat_right : (4,) their rotations as quaternions [x, y, z, w].
    """

    name: str
    frame_id: int
    parent: int  # index in the link list, -1 for the root link
    joint: int
    left: FloatArray
    right: FloatArray
    quat_left: FloatArray
    quat_right: FloatArray


def _se3(placement: Any) -> FloatArray:
    out = np.eye(4)
    out[:3, :3] = np.asarray(placement.rotation, dtype=np.float64)
    out[:3, 3] = np.asarray(placement.translation, dtype=np.float64)
    return out


def _inverse(matrix: FloatArray) -> FloatArray:
    out = np.eye(4)
    out[:3, :3] = matrix[:3, :3].T
    out[:3, 3] = -matrix[:3, :3].T @ matrix[:3, 3]
    return out


@lru_cache(maxsize=16)
def _links(character: Character) -> tuple[_Link, ...]:
    """The character's links, parents before children (Pinocchio frame order)."""
    model = character.model
    frames = model.frames
    body = pin.FrameType.BODY
    index_of: dict[int, int] = {}
    links: list[_Link] = []
    for frame_id in range(len(frames)):
        frame = frames[frame_id]
        if frame.type != body:
            continue
        via = frames[frame.parentFrame]  # the joint (or fixed joint) frame above the link
        parent_frame = int(via.parentFrame)
        parent = index_of.get(parent_frame, -1)
        if parent == -1 and links:
            raise ExportError(f"link {frame.name!r} has no parent link in the model")
        placement = _se3(frame.placement)  # in the link's parent joint frame
        parent_placement = (
            _se3(frames[parent_frame].placement) if parent >= 0 else np.eye(4)
        )  # the parent link in its own joint frame
        joint = int(frame.parentJoint)
        parent_joint = int(frames[parent_frame].parentJoint) if parent >= 0 else 0
        if parent >= 0 and joint == parent_joint:  # rigidly fixed to its parent
            left = _inverse(parent_placement) @ placement
            right = np.eye(4)
            joint = 0
        else:
            left = _inverse(parent_placement) @ _se3(model.jointPlacements[joint])
            right = placement
        if parent == -1:
            left[:3, :] = Z_UP_TO_Y_UP @ left[:3, :]
        index_of[frame_id] = len(links)
        links.append(
            _Link(
                str(frame.name),
                frame_id,
                parent,
                joint,
                left,
                right,
                _quat(left[:3, :3]),
                _quat(right[:3, :3]),
            )
        )
    if not links or links[0].joint != 1:
        raise ExportError("the model's first link must be the free-flyer root")
    return tuple(links)


def _quat_multiply(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton products a b of quaternions [x, y, z, w], broadcast over leading axes."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def _quat_rotate(q: FloatArray, v: FloatArray) -> FloatArray:
    """Vectors v (..., 3) rotated by unit quaternions q (..., 4) [x, y, z, w]."""
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return np.asarray(v + w * t + np.cross(u, t))


def _quat(matrix: FloatArray) -> FloatArray:
    """(4,) quaternion [x, y, z, w] of a (3, 3) rotation matrix."""
    return np.asarray(Rotation.from_matrix(matrix).as_quat(), dtype=np.float64)


def _joint_motion(
    character: Character, joint: int, qs: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The joint's own motion over the keyframes: quaternions (n, 4) [x, y, z, w] and
    translations (n, 3), m."""
    model = character.model
    joint_model = model.joints[joint]
    kind = joint_model.shortname()
    n = len(qs)
    idx = int(joint_model.idx_q)
    if kind == "JointModelFreeFlyer":
        quats = qs[:, idx + 3 : idx + 7]
        quats = quats / np.linalg.norm(quats, axis=1, keepdims=True)
        return np.asarray(quats), np.asarray(qs[:, idx : idx + 3])
    if kind in _LINEAR_TYPES:
        axis, prismatic = _LINEAR_TYPES[kind]
    elif kind in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(joint_model.axis, dtype=np.float64)
        prismatic = kind == "JointModelPrismaticUnaligned"
    else:
        raise ExportError(f"joint {model.names[joint]!r} of type {kind} is not exportable")
    values = qs[:, idx]
    identity = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    if prismatic:
        return identity, values[:, None] * axis[None, :]
    half = 0.5 * values[:, None]
    quats = np.concatenate([np.sin(half) * axis[None, :], np.cos(half)], axis=1)
    return quats, np.zeros((n, 3))


def _link_tracks(
    character: Character, link: _Link, qs: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A moving link's placement in its parent over the keyframes: translations (n, 3) m,
    quaternions (n, 4) [x, y, z, w] (sign-continuous). The root link's is in glTF's world."""
    left = link.left
    quat_m, trans_m = _joint_motion(character, link.joint, qs)
    quats = _quat_multiply(link.quat_left, quat_m)
    if np.any(link.quat_right[:3]):
        quats = _quat_multiply(quats, link.quat_right)
    inner = trans_m
    if np.any(link.right[:3, 3]):
        inner = inner + _quat_rotate(quat_m, link.right[:3, 3])
    translations = left[:3, 3][None, :] + inner @ left[:3, :3].T
    flips = np.sign(np.einsum("ij,ij->i", quats[1:], quats[:-1]))
    flips[flips == 0] = 1.0
    signs = np.concatenate([[1.0], np.cumprod(flips)])
    return np.asarray(translations), np.asarray(quats * signs[:, None])


# -- visual geometry ------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Visual:
    """One visual geometry of a link: placement (4, 4) in the link frame, mesh key, colour."""

    name: str
    link: int
    placement: FloatArray
    key: str
    rgba: tuple[float, float, float, float]
    translation: list[float] | None
    rotation: list[float] | None


def _primitive(geometry: Any) -> Any:
    """A coal primitive (box, cylinder, sphere, capsule) as a trimesh, centred, axis z."""
    kind = type(geometry).__name__
    if kind == "Box":
        return trimesh.creation.box(extents=2.0 * np.asarray(geometry.halfSide))
    if kind == "Cylinder":
        return trimesh.creation.cylinder(
            radius=float(geometry.radius),
            height=2.0 * float(geometry.halfLength),
            sections=CYLINDER_SECTIONS,
        )
    if kind == "Sphere":
        return trimesh.creation.icosphere(
            subdivisions=SPHERE_SUBDIVISIONS, radius=float(geometry.radius)
        )
    if kind == "Capsule":
        return trimesh.creation.capsule(
            height=2.0 * float(geometry.halfLength), radius=float(geometry.radius)
        )
    raise ExportError(f"visual geometry of type {kind} is not exportable")


@lru_cache(maxsize=16)
def _visuals(
    character: Character,
) -> tuple[tuple[_Visual, ...], dict[str, tuple[FloatArray, IntArray]]]:
    """The character's visual geometry from its URDF (meshes from their packages when they
    load; a geometry whose mesh cannot be read is left out) and the meshes by key."""
    urdf_path = resolve_urdf(character.spec, character.spec_path)
    share = example_robot_data_share()
    model = character.model
    geometry = pin.buildGeomFromUrdf(
        model,
        str(urdf_path),
        pin.GeometryType.VISUAL,
        package_dirs=[str(share)] if share is not None else [],
    )
    link_of = {link.frame_id: k for k, link in enumerate(_links(character))}
    meshes: dict[str, tuple[FloatArray, IntArray]] = {}
    visuals: list[_Visual] = []
    for obj in geometry.geometryObjects:
        link = link_of.get(int(obj.parentFrame))
        if link is None:
            continue
        path = str(obj.meshPath)
        scale = np.asarray(obj.meshScale, dtype=np.float64)
        if path and path.upper() not in PRIMITIVE_MESHES:
            key = f"{path}|{scale.tolist()}"
            if key not in meshes:
                try:
                    loaded = trimesh.load(path, force="mesh")
                except Exception:
                    continue
                if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
                    continue
                meshes[key] = (
                    np.asarray(loaded.vertices, dtype=np.float64) * scale,
                    np.asarray(loaded.faces, dtype=np.int64),
                )
        else:
            mesh = _primitive(obj.geometry)
            key = f"{obj.name}|primitive"
            meshes[key] = (
                np.asarray(mesh.vertices, dtype=np.float64),
                np.asarray(mesh.faces, dtype=np.int64),
            )
        frame_placement = _se3(model.frames[obj.parentFrame].placement)
        placement = _inverse(frame_placement) @ _se3(obj.placement)
        rgba = tuple(float(v) for v in np.clip(np.asarray(obj.meshColor), 0.0, 1.0))
        translation, rotation = _trs(placement)
        visuals.append(
            _Visual(str(obj.name), link, placement, key, rgba, translation, rotation)  # type: ignore[arg-type]
        )
    return tuple(visuals), meshes


# -- the container --------------------------------------------------------------------------


def _trs(matrix: FloatArray) -> tuple[list[float] | None, list[float] | None]:
    """glTF translation and rotation [x, y, z, w] of a rigid (4, 4) transform (None: identity)."""
    translation = [float(v) for v in matrix[:3, 3]]
    rotation = [float(v) for v in Rotation.from_matrix(matrix[:3, :3]).as_quat()]
    if rotation[3] < 0:
        rotation = [-v for v in rotation]
    return (
        translation if any(translation) else None,
        rotation if rotation != [0.0, 0.0, 0.0, 1.0] else None,
    )


@dataclass
class _Builder:
    """Accumulates one binary buffer and the glTF objects that view it."""

    gltf: pygltflib.GLTF2 = field(default_factory=pygltflib.GLTF2)
    blob: bytearray = field(default_factory=bytearray)
    materials: dict[tuple[float, float, float, float], int] = field(default_factory=dict)

    def view(self, data: bytes, target: int | None = None) -> int:
        """A buffer view over ``data`` (4-byte aligned); its index."""
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        offset = len(self.blob)
        self.blob.extend(data)
        self.gltf.bufferViews.append(
            pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=len(data), target=target)
        )
        return len(self.gltf.bufferViews) - 1

    def floats(self, values: FloatArray, kind: str, target: int | None = None) -> int:
        """A float accessor over (n,) or (n, k) values, with its min and max."""
        array = np.ascontiguousarray(values, dtype="<f4")
        rows = array.reshape(len(array), -1)
        self.gltf.accessors.append(
            pygltflib.Accessor(
                bufferView=self.view(array.tobytes(), target),
                componentType=pygltflib.FLOAT,
                count=len(rows),
                type=kind,
                min=[float(v) for v in rows.min(axis=0)],
                max=[float(v) for v in rows.max(axis=0)],
            )
        )
        return len(self.gltf.accessors) - 1

    def indices(self, faces: IntArray, vertex_count: int) -> int:
        """An index accessor over triangle corners (unsigned short when they fit, else int)."""
        wide = vertex_count > 65_535
        array = np.ascontiguousarray(faces.reshape(-1), dtype="<u4" if wide else "<u2")
        self.gltf.accessors.append(
            pygltflib.Accessor(
                bufferView=self.view(array.tobytes(), pygltflib.ELEMENT_ARRAY_BUFFER),
                componentType=pygltflib.UNSIGNED_INT if wide else pygltflib.UNSIGNED_SHORT,
                count=len(array),
                type=pygltflib.SCALAR,
            )
        )
        return len(self.gltf.accessors) - 1

    def material(self, rgba: tuple[float, float, float, float], name: str = "") -> int:
        """A matte material of this base colour (shared by every mesh of that colour)."""
        if rgba not in self.materials:
            self.gltf.materials.append(
                pygltflib.Material(
                    name=name or None,
                    pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
                        baseColorFactor=list(rgba), metallicFactor=0.0, roughnessFactor=0.9
                    ),
                    alphaMode=pygltflib.OPAQUE if rgba[3] >= 1.0 else pygltflib.BLEND,
                    doubleSided=True,
                )
            )
            self.materials[rgba] = len(self.gltf.materials) - 1
        return self.materials[rgba]

    def triangle_mesh(self, name: str, vertices: FloatArray, faces: IntArray, material: int) -> int:
        """A mesh of one triangle primitive (positions only: viewers shade it flat)."""
        positions = self.floats(vertices, pygltflib.VEC3, pygltflib.ARRAY_BUFFER)
        primitive = pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=positions),
            indices=self.indices(faces, len(vertices)),
            material=material,
            mode=pygltflib.TRIANGLES,
        )
        self.gltf.meshes.append(pygltflib.Mesh(name=name, primitives=[primitive]))
        return len(self.gltf.meshes) - 1

    def point_mesh(self, name: str, groups: list[FloatArray], mode: int, material: int) -> int:
        """A mesh of point or line-strip primitives, one per (m, 3) group of positions."""
        primitives = [
            pygltflib.Primitive(
                attributes=pygltflib.Attributes(
                    POSITION=self.floats(group, pygltflib.VEC3, pygltflib.ARRAY_BUFFER)
                ),
                material=material,
                mode=mode,
            )
            for group in groups
        ]
        self.gltf.meshes.append(pygltflib.Mesh(name=name, primitives=primitives))
        return len(self.gltf.meshes) - 1

    def node(self, node: pygltflib.Node) -> int:
        self.gltf.nodes.append(node)
        return len(self.gltf.nodes) - 1

    def glb(self, roots: list[int], generator: str, extras: dict[str, Any] | None) -> bytes:
        """The finished GLB bytes (deterministic for the same inputs)."""
        gltf = self.gltf
        gltf.asset = pygltflib.Asset(version="2.0", generator=generator)
        scene = pygltflib.Scene(name="gecko", nodes=roots)
        if extras:
            scene.extras = {"gecko": extras}
        gltf.scenes = [scene]
        gltf.scene = 0
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        gltf.buffers = [pygltflib.Buffer(byteLength=len(self.blob))]
        return _pack_glb(gltf, bytes(self.blob))


def _plain(value: Any) -> Any:
    """pygltflib objects as JSON-ready values, without None fields or empty containers."""
    if isinstance(value, pygltflib.Attributes):
        return {k: v for k, v in vars(value).items() if v is not None}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out = {}
        for name, item in vars(value).items():
            if item is None or (isinstance(item, list | dict) and not item):
                continue
            out[name] = item if type(item) in (int, float, str) else _plain(item)
        return out
    if isinstance(value, list | tuple):
        if all(type(v) in (int, float) for v in value):
            return list(value)
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _pack_glb(gltf: pygltflib.GLTF2, blob: bytes) -> bytes:
    """The GLB container (glTF 2.0 section 4.4): a 12-byte header, the JSON chunk padded
    with spaces and the BIN chunk padded with zeros, both to 4 bytes.

    pygltflib's own ``save_to_bytes`` deep-copies every value while serialising (about
    35 ms for a humanoid's animation); this writes the same objects in about 1 ms.
    """
    text = json.dumps(_plain(gltf), separators=(",", ":"), allow_nan=False).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    length = 12 + 8 + len(text) + 8 + len(blob)
    return b"".join(
        [
            struct.pack("<4sII", pygltflib.MAGIC, pygltflib.GLTF_VERSION, length),
            struct.pack("<I4s", len(text), pygltflib.JSON.encode()),
            text,
            struct.pack("<I4s", len(blob), pygltflib.BIN.encode()),
            blob,
        ]
    )


def _world_points(points: FloatArray) -> FloatArray:
    """(n, 3) world points, z up -> y up."""
    return np.asarray(np.asarray(points, dtype=np.float64) @ Z_UP_TO_Y_UP.T)


def _check_mesh(vertices: FloatArray, faces: IntArray, what: str) -> None:
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise ExportError(f"{what}: vertices must be a non-empty (n, 3) array")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ExportError(f"{what}: faces must be a non-empty (m, 3) array")
    if len(faces) > MAX_SCENE_TRIANGLES:
        raise ExportError(f"{what}: {len(faces)} triangles; limit {MAX_SCENE_TRIANGLES}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ExportError(f"{what}: face indices out of range")
    if not np.all(np.isfinite(vertices)):
        raise ExportError(f"{what}: non-finite vertices")


def _add_scene(builder: _Builder, scene: SceneMesh) -> int:
    vertices = np.asarray(scene.vertices, dtype=np.float64)
    faces = np.asarray(scene.faces, dtype=np.int64)
    _check_mesh(vertices, faces, "scene")
    material = builder.material((0.78, 0.76, 0.72, 1.0), "scene")
    mesh = builder.triangle_mesh(scene.name, _world_points(vertices), faces, material)
    return builder.node(pygltflib.Node(name="scene", mesh=mesh))


def scene_glb(scene: SceneMesh, *, generator: str = "Gecko") -> bytes:
    """A scene mesh as GLB, in glTF's frame (y up, metres): one node ``scene``."""
    builder = _Builder()
    root = _add_scene(builder, scene)
    return builder.glb([root], generator, None)


def _add_overlays(builder: _Builder, overlays: Overlays) -> list[int]:
    roots: list[int] = []
    lines = [np.asarray(p, dtype=np.float64) for p in overlays.polylines if len(p) >= 2]
    if lines:
        material = builder.material((0.9, 0.15, 0.1, 1.0), "com")
        mesh = builder.point_mesh(
            "com", [_world_points(p) for p in lines], pygltflib.LINE_STRIP, material
        )
        roots.append(builder.node(pygltflib.Node(name="com", mesh=mesh)))
    if overlays.phases:
        material = builder.material((0.1, 0.45, 0.95, 1.0), "contacts")
        balance = builder.material((0.1, 0.7, 0.25, 1.0), "equilibrium")
        children = []
        for index, phase in enumerate(overlays.phases):
            node = pygltflib.Node(name=f"phase_{index:03d}")
            node.extras = {"t0": phase.t0, "t1": phase.t1, "limbs": list(phase.limbs)}
            points = np.asarray(phase.points, dtype=np.float64).reshape(-1, 3)
            if len(points):
                node.mesh = builder.point_mesh(
                    f"contacts_{index:03d}", [_world_points(points)], pygltflib.POINTS, material
                )
            outline = np.asarray(phase.equilibrium, dtype=np.float64).reshape(-1, 3)
            if len(outline) >= 3:
                polygon = builder.point_mesh(
                    f"equilibrium_{index:03d}",
                    [_world_points(outline)],
                    pygltflib.LINE_LOOP,
                    balance,
                )
                name = f"equilibrium_{index:03d}"
                node.children = [builder.node(pygltflib.Node(name=name, mesh=polygon))]
            children.append(builder.node(node))
        roots.append(builder.node(pygltflib.Node(name="contacts", children=children)))
    return roots


def _check_motion(character: Character, times: FloatArray, qs: FloatArray) -> None:
    nq = int(character.model.nq)
    if times.ndim != 1 or len(times) == 0:
        raise ExportError("keyframes: at least one keyframe is needed")
    if len(times) > MAX_KEYFRAMES:
        raise ExportError(f"keyframes: {len(times)} keyframes; limit {MAX_KEYFRAMES}")
    if qs.shape != (len(times), nq):
        raise ExportError(f"keyframes: configurations must be ({len(times)}, {nq}), not {qs.shape}")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(qs))):
        raise ExportError("keyframes: non-finite time or configuration")
    if np.any(np.diff(times) < 0):
        raise ExportError("keyframes: times must not decrease")


def motion_glb(
    character: Character,
    times: FloatArray,
    qs: FloatArray,
    *,
    scene: SceneMesh | None = None,
    overlays: Overlays | None = None,
    extras: dict[str, Any] | None = None,
    generator: str = "Gecko",
) -> bytes:
    """A character's motion as GLB, in glTF's frame (y up, metres).

    times : (n,) keyframe times, s, non-decreasing (a repeated time keeps its first
    keyframe). qs : (n, nq) Pinocchio configurations (root position, root quaternion
    [x, y, z, w], joints) in Gecko's world (z up). ``extras`` (JSON-ready) is stored as the
    glTF scene's ``extras.gecko``. Raises ExportError on malformed input.
    """
    times = np.asarray(times, dtype=np.float64)
    qs = np.asarray(qs, dtype=np.float64)
    _check_motion(character, times, qs)
    keep = np.concatenate([[True], np.diff(times.astype(np.float32)) > 0])
    times, qs = times[keep], qs[keep]

    builder = _Builder()
    links = _links(character)
    visuals, meshes = _visuals(character)
    mesh_index: dict[str, int] = {}
    node_of: list[int] = []
    children: dict[int, list[int]] = {}
    channels: list[tuple[int, str, FloatArray]] = []
    for k, link in enumerate(links):
        node = pygltflib.Node(name=link.name)
        if link.joint:
            translations, quats = _link_tracks(character, link, qs)
            node.translation = [float(v) for v in translations[0]]
            node.rotation = [float(v) for v in quats[0]]
            channels.append((k, "rotation", quats))
            if link.parent == -1 or np.ptp(translations, axis=0).max() > 0.0:
                channels.append((k, "translation", translations))
        else:
            node.translation, node.rotation = _trs(link.left)
        node_of.append(builder.node(node))
        if link.parent >= 0:
            children.setdefault(link.parent, []).append(node_of[k])
    for visual in visuals:
        if visual.key not in mesh_index:
            vertices, faces = meshes[visual.key]
            material = builder.material(visual.rgba)
            mesh_index[visual.key] = builder.triangle_mesh(visual.name, vertices, faces, material)
        child = builder.node(
            pygltflib.Node(
                name=visual.name,
                mesh=mesh_index[visual.key],
                translation=visual.translation,
                rotation=visual.rotation,
            )
        )
        children.setdefault(visual.link, []).append(child)
    for k, kids in children.items():
        builder.gltf.nodes[node_of[k]].children = kids

    time_accessor = builder.floats(times, pygltflib.SCALAR)
    samplers, targets = [], []
    for k, path, values in channels:
        kind = pygltflib.VEC4 if path == "rotation" else pygltflib.VEC3
        samplers.append(
            pygltflib.AnimationSampler(
                input=time_accessor,
                output=builder.floats(values, kind),
                interpolation=pygltflib.ANIM_LINEAR,
            )
        )
        targets.append(
            pygltflib.AnimationChannel(
                sampler=len(samplers) - 1,
                target=pygltflib.AnimationChannelTarget(node=node_of[k], path=path),
            )
        )
    builder.gltf.animations.append(
        pygltflib.Animation(name="motion", samplers=samplers, channels=targets)
    )
    roots = [node_of[0]]
    if scene is not None:
        roots.append(_add_scene(builder, scene))
    if overlays is not None:
        roots.extend(_add_overlays(builder, overlays))
    return builder.glb(roots, generator, _json_ready(extras))


def _json_ready(extras: dict[str, Any] | None) -> dict[str, Any] | None:
    """Extras through a JSON round trip: plain types only, so the output is deterministic."""
    if extras is None:
        return None
    loaded: dict[str, Any] = json.loads(json.dumps(extras, sort_keys=True))
    return loaded
