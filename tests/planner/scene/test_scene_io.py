"""Mesh loading: format round trips, y-up input and clear errors on bad input."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
import trimesh

from planner.scene import SceneError, build_scene, load_mesh
from planner.scene.builtin import stairs_mesh


def _sorted_triangles(mesh: trimesh.Trimesh) -> np.ndarray:
    tri = np.round(mesh.vertices[mesh.faces], 4) + 0.0
    # Order-independent: sort vertices within each triangle, then the triangles.
    tri = np.sort(tri.view([("", tri.dtype)] * 3).reshape(len(tri), 3), axis=1)
    return np.sort(tri.reshape(len(tri), -1), axis=0)


@pytest.mark.parametrize("fmt", ["stl", "obj", "ply", "glb", "dae"])
def test_round_trip(fmt: str, tmp_path) -> None:
    original = stairs_mesh()
    data = original.export(file_type=fmt)
    if isinstance(data, str):
        data = data.encode()
    from_bytes = load_mesh(data, fmt)
    path = tmp_path / f"scene.{fmt}"
    path.write_bytes(data)
    from_file = load_mesh(path)
    for loaded in (from_bytes, from_file):
        assert len(loaded.faces) == len(original.faces)
        assert np.allclose(loaded.bounds, original.bounds, atol=1e-6)
        assert loaded.area == pytest.approx(original.area, rel=1e-6)
        assert np.array_equal(_sorted_triangles(loaded), _sorted_triangles(original))
    scene = build_scene(from_file)
    assert len(scene.surfaces) == len(build_scene(original).surfaces)


def test_y_up_input(tmp_path) -> None:
    original = stairs_mesh()
    y_up = original.copy()
    # z-up -> y-up: rotate -90 degrees about x (z becomes y).
    y_up.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    assert y_up.bounds[1, 1] == pytest.approx(original.bounds[1, 2])
    path = tmp_path / "y_up.glb"
    path.write_bytes(y_up.export(file_type="glb"))
    restored = load_mesh(path, y_up=True)
    assert np.allclose(restored.bounds, original.bounds, atol=1e-6)
    not_rotated = load_mesh(path)
    assert np.allclose(not_rotated.bounds, y_up.bounds, atol=1e-6)


def _binary_stl(triangles: np.ndarray) -> bytes:
    out = io.BytesIO()
    out.write(b"\0" * 80 + struct.pack("<I", len(triangles)))
    for tri in triangles:
        out.write(struct.pack("<12fH", 0, 0, 0, *np.asarray(tri, dtype=np.float32).ravel(), 0))
    return out.getvalue()


def test_corrupt_bytes_give_scene_error() -> None:
    valid = stairs_mesh().export(file_type="stl")
    for fmt, data in [
        ("stl", valid[: len(valid) // 2 + 7]),
        ("glb", b"glTF" + b"\x02\x00\x00\x00" + b"\xff" * 40),
        ("ply", b"ply\nformat nonsense\n"),
        ("dae", b"<COLLADA><garbage"),
        ("obj", b"v 0 0 0\nv 1 0\nf 1 2 3\n"),
    ]:
        with pytest.raises(SceneError) as info:
            load_mesh(data, fmt)
        assert info.value.field in {"mesh", "vertices", "faces"}
        assert info.value.message


def test_empty_input() -> None:
    with pytest.raises(SceneError, match="empty"):
        load_mesh(b"", "stl")
    with pytest.raises(SceneError, match=r"empty|no triangle"):
        load_mesh(_binary_stl(np.zeros((0, 3, 3))), "stl")
    with pytest.raises(SceneError, match=r"empty|no triangle"):
        load_mesh(b"# nothing here\n", "obj")
    with pytest.raises(SceneError, match="empty"):
        build_scene(trimesh.Trimesh())


def test_nan_vertices() -> None:
    triangles = np.array(
        [[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]]
    )
    with pytest.raises(SceneError) as info:
        load_mesh(_binary_stl(triangles), "stl")
    assert info.value.field == "vertices"
    assert "NaN" in info.value.message
    obj = b"v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n"
    with pytest.raises(SceneError, match="NaN"):
        load_mesh(obj, "obj")
    bad = trimesh.Trimesh(
        np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), np.array([[0, 1, 2]]), process=False
    )
    with pytest.raises(SceneError, match="NaN or infinite"):
        build_scene(bad)


def test_degenerate_and_limits() -> None:
    flat = np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0]]])
    with pytest.raises(SceneError, match="degenerate"):
        load_mesh(_binary_stl(flat), "stl")
    with pytest.raises(SceneError, match="limit"):
        load_mesh(stairs_mesh().export(file_type="stl"), "stl", max_triangles=10)
    with pytest.raises(SceneError) as info:
        load_mesh(b"solid", "fbx")
    assert info.value.field == "format"
    with pytest.raises(SceneError) as info:
        load_mesh(b"solid")
    assert info.value.field == "format"
    with pytest.raises(SceneError, match="no such"):
        load_mesh(__import__("pathlib").Path("/nonexistent/scene.stl"))


def test_gltf_with_external_buffers(tmp_path) -> None:
    original = stairs_mesh()
    files = original.export(file_type="gltf")
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    loaded = load_mesh(tmp_path / "model.gltf")
    assert len(loaded.faces) == len(original.faces)
    assert np.allclose(loaded.bounds, original.bounds)
    with pytest.raises(SceneError, match="GLB"):
        load_mesh(files["model.gltf"], "gltf")


@pytest.mark.parametrize("fmt", ["stl", "obj", "ply", "glb", "dae"])
def test_random_bytes_only_raise_scene_error(fmt: str) -> None:
    rng = np.random.default_rng(3)
    for size in (1, 84, 200, 5000):
        try:
            mesh = load_mesh(rng.bytes(size), fmt)
        except SceneError as error:
            assert error.message
        else:  # a lucky parse must still be a valid mesh
            assert len(mesh.faces) > 0 and np.all(np.isfinite(mesh.vertices))
