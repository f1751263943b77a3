"""Exports of motions and scenes to interchange formats (glTF 2.0 binary)."""

from planner.export.gltf import (
    Z_UP_TO_Y_UP,
    ExportError,
    Overlays,
    PhaseMarks,
    SceneMesh,
    motion_glb,
    scene_glb,
)
from planner.export.overlays import (
    bezier_polyline,
    contact_points,
    equilibrium_outline,
    parabola,
    phases_from_keyframes,
)

__all__ = [
    "Z_UP_TO_Y_UP",
    "ExportError",
    "Overlays",
    "PhaseMarks",
    "SceneMesh",
    "bezier_polyline",
    "contact_points",
    "equilibrium_outline",
    "motion_glb",
    "parabola",
    "phases_from_keyframes",
    "scene_glb",
]
