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
