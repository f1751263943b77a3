"""Mesh files for upload tests, built from real meshes: instanced GLBs and large PLYs."""

from __future__ import annotations

import numpy as np
import trimesh


def instanced_glb(instances: int, subdivisions: int = 3) -> bytes:
    """A GLB whose one mesh (an icosphere: 20 * 4**subdivisions triangles) is instanced by
    ``instances`` nodes, 3 m apart along x: small on disk, ``instances`` times that in
    triangles once flattened."""
    ball = trimesh.creation.icosphere(subdivisions=subdivisions)
    scene = trimesh.Scene()
    for index in range(instances):
        transform = np.eye(4)
        transform[0, 3] = 3.0 * index
        scene.graph.update(
            frame_from=scene.graph.base_frame,
            frame_to=f"instance{index}",
            matrix=transform,
            geometry="ball",
        )
    scene.geometry["ball"] = ball
    data = scene.export(file_type="glb")
    assert isinstance(data, bytes)
    return data


def grid_mesh(triangles: int) -> trimesh.Trimesh:
    """A flat grid of at least ``triangles`` triangles (two per 0.1 m cell), z = 0."""
    side = int(np.ceil(np.sqrt(triangles / 2.0)))
    xs = np.arange(side + 1, dtype=np.float64) * 0.1
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    corner = (np.arange(side)[:, None] * (side + 1) + np.arange(side)[None, :]).ravel()
    a, b, c, d = corner, corner + side + 1, corner + side + 2, corner + 1
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(vertices, faces, process=False)


def grid_ply(triangles: int) -> bytes:
    """A binary PLY of :func:`grid_mesh`."""
    data = grid_mesh(triangles).export(file_type="ply")
    assert isinstance(data, bytes)
    return data


def instanced_dae(
    instances: int, *, subdivisions: int = 2, doublings: int = 0, primitive: str = "triangles"
) -> bytes:
    """A COLLADA 1.4.1 file whose one mesh (an icosphere: 20 * 4**subdivisions triangles, as
    ``triangles`` or as a ``polylist`` of triangles) is instanced ``instances`` times, 3 m apart
    along x, by nodes of the visual scene naming a library node (``instance_node``). With
    ``doublings`` = k, that library node is itself a chain of k nodes each instancing the next
    twice (two offsets along y), so each instance holds 2**k copies: a file of a few KB can
    hold millions of triangles once flattened."""
    ball = trimesh.creation.icosphere(subdivisions=subdivisions)
    positions = " ".join(f"{x:.6f}" for x in ball.vertices.ravel())
    indices = " ".join(str(i) for i in ball.faces.ravel())
    count = len(ball.faces)
    if primitive == "triangles":
        faces = f'<triangles count="{count}">{{input}}<p>{indices}</p></triangles>'
    elif primitive == "polylist":
        vcount = " ".join("3" for _ in range(count))
        faces = (
            f'<polylist count="{count}">{{input}}<vcount>{vcount}</vcount>'
            f"<p>{indices}</p></polylist>"
        )
    else:
        raise ValueError(f"unknown primitive {primitive!r}")
    faces = faces.format(input='<input semantic="VERTEX" source="#ball-vertices" offset="0"/>')
    chain = ['<node id="level0" name="level0"><instance_geometry url="#ball"/></node>']
    for level in range(1, doublings + 1):
        chain.append(
            f'<node id="level{level}" name="level{level}">'
            f"<node><matrix>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</matrix>"
            f'<instance_node url="#level{level - 1}"/></node>'
            f"<node><matrix>1 0 0 0 0 1 0 {3 * 2 ** (level - 1)} 0 0 1 0 0 0 0 1</matrix>"
            f'<instance_node url="#level{level - 1}"/></node></node>'
        )
    placed = "".join(
        f'<node id="instance{index}"><matrix>1 0 0 {3.0 * index} 0 1 0 0 0 0 1 0 0 0 0 1'
        f'</matrix><instance_node url="#level{doublings}"/></node>'
        for index in range(instances)
    )
    document = f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><unit meter="1" name="meter"/><up_axis>Z_UP</up_axis></asset>
<library_geometries><geometry id="ball" name="ball"><mesh>
<source id="ball-positions">
<float_array id="ball-positions-array" count="{ball.vertices.size}">{positions}</float_array>
<technique_common><accessor source="#ball-positions-array" count="{len(ball.vertices)}" stride="3">
<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
</accessor></technique_common></source>
<vertices id="ball-vertices"><input semantic="POSITION" source="#ball-positions"/></vertices>
{faces}
</mesh></geometry></library_geometries>
<library_nodes>{"".join(chain)}</library_nodes>
<library_visual_scenes><visual_scene id="scene">{placed}</visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""
    return document.encode()
