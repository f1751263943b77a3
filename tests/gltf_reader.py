"""An independent glTF reader for the tests: accessors decoded from the GLB's binary chunk,
node transforms composed down the tree, animation samplers interpolated (linear, slerp).
Shares nothing with the exporter (planner/export)."""

from __future__ import annotations

import numpy as np
import pygltflib

# Gecko z up -> glTF y up: (x, y, z) -> (x, z, -y), written here independently.
TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
COMPONENTS = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}
DTYPES = {5126: "<f4", 5125: "<u4", 5123: "<u2"}


def accessor(gltf: pygltflib.GLTF2, blob: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` as an (count, components) float64 array."""
    item = gltf.accessors[index]
    view = gltf.bufferViews[item.bufferView]
    width = COMPONENTS[item.type]
    start = (view.byteOffset or 0) + (item.byteOffset or 0)
    data = np.frombuffer(
        blob, dtype=DTYPES[item.componentType], count=item.count * width, offset=start
    )
    return data.reshape(item.count, width).astype(np.float64)


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    dot = float(a @ b)
    if dot < 0:
        b, dot = -b, -dot
    if dot > 0.9995:
        out = a + s * (b - a)
    else:
        theta = np.arccos(dot)
        out = (np.sin((1 - s) * theta) * a + np.sin(s * theta) * b) / np.sin(theta)
    return np.asarray(out / np.linalg.norm(out))


def _sample(times: np.ndarray, values: np.ndarray, t: float, rotation: bool) -> np.ndarray:
    if t <= times[0]:
        return values[0]
    if t >= times[-1]:
        return values[-1]
    k = int(np.searchsorted(times, t, side="right")) - 1
    s = (t - times[k]) / (times[k + 1] - times[k])
    if rotation:
        return _slerp(values[k], values[k + 1], s)
    return np.asarray(values[k] + s * (values[k + 1] - values[k]))


def world_transforms(glb: bytes, t: float) -> dict[str, np.ndarray]:
    """Every named node's (4, 4) world transform at animation time t."""
    gltf = pygltflib.GLTF2.load_from_bytes(glb)
    blob = gltf.binary_blob()
    trs: list[dict[str, np.ndarray]] = []
    for node in gltf.nodes:
        assert node.matrix is None and node.scale in (None, [1, 1, 1])
        trs.append(
            {
                "translation": np.array(node.translation or [0.0, 0.0, 0.0]),
                "rotation": np.array(node.rotation or [0.0, 0.0, 0.0, 1.0]),
            }
        )
    for animation in gltf.animations:
        for channel in animation.channels:
            sampler = animation.samplers[channel.sampler]
            times = accessor(gltf, blob, sampler.input)[:, 0]
            values = accessor(gltf, blob, sampler.output)
            path = channel.target.path
            trs[channel.target.node][path] = _sample(times, values, t, path == "rotation")
    world: dict[str, np.ndarray] = {}

    def walk(index: int, parent: np.ndarray) -> None:
        local = np.eye(4)
        local[:3, :3] = _quat_matrix(trs[index]["rotation"])
        local[:3, 3] = trs[index]["translation"]
        placed = parent @ local
        name = gltf.nodes[index].name
        assert name not in world, f"node name {name} repeated"
        world[name] = placed
        for child in gltf.nodes[index].children:
            walk(child, placed)

    for root in gltf.scenes[gltf.scene].nodes:
        walk(root, np.eye(4))
    return world
