"""Relating contact states to their surroundings: which surface a contact touches, and other
characters turned into collision obstacles."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import frame_placement, scratch_data
from planner.scene import Scene
from planner.shapes import Box, Capsule

FloatArray = NDArray[np.float64]
Obstacle = tuple[Box | Capsule, FloatArray]

SURFACE_TOLERANCE = 0.01  # m between a contact point and the surface plane
NORMAL_COSINE = np.cos(np.radians(15.0))  # contact normal within 15 degrees of the surface's


def surface_under(scene: Scene, contact: LimbContact) -> int:
    """Id of the surface whose plane holds the contact's points (within 1 cm) and whose polygon
    contains their centre, with a normal within 15 degrees of the contact's; -1 if none."""
    centre = contact.points.mean(axis=0)
    best, best_gap = -1, SURFACE_TOLERANCE
    for surface in scene.surfaces:
        if float(surface.normal @ contact.normal) < NORMAL_COSINE:
            continue
        gap = float(np.max(np.abs(surface.height(contact.points))))
        if gap <= best_gap and bool(surface.contains_projection(centre[None])[0]):
            best, best_gap = surface.id, gap
    return best


def with_surfaces(scene: Scene, state: ContactState) -> ContactState:
    """The state with each contact's surface id filled in where it was unknown (-1)."""
    contacts = tuple(
        c
        if c.surface >= 0
        else LimbContact(c.limb, c.placement, c.points, c.normal, c.mu, surface_under(scene, c))
        for c in state.contacts
    )
    return ContactState(state.q, contacts)


def character_obstacles(
    character: Character, q: FloatArray, radius: float = 0.05
) -> list[Obstacle]:
    """Another character posed at ``q`` as obstacles: its trunk shapes at the root pose, and a
    capsule of ``radius`` m along each limb segment (joint to joint, down to the effector)."""
    model = character.model
    data = scratch_data(model)
    pin.forwardKinematics(model, data, np.asarray(q, dtype=np.float64))
    root = np.array(data.oMi[1].homogeneous)
    obstacles: list[Obstacle] = [(shape, root) for shape in character.trunk]
    for limb in character.limbs:
        points = [np.array(data.oMi[int(j)].translation) for j in limb.joint_ids]
        points.append(frame_placement(model, q, limb.effector_frame, data)[:3, 3])
        for a, b in itertools.pairwise(points):
            obstacles.append(_segment_capsule(a, b, radius))
    return obstacles


def _segment_capsule(a: FloatArray, b: FloatArray, radius: float) -> Obstacle:
    axis = b - a
    length = float(np.linalg.norm(axis))
    pose = np.eye(4)
    pose[:3, 3] = 0.5 * (a + b)
    if length > 1e-9:
        z = axis / length
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return Capsule(radius=radius, half_length=0.5 * length), pose
