"""Triangle and vertex counts of a mesh file read from its header or scene graph, before parsing.

A mesh file can promise far more geometry than its size suggests: a 368 KB GLB whose one mesh
is instanced by 95 nodes expands to 1.9 million triangles. These counts let a caller refuse an
oversized file before any array is built:

- STL: binary files state their triangle count at bytes 80..84 (checked against the file
  size); ASCII files are counted by their ``endfacet`` keywords.
- PLY: the header's ``element vertex N`` and ``element face N``.
- OBJ: the ``v`` and ``f`` lines (a polygon counts as one triangle: a lower bound).
- GLB / glTF: per mesh, the triangles of its primitives (from the accessors' ``count``), summed
  over the nodes of the scene graph that instance it, as trimesh flattens the scene.
- DAE: not counted (None); the caller checks the parsed mesh instead.

Counts read from headers are what the file claims; the parser still validates the data.
"""

from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass
from typing import Any

from planner.scene.errors import SceneError

PLY_HEADER_MAX_BYTES = 65_536  # a PLY header longer than this is not one we can use
_STL_HEADER_BYTES = 84  # 80-byte header + uint32 triangle count
_STL_TRIANGLE_BYTES = 50  # normal, 3 vertices (12 float32) + uint16 attribute
_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A
_GL_TRIANGLES, _GL_TRIANGLE_STRIP, _GL_TRIANGLE_FAN = 4, 5, 6
_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]", re.MULTILINE)
_OBJ_VERTEX = re.compile(rb"^[ \t]*v[ \t]", re.MULTILINE)
_PLY_ELEMENT = re.compile(rb"^element[ \t]+(\w+)[ \t]+(\d+)[ \t]*$", re.MULTILINE)


@dataclass(frozen=True, slots=True)
class MeshCounts:
    """What a mesh file holds, from its header or scene graph.

    triangles : triangles after instancing (a lower bound for OBJ/PLY polygons, which
    triangulate into more). vertices : vertices after instancing.
    """

    triangles: int
    vertices: int


def count_mesh(data: bytes, fmt: str) -> MeshCounts | None:
    """Counts of the mesh file ``data`` in format ``fmt`` (``stl``, ``ply``, ``obj``, ``glb``,
    ``gltf``; None for ``dae``), without parsing its arrays.

    Raises SceneError (field ``mesh``) when the header or scene graph is unreadable, e.g. a
    GLB without its JSON chunk or a scene graph with a cycle.
    """
    fmt = fmt.lower().lstrip(".")
    if fmt == "stl":
        return _count_stl(data)
    if fmt == "ply":
        return _count_ply(data)
    if fmt == "obj":
        return MeshCounts(len(_OBJ_FACE.findall(data)), len(_OBJ_VERTEX.findall(data)))
    if fmt == "glb":
        return _count_gltf(_glb_json(data))
    if fmt == "gltf":
        return _count_gltf(_json_document(data, "glTF"))
    return None


def _count_stl(data: bytes) -> MeshCounts:
    if len(data) >= _STL_HEADER_BYTES:
        (declared,) = struct.unpack_from("<I", data, 80)
        if _STL_HEADER_BYTES + _STL_TRIANGLE_BYTES * declared == len(data):
            return MeshCounts(declared, 3 * declared)
    facets = data.count(b"endfacet")  # ASCII STL (trimesh reads any other size as ASCII)
    return MeshCounts(facets, 3 * facets)


def _count_ply(data: bytes) -> MeshCounts:
    end = data.find(b"end_header", 0, PLY_HEADER_MAX_BYTES)
    if not data.startswith(b"ply") or end < 0:
        raise SceneError("the PLY data has no header (ply ... end_header)", "mesh")
    header = data[:end].replace(b"\r\n", b"\n")
    elements = {name.lower(): int(count) for name, count in _PLY_ELEMENT.findall(header)}
    return MeshCounts(elements.get(b"face", 0), elements.get(b"vertex", 0))


def _glb_json(data: bytes) -> dict[str, Any]:
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        raise SceneError("the GLB data does not start with a GLB header", "mesh")
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != _GLB_JSON_CHUNK or 20 + length > len(data):
        raise SceneError("the GLB data has no JSON chunk first", "mesh")
    return _json_document(data[20 : 20 + length], "GLB")


def _json_document(data: bytes, what: str) -> dict[str, Any]:
    try:
        document = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise SceneError(f"the {what} JSON is unreadable: {exc}", "mesh") from exc
    if not isinstance(document, dict):
        raise SceneError(f"the {what} JSON is not an object", "mesh")
    return document


def _count_gltf(document: dict[str, Any]) -> MeshCounts:
    """Triangles and vertices of the glTF ``document`` as trimesh flattens it: every mesh
    once per node reachable from the default scene's roots that names it."""
    try:
        accessors = [int(a.get("count", 0)) for a in document.get("accessors", [])]
        meshes = [_mesh_counts(mesh, accessors) for mesh in document.get("meshes", [])]
        nodes = document.get("nodes", [])
        scenes = document.get("scenes", [])
        if scenes:
            roots = [int(n) for n in scenes[int(document.get("scene", 0))].get("nodes", [])]
            reached = _reachable(nodes, roots)
            instanced = [int(nodes[n]["mesh"]) for n in reached if "mesh" in nodes[n]]
        else:  # no scene graph: count every mesh once per node naming it, and at least once
            instanced = [int(node["mesh"]) for node in nodes if "mesh" in node]
            instanced.extend(set(range(len(meshes))) - set(instanced))
        triangles = sum(meshes[m].triangles for m in instanced)
        vertices = sum(meshes[m].vertices for m in instanced)
    except (AttributeError, IndexError, KeyError, TypeError, ValueError) as exc:
        raise SceneError(f"the glTF scene graph is malformed: {exc!r}", "mesh") from exc
    return MeshCounts(triangles, vertices)


def _mesh_counts(mesh: dict[str, Any], accessors: list[int]) -> MeshCounts:
    triangles = vertices = 0
    for primitive in mesh.get("primitives", []):
        positions = accessors[int(primitive["attributes"]["POSITION"])]
        corners = accessors[int(primitive["indices"])] if "indices" in primitive else positions
        mode = int(primitive.get("mode", _GL_TRIANGLES))
        if mode == _GL_TRIANGLES:
            triangles += corners // 3
        elif mode in (_GL_TRIANGLE_STRIP, _GL_TRIANGLE_FAN):
            triangles += max(corners - 2, 0)
        vertices += positions
    return MeshCounts(triangles, vertices)


def _reachable(nodes: list[dict[str, Any]], roots: list[int]) -> list[int]:
    """Distinct node indices reachable from ``roots`` (each once, however often shared)."""
    seen: set[int] = set()
    order: list[int] = []
    stack = list(roots)
    while stack:
        index = stack.pop()
        if index in seen:
            continue
        if not 0 <= index < len(nodes):
            raise IndexError(f"node {index} does not exist")
        seen.add(index)
        order.append(index)
        stack.extend(int(child) for child in nodes[index].get("children", []))
    return order
