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
- DAE (COLLADA): the XML is read (no entities, no network) but not built into a scene: per
  geometry, the triangles its ``triangles``, ``polylist`` and ``polygons`` hold (from their
  index data, not their ``count`` attributes: a polygon of n corners is n - 2 triangles), summed
  over the ``instance_geometry`` elements reachable from the scene, through nested nodes and
  ``instance_node`` references (shared subtrees counted once per reference, as trimesh
  flattens them); 3 vertices a triangle (trimesh copies each instance's corners).

Counts read from headers are what the file claims; the parser still validates the data.
"""

from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass
from typing import Any

from lxml import etree

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
    ``gltf``, ``dae``), without parsing its arrays into a mesh.

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
    if fmt == "dae":
        return _count_collada(data)
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


def _count_collada(data: bytes) -> MeshCounts:
    """Triangles of a COLLADA document as trimesh flattens it (see the module's docstring)."""
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=True, recover=False
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        raise SceneError(f"the DAE data is not readable XML: {exc}", "mesh") from exc
    try:
        geometries = {
            element.get("id"): _collada_geometry_triangles(element)
            for element in root.iter(_dae("geometry"))
            if element.get("id")
        }
        nodes = {element.get("id"): element for element in root.iter(_dae("node"))}
        scene = _collada_scene(root)
        triangles = 0 if scene is None else _collada_node_triangles(scene, geometries, nodes, {})
    except (KeyError, ValueError, RecursionError) as exc:
        raise SceneError(f"the DAE scene graph is malformed: {exc}", "mesh") from exc
    return MeshCounts(triangles, 3 * triangles)


def _dae(tag: str) -> str:
    """``tag`` in any namespace (COLLADA 1.4's, 1.5's or none), for lxml's iter and find."""
    return "{*}" + tag


def _local_name(element: Any) -> str:
    """An element's tag without its namespace ('' for comments and processing instructions)."""
    return etree.QName(element).localname if isinstance(element.tag, str) else ""


def _collada_scene(root: Any) -> Any:
    """The visual scene ``<scene><instance_visual_scene>`` names (trimesh loads that one), or
    the first one; None without any."""
    scenes = {element.get("id"): element for element in root.iter(_dae("visual_scene"))}
    instance = root.find(f"{_dae('scene')}/{_dae('instance_visual_scene')}")
    if instance is not None and instance.get("url", "").startswith("#"):
        named = scenes.get(instance.get("url")[1:])
        if named is not None:
            return named
    return next(iter(scenes.values()), None)


def _collada_geometry_triangles(geometry: Any) -> int:
    """Triangles of one ``<geometry>``'s mesh, counted from its index data."""
    triangles = 0
    for mesh in geometry.findall(_dae("mesh")):
        for primitive in mesh:
            kind = _local_name(primitive)
            if kind not in ("triangles", "polylist", "polygons"):
                continue  # lines, tristrips, trifans: trimesh reads no triangles from them
            offsets = [int(i.get("offset", 0)) for i in primitive.findall(_dae("input"))]
            stride = max(offsets, default=-1) + 1
            if stride == 0:
                continue
            if kind == "triangles":
                for p in primitive.findall(_dae("p")):
                    triangles += _token_count(p.text) // (3 * stride)
            elif kind == "polylist":
                vcount = primitive.find(_dae("vcount"))
                if vcount is not None and vcount.text:
                    triangles += sum(max(int(v) - 2, 0) for v in vcount.text.split())
            else:
                for p in primitive.findall(_dae("p")):
                    triangles += max(_token_count(p.text) // stride - 2, 0)
    return triangles


def _token_count(text: str | None) -> int:
    return 0 if not text else len(text.split())


def _collada_node_triangles(
    node: Any, geometries: dict[str, int], nodes: dict[str, Any], counted: dict[Any, int]
) -> int:
    """Triangles below ``node`` (a visual scene or a node): its geometry instances, its child
    nodes and the nodes it instances, each reference counted in full. ``counted`` holds the
    totals of nodes done (a shared subtree is walked once); a node met again while being
    counted is a cycle (ValueError). Keyed by the element itself: the dictionary keeps lxml's
    proxy alive, so the key stays that node's."""
    if node in counted:
        if counted[node] < 0:
            raise ValueError(f"node {node.get('id')!r} instances itself")
        return counted[node]
    counted[node] = -1
    total = 0
    for child in node:
        kind = _local_name(child)
        if kind == "instance_geometry":
            total += geometries.get(_fragment(child.get("url", "")), 0)
        elif kind == "instance_node":
            target = nodes.get(_fragment(child.get("url", "")))
            if target is not None:
                total += _collada_node_triangles(target, geometries, nodes, counted)
        elif kind == "node":
            total += _collada_node_triangles(child, geometries, nodes, counted)
    counted[node] = total
    return total


def _fragment(url: str) -> str:
    """The id a local reference ``#id`` names ('' for other references)."""
    return url[1:] if url.startswith("#") else ""
