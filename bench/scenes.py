"""Scene benchmarks: load + surface extraction, BVH cache, collision queries. Prints medians.

Run: ``.venv/bin/python -m bench.scenes`` (or ``python bench/scenes.py``) from the repo root.
Asserts nothing; numbers depend on the machine.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.poses import normalize_quaternion, poses_from, quaternion_to_matrix
from planner.scene import (
    Scene,
    SurfaceKind,
    build_scene,
    builtin_scene_ids,
    hpp_environment_meshes,
    load_builtin_scene,
    load_mesh,
)
from planner.scene.builtin import BUILTIN_MESHES
from planner.shapes import Box

TRUNK = Box(half_extents=np.array([0.2, 0.15, 0.3]))  # a 0.4 x 0.3 x 0.6 m trunk


def median_seconds(run: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def random_poses(scene: Scene, count: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = scene.bounds
    centres = rng.uniform(lo - 0.2, hi + 0.2, size=(count, 3))
    rotations = quaternion_to_matrix(normalize_quaternion(rng.normal(size=(count, 4))))
    return poses_from(centres, rotations)


def collision_row(label: str, scene: Scene) -> None:
    poses = random_poses(scene, 2000)
    world = scene.collision
    hits = world.collides_many(TRUNK, poses)
    single = median_seconds(lambda: [world.collides(TRUNK, p) for p in poses[:500]], 5) / 500
    batched = median_seconds(lambda: world.collides_many(TRUNK, poses), 5) / len(poses)
    distance = median_seconds(lambda: world.distance_many(TRUNK, poses[:300]), 3) / 300
    print(
        f"  {label:<28} collide single {single * 1e6:7.1f} us  batched {batched * 1e6:7.1f} us"
        f"/pose  distance {distance * 1e6:7.1f} us/pose  ({hits.mean():.0%} colliding)"
    )


def main() -> None:
    print("Built-in scenes: mesh generation + surfaces + BVH (median of 5)")
    for scene_id in builtin_scene_ids():
        seconds = median_seconds(lambda scene_id=scene_id: load_builtin_scene(scene_id), 5)
        scene = load_builtin_scene(scene_id)
        support = len(scene.surfaces_of(SurfaceKind.SUPPORT))
        lean = len(scene.surfaces_of(SurfaceKind.LEAN))
        mesh = BUILTIN_MESHES[scene_id][1]()
        extract = median_seconds(lambda mesh=mesh: build_scene(mesh), 5)
        print(
            f"  {scene_id:<14} {scene.triangle_count:>6} tris  {support:>3} support"
            f" {lean:>3} lean  total {seconds * 1e3:7.1f} ms  (build_scene {extract * 1e3:6.1f} ms)"
        )

    meshes = hpp_environment_meshes()
    if not meshes:
        print("hpp-environments not installed: skipping the real scenes")
    names = [
        n for n in ("plateformes_full", "cave_simplified", "bauzil_stairs", "darpa") if n in meshes
    ]
    scenes: dict[str, Scene] = {}
    if names:
        print(
            "hpp-environments scenes (median of 3): load_mesh, build_scene (no cache),"
            " build_scene from the BVH cache"
        )
    for name in names:
        path = meshes[name]
        load = median_seconds(lambda path=path: load_mesh(path), 3)
        mesh = load_mesh(path)
        build = median_seconds(lambda mesh=mesh: build_scene(mesh), 3)
        with tempfile.TemporaryDirectory() as cache:
            build_scene(mesh, cache_dir=Path(cache))
            cached = median_seconds(
                lambda mesh=mesh, cache=cache: build_scene(mesh, cache_dir=Path(cache)), 3
            )
        scene = build_scene(mesh, name=name)
        scenes[name] = scene
        support = len(scene.surfaces_of(SurfaceKind.SUPPORT))
        lean = len(scene.surfaces_of(SurfaceKind.LEAN))
        print(
            f"  {name:<20} {scene.triangle_count:>7} tris  {support:>4} support {lean:>4} lean"
            f"  load {load * 1e3:7.1f} ms  build {build * 1e3:7.1f} ms"
            f"  cached {cached * 1e3:7.1f} ms"
        )

    print("Collision queries, trunk box 0.4 x 0.3 x 0.6 m at random poses (median)")
    for scene_id in ("stairs", "climbing_wall", "rubble"):
        collision_row(scene_id, load_builtin_scene(scene_id))
    for name, scene in scenes.items():
        collision_row(name, scene)


if __name__ == "__main__":
    main()
