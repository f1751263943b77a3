"""Stored results and scenes as GLB files (glTF 2.0, y up, metres): the glue between the
JSON answers and ``planner.export``."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.character import Character
from planner.export import (
    ExportError,
    Overlays,
    PhaseMarks,
    SceneMesh,
    bezier_polyline,
    motion_glb,
    parabola,
    phases_from_keyframes,
    scene_glb,
)
from planner.scene import Scene
from service import __version__
from service.errors import ApiError, not_found
from service.registry import Registry
from service.results import StoredResult

FloatArray = NDArray[np.float64]
GENERATOR = f"Gecko {__version__}"


def keyframe_arrays(
    character: Character, keyframes: list[dict[str, Any]]
) -> tuple[FloatArray, FloatArray, list[list[str]]]:
    """JSON keyframes as times (n,) s, Pinocchio configurations (n, nq) and contact limbs."""
    names = character.joint_names
    reference = dict(zip(names, np.asarray(character.q_ref[7:], dtype=np.float64), strict=True))
    qs = np.array(
        [
            [
                *k["root"]["position"],
                *k["root"]["orientation"],
                *(k["joints"].get(name, reference[name]) for name in names),
            ]
            for k in keyframes
        ],
        dtype=np.float64,
    ).reshape(len(keyframes), 7 + len(names))
    times = np.array([k["t"] for k in keyframes], dtype=np.float64)
    return times, qs, [list(k.get("contacts", [])) for k in keyframes]


def _phase_marks(phases: list[dict[str, Any]]) -> tuple[PhaseMarks, ...]:
    marks = []
    for phase in phases:
        contacts = phase["contacts"]
        points = [p for c in contacts for p in c["points"]]
        marks.append(
            PhaseMarks(
                t0=float(phase["t0"]),
                t1=float(phase["t1"]),
                limbs=tuple(c["limb"] for c in contacts),
                points=np.asarray(points, dtype=np.float64).reshape(-1, 3),
            )
        )
    return tuple(marks)


def overlays_of(
    result: StoredResult, character: Character, times: FloatArray, qs: FloatArray, contacts: Any
) -> Overlays:
    """COM curve (plans, steps) or jump parabolas (jumps), and the contact phases."""
    response = result.response
    if result.kind == "jump":
        arcs = tuple(
            parabola(
                np.asarray(j["takeoff"]["position"], dtype=np.float64),
                np.asarray(j["takeoff"]["velocity"], dtype=np.float64),
                float(j["duration"]),
            )
            for j in response.get("jumps", [])
        )
        return Overlays(arcs, phases_from_keyframes(character, times, qs, contacts))
    segments = [
        (float(s["t0"]), float(s["t1"]), np.asarray(s["control_points"], dtype=np.float64))
        for s in response.get("com", [])
    ]
    com = bezier_polyline(segments)
    return Overlays((com,) if len(com) >= 2 else (), _phase_marks(response.get("phases", [])))


def timeline(overlays: Overlays) -> list[dict[str, Any]]:
    """The contact phases as JSON: t0, t1 (s) and the limbs in contact."""
    return [{"t0": p.t0, "t1": p.t1, "limbs": list(p.limbs)} for p in overlays.phases]


def scene_mesh(scene: Scene) -> SceneMesh:
    """A served scene's triangle mesh (Gecko's frame)."""
    return SceneMesh(
        np.asarray(scene.vertices, dtype=np.float64),
        np.asarray(scene.faces, dtype=np.int64),
        name=scene.name or scene.id,
    )


def result_glb(
    registry: Registry, result: StoredResult, *, with_scene: bool, with_overlays: bool
) -> bytes:
    """The GLB of a stored plan, Twister step or jump (see ``planner.export.gltf``).

    The scene's ``extras.gecko`` always carries the kind, id, character, scene, status and
    the contact timeline; ``with_scene`` adds the scene mesh, ``with_overlays`` the COM
    curve or jump arcs and the contact points per phase. 409 when the result has no
    keyframes (a failed answer), 404 when its character or scene is no longer served.
    """
    character_id = str(result.request.get("character", ""))
    entry = registry.get_character(character_id)
    if entry is None:
        raise not_found("character", character_id, "character")
    keyframes = result.response.get("keyframes", [])
    if not keyframes:
        message = f"{result.kind} {result.id} has no keyframes to animate (status "
        message += f"{result.response.get('status')})"
        raise ApiError(409, "no_motion", message, "id")
    character = entry.character
    times, qs, contacts = keyframe_arrays(character, keyframes)
    overlays = overlays_of(result, character, times, qs, contacts)
    mesh = None
    if with_scene:
        scene_id = str(result.request.get("scene", ""))
        scene = registry.get_scene(scene_id)
        if scene is None:
            raise not_found("scene", scene_id, "scene")
        mesh = scene_mesh(scene)
    extras = {
        "kind": result.kind,
        "id": result.id,
        "character": character_id,
        "scene": result.request.get("scene"),
        "status": result.response.get("status"),
        "seed": result.response.get("seed"),
        "start": float(times[0]),
        "end": float(times[-1]),
        "phases": timeline(overlays),
        "frame": "glTF: +y up, metres; Gecko world (x, y, z) -> glTF (x, z, -y)",
    }
    try:
        return motion_glb(
            character,
            times,
            qs,
            scene=mesh,
            overlays=overlays if with_overlays else None,
            extras=extras,
            generator=GENERATOR,
        )
    except ExportError as exc:
        raise ApiError(422, "not_exportable", str(exc), "id") from exc


def scene_glb_bytes(scene: Scene) -> bytes:
    """A served scene as GLB in glTF's frame (y up, metres)."""
    return scene_glb(scene_mesh(scene), generator=GENERATOR)
