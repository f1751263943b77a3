"""Conversion from domain objects (planner, trajectory) to API schemas."""

from __future__ import annotations

import numpy as np

from planner.character import Character
from planner.poses import matrix_to_quaternion
from planner.scene import Scene, Surface, SurfaceKind
from planner.shapes import Box, Capsule, ConvexPolytope, Shape
from service import schemas


def _vec(values: np.ndarray) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def configuration_from_q(character: Character, q: np.ndarray) -> schemas.Configuration:
    """Pinocchio configuration (free-flyer first: position, quaternion [x,y,z,w]) to the schema."""
    joints = {name: float(value) for name, value in zip(character.joint_names, q[7:], strict=True)}
    orientation = q[3:7] / np.linalg.norm(q[3:7])
    root = schemas.RootPose(
        position=_vec(q[:3]),
        orientation=(
            float(orientation[0]),
            float(orientation[1]),
            float(orientation[2]),
            float(orientation[3]),
        ),
    )
    return schemas.Configuration(root=root, joints=joints)


def _shape_info(shape: Shape) -> dict[str, object]:
    pose = {
        "position": list(_vec(shape.offset[:3, 3])),
        "orientation": [float(v) for v in matrix_to_quaternion(shape.offset[:3, :3])],
    }
    if isinstance(shape, Box):
        return {"type": "box", "half_extents": list(_vec(shape.half_extents)), **pose}
    if isinstance(shape, Capsule):
        return {
            "type": "capsule",
            "radius": shape.radius,
            "half_length": shape.half_length,
            **pose,
        }
    assert isinstance(shape, ConvexPolytope)
    return {"type": "convex", "vertices": shape.vertices.tolist(), **pose}


def character_detail(character: Character) -> schemas.CharacterDetail:
    limbs = [
        schemas.LimbInfo(
            name=limb.name,
            root_joint=limb.root_joint,
            effector_frame=limb.effector_frame,
            contact="patch" if limb.contact == "patch" else "point",
            half_size=(float(limb.half_size[0]), float(limb.half_size[1])),
            normal=_vec(limb.normal),
            mu=float(limb.mu),
        )
        for limb in character.limbs
    ]
    return schemas.CharacterDetail(
        id=character.id,
        mass=float(character.mass),
        joints=list(character.joint_names),
        reference_configuration=configuration_from_q(character, character.q_ref),
        limbs=limbs,
        trunk=[_shape_info(shape) for shape in character.trunk],
    )


def character_summary(character: Character) -> schemas.CharacterSummary:
    return schemas.CharacterSummary(
        id=character.id,
        mass=float(character.mass),
        joint_count=len(character.joint_names),
        limbs=[limb.name for limb in character.limbs],
    )


def surface_info(surface: Surface) -> schemas.SurfaceInfo:
    return schemas.SurfaceInfo(
        id=int(surface.id),
        kind="support" if surface.kind == SurfaceKind.SUPPORT else "lean",
        normal=_vec(surface.normal),
        area=float(surface.area),
        centroid=_vec(surface.centroid),
        polygons=[[_vec(point) for point in polygon] for polygon in surface.polygons],
    )


def scene_summary(scene: Scene, builtin: bool) -> schemas.SceneSummary:
    return schemas.SceneSummary(
        id=scene.id,
        name=scene.name,
        builtin=builtin,
        triangle_count=int(scene.triangle_count),
        surface_count=len(scene.surfaces),
    )


def scene_detail(scene: Scene, builtin: bool) -> schemas.SceneDetail:
    return schemas.SceneDetail(
        id=scene.id,
        name=scene.name,
        builtin=builtin,
        bounds=(_vec(scene.bounds[0]), _vec(scene.bounds[1])),
        triangle_count=int(scene.triangle_count),
        surfaces=[surface_info(surface) for surface in scene.surfaces],
    )
