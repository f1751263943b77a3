"""Mesh loading: STL, OBJ, PLY, GLB/glTF and DAE through trimesh, validated at the boundary.

Meshes are in metres, z up; ``y_up=True`` rotates y-up input (glTF's convention) by +90 degrees
about x so that +y becomes +z. Multi-object files (glTF scenes, COLLADA) are flattened with their
node transforms applied. Duplicate vertices are merged and degenerate triangles dropped.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
import trimesh

from planner.scene.errors import SceneError

SUPPORTED_FORMATS = ("stl", "obj", "ply", "glb", "gltf", "dae")

_Y_UP_TO_Z_UP = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


def _format_of(source: Path | bytes, fmt: str | None) -> str:
    if fmt is None:
        if isinstance(source, bytes | bytearray | memoryview):
            raise SceneError("the format is required when loading from bytes", "format")
        fmt = Path(source).suffix.lstrip(".")
    fmt = fmt.lower().lstrip(".")
    if fmt not in SUPPORTED_FORMATS:
        raise SceneError(
            f"unsupported mesh format {fmt!r}; expected one of {', '.join(SUPPORTED_FORMATS)}",
            "format",
        )
    return fmt


def _parse(source: Path | bytes, fmt: str) -> object:
    # trimesh logs parse noise at warning level; keep it out of the service logs.
    logger = logging.getLogger("trimesh")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        if isinstance(source, bytes | bytearray | memoryview):
            data = bytes(source)
            if not data:
                raise SceneError("the mesh file is empty (0 bytes)", "mesh")
            return trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh", process=False)
        path = Path(source)
        if not path.is_file():
            raise SceneError(f"no such mesh file: {path}", "mesh")
        return trimesh.load(path, file_type=fmt, force="mesh", process=False)
    except SceneError:
        raise
    except Exception as exc:
        detail = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else type(exc).__name__
        hint = ""
        if fmt == "gltf" and not isinstance(source, Path):
            hint = " (glTF given as bytes must embed its buffers; send GLB instead)"
        raise SceneError(f"could not parse the {fmt.upper()} data: {detail}{hint}", "mesh") from exc
    finally:
        logger.setLevel(level)


def validate_arrays(vertices: object, faces: object) -> tuple[np.ndarray, np.ndarray]:
    """Checked float64 (n, 3) vertices and int64 (m, 3) faces; raises SceneError."""
    try:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"mesh arrays are not numeric: {exc}", "mesh") from exc
    if f.size == 0 or v.size == 0:
        raise SceneError("the mesh is empty (no triangles)", "mesh")
    if v.ndim != 2 or v.shape[1] != 3:
        raise SceneError(f"vertices must be (n, 3), got {v.shape}", "vertices")
    if f.ndim != 2 or f.shape[1] != 3:
        raise SceneError(f"faces must be (m, 3) triangles, got {f.shape}", "faces")
    if not np.all(np.isfinite(v)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(v), axis=1)))
        raise SceneError(f"{bad} vertices have NaN or infinite coordinates", "vertices")
    if f.min() < 0 or f.max() >= len(v):
        raise SceneError("faces index vertices that do not exist", "faces")
    return v, f


def load_mesh(
    source: Path | bytes,
    fmt: str | None = None,
    *,
    y_up: bool = False,
    max_triangles: int | None = None,
) -> trimesh.Trimesh:
    """Load a triangle mesh from a file path or raw bytes.

    fmt : one of ``SUPPORTED_FORMATS``; taken from the file suffix when None (bytes need it).
    y_up : the input is y-up; rotate it to z-up. max_triangles : reject bigger meshes.
    Raises SceneError (with ``field``) on unknown formats, corrupt or empty files, NaN or
    infinite vertices, out-of-range faces, all-degenerate meshes and oversized meshes.
    """
    fmt = _format_of(source, fmt)
    loaded = _parse(source, fmt)
    if not isinstance(loaded, trimesh.Trimesh):
        raise SceneError(f"the {fmt.upper()} data holds no triangle mesh", "mesh")
    vertices, faces = validate_arrays(loaded.vertices, loaded.faces)
    if max_triangles is not None and len(faces) > max_triangles:
        raise SceneError(
            f"the mesh has {len(faces)} triangles, more than the limit of {max_triangles}", "mesh"
        )
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise SceneError("every triangle of the mesh is degenerate (zero area)", "mesh")
    if y_up:
        mesh.apply_transform(_Y_UP_TO_Z_UP)
    return mesh
