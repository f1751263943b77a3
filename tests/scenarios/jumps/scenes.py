"""Scenes of the jump scenarios: built-in, generated here (pond, rooftops) or hpp-environments."""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

from planner.scene import Scene, build_scene, hpp_environment_meshes, load_builtin_scene, load_mesh
from tests.paths import gecko_cache_dir


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    size = np.subtract(hi, lo)
    centre = np.add(hi, lo) / 2.0
    return trimesh.creation.box(
        extents=size, transform=trimesh.transformations.translation_matrix(centre)
    )


def pond_mesh() -> trimesh.Trimesh:
    """Two banks (top z = 0.3) and five 0.5 m stepping stones of varying height over a pond
    whose water (no surface at all) lies between x = 0 and x = 4.4."""
    parts = [_box((-2.0, -1.5, -0.5), (0.0, 1.5, 0.3)), _box((4.4, -1.5, -0.5), (6.4, 1.5, 0.3))]
    stones = [
        (0.55, 0.0, 0.25),
        (1.3, 0.3, 0.35),
        (2.05, -0.2, 0.2),
        (2.9, 0.1, 0.3),
        (3.7, -0.1, 0.25),
    ]
    for x, y, top in stones:
        parts.append(_box((x - 0.25, y - 0.25, -0.5), (x + 0.25, y + 0.25, top)))
    return trimesh.util.concatenate(parts)


def rooftops_mesh() -> trimesh.Trimesh:
    """A street (z = 0) and a row of 2.5 x 3 m roofs of heights 3.0 to 4.2 m with 0.8 to 1.4 m
    gaps between the houses."""
    parts = [_box((-2.0, -3.0, -0.1), (16.0, 3.0, 0.0))]
    x = 0.0
    for height, gap in [(3.0, 0.8), (3.6, 1.2), (3.2, 1.0), (4.2, 1.4), (3.8, 0.0)]:
        parts.append(_box((x, -1.5, 0.0), (x + 2.5, 1.5, height)))
        x += 2.5 + gap
    return trimesh.util.concatenate(parts)


GENERATED = {"pond": pond_mesh, "rooftops": rooftops_mesh}


def load_scenario_scene(spec: dict[str, Any]) -> Scene | None:
    """The scene of a scenario's ``scene`` entry; None when its hpp mesh is not installed."""
    kind, name = spec["kind"], spec["name"]
    if kind == "builtin":
        return load_builtin_scene(name, gecko_cache_dir())
    if kind == "generated":
        return build_scene(GENERATED[name](), scene_id=name, cache_dir=gecko_cache_dir())
    if kind == "hpp":
        meshes = hpp_environment_meshes()
        if name not in meshes:
            return None
        return build_scene(load_mesh(meshes[name]), scene_id=name, cache_dir=gecko_cache_dir())
    raise ValueError(f"unknown scene kind {kind!r}")
