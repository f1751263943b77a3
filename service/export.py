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
    equilibrium_outline,
    motion_glb,
    parabola,
    phases_from_keyframes,
    scene_glb,
)
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


OUTLINE_LIFT = 0.005  # m: equilibrium outlines float this far above the lowest contact
ContactTriple = tuple[FloatArray, FloatArray, float]  # points (k, 3), normal (3,), mu


def _outline(contacts: list[ContactTriple], mass: float) -> FloatArray:
    """The phase's equilibrium outline, drawn just above its lowest contact point."""
    if not contacts:
        return np.zeros((0, 3))
    height = float(np.min(np.vstack([p for p, _, _ in contacts])[:, 2])) + OUTLINE_LIFT
    try:
        return equilibrium_outline(contacts, mass, height)
    except ValueError:  # a stored contact the trajectory library refuses: draw no outline
        return np.zeros((0, 3))


def _phase_marks(
    phases: list[dict[str, Any]], mass: float, outlines: bool
) -> tuple[PhaseMarks, ...]:
    """Plan or step phases with their contact points (and equilibrium outlines)."""
    marks = []
    for phase in phases:
        contacts = phase["contacts"]
        triples: list[ContactTriple] = [
            (
                np.asarray(c["points"], dtype=np.float64).reshape(-1, 3),
                np.asarray(c["normal"], dtype=np.float64),
                float(c["mu"]),
            )
            for c in contacts
        ]
        t0, t1 = float(phase["t0"]), float(phase["t1"])
        points = [p for c in contacts for p in c["points"]]
        marks.append(
            PhaseMarks(
                t0=t0,
                t1=t1,
                limbs=tuple(c["limb"] for c in contacts),
                points=np.asarray(points, dtype=np.float64).reshape(-1, 3),
                equilibrium=_outline(triples, mass) if outlines else np.zeros((0, 3)),
            )
        )
    return tuple(marks)


def _jump_phase_marks(
    character: Character, jumps: list[dict[str, Any]], marks: tuple[PhaseMarks, ...]
) -> tuple[PhaseMarks, ...]:
    """Keyframe phases of a jump answer with their equilibrium outlines: each limb's normal
    and friction are those of the nearest take-off or landing contact of the same limb."""
    known: dict[str, list[tuple[FloatArray, FloatArray, float]]] = {}
    for jump in jumps:
        for end in (jump["takeoff"], jump["landing"]):
            for c in end["contacts"]:
                entry = (
                    np.asarray(c["point"], dtype=np.float64),
                    np.asarray(c["normal"], dtype=np.float64),
                    float(c["mu"]),
                )
                known.setdefault(c["limb"], []).append(entry)
    out = []
    for mark in marks:
        triples: list[ContactTriple] = []
        offset = 0
        for limb in mark.limbs:
            count = len(character.limb(limb).contact_points())
            points = mark.points[offset : offset + count]
            offset += count
            candidates = known.get(limb)
            if not candidates:
                triples = []
                break
            centre = points.mean(axis=0)
            _, normal, mu = min(candidates, key=lambda e: float(np.linalg.norm(e[0] - centre)))
            triples.append((points, normal, mu))
        outline = _outline(triples, float(character.mass))
        out.append(PhaseMarks(mark.t0, mark.t1, mark.limbs, mark.points, outline))
    return tuple(out)


def overlays_of(
    result: StoredResult,
    character: Character,
    times: FloatArray,
    qs: FloatArray,
    contacts: Any,
    *,
    outlines: bool = True,
) -> Overlays:
    """Contact phases; with ``outlines`` (what a viewer draws, not the timeline) also the
    COM curve (plans, steps) or jump parabolas (jumps) and the phases' static-equilibrium
    outlines."""
    response = result.response
    if result.kind == "jump":
        jumps = response.get("jumps", [])
        arcs = tuple(
            parabola(
                np.asarray(j["takeoff"]["position"], dtype=np.float64),
                np.asarray(j["takeoff"]["velocity"], dtype=np.float64),
                float(j["duration"]),
            )
            for j in jumps
        )
        marks = phases_from_keyframes(character, times, qs, contacts)
        return Overlays(arcs, _jump_phase_marks(character, jumps, marks) if outlines else marks)
    segments = [
        (float(s["t0"]), float(s["t1"]), np.asarray(s["control_points"], dtype=np.float64))
        for s in response.get("com", [])
    ]
    com = bezier_polyline(segments) if outlines else np.zeros((0, 3))
    phases = _phase_marks(response.get("phases", []), float(character.mass), outlines)
    return Overlays((com,) if len(com) >= 2 else (), phases)


def timeline(overlays: Overlays) -> list[dict[str, Any]]:
    """The contact phases as JSON: t0, t1 (s) and the limbs in contact."""
    return [{"t0": p.t0, "t1": p.t1, "limbs": list(p.limbs)} for p in overlays.phases]


def scene_mesh(registry: Registry, scene_id: str) -> SceneMesh | None:
    """A served scene's triangle mesh (Gecko's frame), without loading an uploaded scene;
    None if unknown."""
    found = registry.scene_mesh(scene_id)
    if found is None:
        return None
    name, vertices, faces = found
    return SceneMesh(
        np.asarray(vertices, dtype=np.float64),
        np.asarray(faces, dtype=np.int64),
        name=name or scene_id,
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
    overlays = overlays_of(result, character, times, qs, contacts, outlines=with_overlays)
    mesh = None
    if with_scene:
        scene_id = str(result.request.get("scene", ""))
        mesh = scene_mesh(registry, scene_id)
        if mesh is None:
            raise not_found("scene", scene_id, "scene")
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


def scene_glb_bytes(mesh: SceneMesh) -> bytes:
    """A served scene's mesh as GLB in glTF's frame (y up, metres)."""
    return scene_glb(mesh, generator=GENERATOR)
