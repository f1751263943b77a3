"""Counts read from mesh headers and glTF scene graphs agree with what the parser builds."""

from __future__ import annotations

import io
import json
import struct

import pytest
import trimesh

from planner.scene import SceneError
from planner.scene.builtin import stairs_mesh
from planner.scene.counts import MeshCounts, count_mesh
from tests.mesh_files import grid_mesh, grid_ply, instanced_dae, instanced_glb


def _parsed(data: bytes, fmt: str) -> trimesh.Trimesh:
    loaded = trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh", process=False)
    assert isinstance(loaded, trimesh.Trimesh)
    return loaded


@pytest.mark.parametrize("fmt", ["stl", "stl_ascii", "ply", "obj", "glb"])
def test_counts_match_the_parsed_mesh(fmt: str) -> None:
    data = stairs_mesh().export(file_type=fmt)
    data = data.encode() if isinstance(data, str) else data
    fmt = fmt.removesuffix("_ascii")
    counts = count_mesh(data, fmt)
    parsed = _parsed(data, fmt)
    assert counts is not None
    assert counts.triangles == len(parsed.faces)
    assert counts.vertices == len(parsed.vertices)


def test_an_instanced_glb_counts_every_instance_before_parsing() -> None:
    data = instanced_glb(95, subdivisions=3)  # 1,280 triangles, 95 times
    counts = count_mesh(data, "glb")
    assert counts == MeshCounts(triangles=95 * 1280, vertices=95 * 642)
    assert counts.triangles == len(_parsed(data, "glb").faces)
    assert len(data) < 64_000  # the file holds the mesh once


def test_a_large_ply_is_counted_from_its_header() -> None:
    data = grid_ply(200_000)
    counts = count_mesh(data, "ply")
    assert counts == MeshCounts(len(grid_mesh(200_000).faces), len(grid_mesh(200_000).vertices))
    truncated = data[: data.index(b"end_header") + 11] + b"\0" * 10
    assert count_mesh(truncated, "ply") == counts  # the header is all it reads


def test_a_binary_stl_states_its_count() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=4)
    data = bytes(mesh.export(file_type="stl"))
    assert count_mesh(data, "stl") == MeshCounts(5120, 3 * 5120)
    claimed = data[:80] + struct.pack("<I", 10**9) + data[84:]  # size disagrees: not binary
    assert count_mesh(claimed, "stl") == MeshCounts(0, 0)


def _gltf(nodes: list[dict[str, object]], roots: list[int]) -> bytes:
    document = {
        "asset": {"version": "2.0"},
        "accessors": [{"count": 30}, {"count": 12}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0}]}],
        "nodes": nodes,
        "scenes": [{"nodes": roots}],
        "scene": 0,
    }
    return json.dumps(document).encode()


def test_shared_and_cyclic_nodes_count_once_each() -> None:
    # Node 1 is a child of nodes 0 and 2, and 2 is its own descendant: each counts once.
    nodes = [{"children": [1, 2]}, {"mesh": 0}, {"mesh": 0, "children": [1, 2]}]
    assert count_mesh(_gltf(nodes, [0]), "gltf") == MeshCounts(triangles=20, vertices=24)
    assert count_mesh(_gltf([{"mesh": 0}, {"mesh": 0}], [0]), "gltf") == MeshCounts(10, 12)


@pytest.mark.parametrize(
    ("data", "fmt"),
    [
        (b"not a glb", "glb"),
        (b"glTF" + struct.pack("<II", 2, 40) + struct.pack("<II", 8, 1) + b"x" * 20, "glb"),
        (b"{not json", "gltf"),
        (_gltf([{"mesh": 5}], [0]), "gltf"),
        (_gltf([{"children": [7]}], [0]), "gltf"),
        (b"ply\nformat ascii 1.0\n", "ply"),
    ],
)
def test_unreadable_headers_are_scene_errors(data: bytes, fmt: str) -> None:
    with pytest.raises(SceneError):
        count_mesh(data, fmt)


@pytest.mark.parametrize(
    ("instances", "doublings", "primitive"),
    [(1, 0, "triangles"), (3, 0, "triangles"), (2, 3, "triangles"), (3, 2, "polylist")],
)
def test_a_dae_counts_every_instance_as_trimesh_flattens_it(
    instances: int, doublings: int, primitive: str
) -> None:
    data = instanced_dae(instances, subdivisions=1, doublings=doublings, primitive=primitive)
    triangles = instances * 2**doublings * 80  # an icosphere of 80 triangles
    assert count_mesh(data, "dae") == MeshCounts(triangles, 3 * triangles)
    assert len(_parsed(data, "dae").faces) == triangles


def test_a_dae_exported_by_trimesh_is_counted() -> None:
    data = stairs_mesh().export(file_type="dae")
    assert count_mesh(data, "dae") == MeshCounts(
        len(stairs_mesh().faces), 3 * len(stairs_mesh().faces)
    )


def test_a_small_dae_of_nested_instances_counts_millions_at_once() -> None:
    data = instanced_dae(20, subdivisions=2, doublings=10)  # 320 triangles, 20 * 1024 times
    assert len(data) < 20_000
    assert count_mesh(data, "dae") == MeshCounts(20 * 1024 * 320, 3 * 20 * 1024 * 320)


def test_a_dae_counts_its_index_data_not_its_count_attributes() -> None:
    honest = instanced_dae(4, subdivisions=1)
    lying = honest.replace(b'<triangles count="80">', b'<triangles count="1">')
    assert lying != honest
    assert count_mesh(lying, "dae") == count_mesh(honest, "dae") == MeshCounts(320, 960)


_DAE_NS = b'xmlns="http://www.collada.org/2005/11/COLLADASchema"'


@pytest.mark.parametrize(
    "data",
    [
        b"<COLLADA",  # not XML
        b"<COLLADA " + _DAE_NS + b"><library_nodes><node id='a'><instance_node url='#b'/></node>"
        b"<node id='b'><instance_node url='#a'/></node></library_nodes><library_visual_scenes>"
        b"<visual_scene id='s'><node><instance_node url='#a'/></node></visual_scene>"
        b"</library_visual_scenes></COLLADA>",  # a cycle of instance_node references
    ],
)
def test_unreadable_or_cyclic_dae_are_scene_errors(data: bytes) -> None:
    with pytest.raises(SceneError):
        count_mesh(data, "dae")


def test_a_dae_without_a_scene_holds_nothing_and_entities_are_not_expanded() -> None:
    assert count_mesh(b"<COLLADA " + _DAE_NS + b"/>", "dae") == MeshCounts(0, 0)
    entity = (
        b'<?xml version="1.0"?><!DOCTYPE COLLADA [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
        b"<COLLADA " + _DAE_NS + b"><asset><title>&x;</title></asset></COLLADA>"
    )
    assert count_mesh(entity, "dae") == MeshCounts(0, 0)
