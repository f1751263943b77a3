"""Conversion from domain objects (planner, trajectory) to API schemas."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.character import Character
from planner.contact.state import ContactState, LimbContact
from planner.motion import ComSegment, Keyframe, Phase
from planner.poses import matrix_to_quaternion
from planner.scene import Scene, Surface, SurfaceKind
from planner.shapes import Box, Capsule, ConvexPolytope, Shape
from service import schemas
from service.errors import ApiError

if TYPE_CHECKING:
    from service.registry import StoredSummary


def vec3(values: np.ndarray) -> tuple[float, float, float]:
    """A (3,) array as a JSON triple of floats."""
    return (float(values[0]), float(values[1]), float(values[2]))


_vec = vec3


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
            on_request=limb.on_request,
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


def stored_summary(scene_id: str, summary: StoredSummary) -> schemas.SceneSummary:
    """An uploaded scene's summary from its stored metadata (the scene is not loaded)."""
    return schemas.SceneSummary(
        id=scene_id,
        name=summary.name,
        builtin=False,
        triangle_count=summary.triangle_count,
        surface_count=summary.surface_count,
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


# -- planning states, phases, keyframes -----------------------------------------------------


def q_from_configuration(
    character: Character, configuration: schemas.ConfigurationIn, field: str
) -> np.ndarray:
    """Pinocchio q from a request configuration; unknown joints and limit violations are 422.

    Joints left out take their reference (standing) value.
    """
    unknown = sorted(set(configuration.joints) - set(character.joint_names))
    if unknown:
        raise ApiError(422, "invalid_request", f"unknown joints {unknown[:5]}", f"{field}.joints")
    q = np.array(character.q_ref, dtype=np.float64)
    q[:3] = configuration.root.position
    q[3:7] = configuration.root.orientation
    for index, name in enumerate(character.joint_names):
        if name in configuration.joints:
            value = configuration.joints[name]
            low, high = character.lower[index], character.upper[index]
            if not low - 1e-6 <= value <= high + 1e-6:
                raise ApiError(
                    422,
                    "invalid_request",
                    f"joint {name} = {value} outside its limits [{low:.4g}, {high:.4g}]",
                    f"{field}.joints.{name}",
                )
            q[7 + index] = value
    return q


def state_request(
    character: Character, state: schemas.StateIn, field: str
) -> tuple[np.ndarray, dict[str, int | None]]:
    """A request state as q and the limbs in contact with their surface ids (None: unknown).

    Unknown or repeated limbs are 422s; the planner places and validates the contacts.
    """
    q = q_from_configuration(character, state.configuration, f"{field}.configuration")
    limb_names = {limb.name for limb in character.limbs}
    contacts: dict[str, int | None] = {}
    for index, contact in enumerate(state.contacts):
        where = f"{field}.contacts.{index}.limb"
        if contact.limb not in limb_names:
            message = f"unknown limb '{contact.limb}'; expected one of {sorted(limb_names)}"
            raise ApiError(422, "invalid_request", message, where)
        if contact.limb in contacts:
            raise ApiError(422, "invalid_request", f"limb '{contact.limb}' listed twice", where)
        contacts[contact.limb] = None if contact.surface in (None, -1) else contact.surface
    return q, contacts


def contact_out(contact: LimbContact) -> schemas.ContactOut:
    return schemas.ContactOut(
        limb=contact.limb,
        points=[_vec(p) for p in contact.points],
        normal=_vec(contact.normal),
        mu=float(contact.mu),
        surface=int(contact.surface),
    )


def state_out(character: Character, state: ContactState) -> schemas.StateOut:
    return schemas.StateOut(
        configuration=configuration_from_q(character, state.q),
        contacts=[contact_out(c) for c in state.contacts],
    )


def phase_out(phase: Phase) -> schemas.PhaseOut:
    return schemas.PhaseOut(
        t0=float(phase.t0), t1=float(phase.t1), contacts=[contact_out(c) for c in phase.contacts]
    )


def com_segment_out(segment: ComSegment) -> schemas.ComSegmentOut:
    return schemas.ComSegmentOut(
        t0=float(segment.t0),
        t1=float(segment.t1),
        control_points=[_vec(p) for p in segment.control_points],
    )


def keyframe_out(character: Character, keyframe: Keyframe) -> schemas.KeyframeOut:
    configuration = configuration_from_q(character, keyframe.q)
    return schemas.KeyframeOut(
        t=float(keyframe.t),
        root=configuration.root,
        joints=configuration.joints,
        contacts=list(keyframe.contacts),
    )
