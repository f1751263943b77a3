"""Fixtures for the scene tests: built-in and hpp-environments scenes, built once per session."""

from __future__ import annotations

import pytest

from planner.scene import Scene, build_scene, hpp_environment_meshes, load_builtin_scene, load_mesh

HPP_SCENES = ("bauzil_stairs", "darpa", "climb", "stairs", "polaris", "random_scene_10x10_V3")


@pytest.fixture(scope="session")
def builtin_scenes() -> dict[str, Scene]:
    from planner.scene import builtin_scene_ids

    return {scene_id: load_builtin_scene(scene_id) for scene_id in builtin_scene_ids()}


@pytest.fixture(scope="session")
def hpp_scenes() -> dict[str, Scene]:
    meshes = hpp_environment_meshes()
    if not meshes:
        pytest.skip("hpp-environments is not installed (test dependency)")
    missing = [name for name in HPP_SCENES if name not in meshes]
    if missing:
        pytest.skip(f"hpp-environments lacks {missing}")
    return {name: build_scene(load_mesh(meshes[name]), name=name) for name in HPP_SCENES}
