"""planner.export: every character (the built-in ones, Talos and HyQ with their meshes when
installed) exported with random motions is a valid GLB whose animation gives Pinocchio's
link placements; bad input is refused by name; the output is deterministic."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pygltflib
import pytest

from planner.character import builtin_character_ids, get_character, real_robot_ids
from planner.export import ExportError, Overlays, PhaseMarks, SceneMesh, motion_glb, scene_glb
from tests.gltf_reader import TO_Y_UP, world_transforms
from tests.gltf_validator import errors_of, validate

CHARACTERS = [*builtin_character_ids(), *real_robot_ids()]


def _random_motion(character_id: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    character = get_character(character_id)
    rng = np.random.default_rng(seed)
    qs = np.tile(np.asarray(character.q_ref), (n, 1))
    qs[:, :3] += rng.uniform(-2.0, 2.0, size=(n, 3))
    quats = rng.normal(size=(n, 4))
    qs[:, 3:7] = quats / np.linalg.norm(quats, axis=1, keepdims=True)
    qs[:, 7:] = rng.uniform(character.lower, character.upper, size=(n, character.n_joints))
    times = np.cumsum(rng.uniform(0.01, 0.1, size=n))
    return times, qs


@pytest.mark.parametrize("character_id", CHARACTERS)
def test_random_motion_matches_forward_kinematics(character_id: str, tmp_path: Path) -> None:
    character = get_character(character_id)
    times, qs = _random_motion(character_id, 6, seed=len(character_id))
    glb = motion_glb(character, times, qs)
    assert glb == motion_glb(character, times, qs), "same input, same bytes"
    path = tmp_path / f"{character_id}.glb"
    path.write_bytes(glb)
    (report,) = validate([path])
    assert report["issues"]["numErrors"] == 0, errors_of(report)
    model, data = character.model, character.model.createData()
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    gltf = pygltflib.GLTF2.load_from_bytes(glb)
    names = [node.name for node in gltf.nodes]
    assert all(names.count(name) == 1 for name in bodies)
    assert len(gltf.meshes) >= 1
    for k in (0, 2, 5):
        world = world_transforms(glb, float(np.float32(times[k])))
        pin.framesForwardKinematics(model, data, qs[k])
        for name in bodies:
            placement = data.oMf[model.getFrameId(name)]
            got = world[name]
            assert np.abs(got[:3, 3] - TO_Y_UP @ placement.translation).max() < 1e-5, name
            assert np.abs(got[:3, :3] - TO_Y_UP @ placement.rotation).max() < 1e-5, name


def test_between_keyframes_is_an_interpolation() -> None:
    character = get_character("humanoid")
    times, qs = np.array([0.0, 1.0]), np.tile(np.asarray(character.q_ref), (2, 1))
    qs[1, 0] += 1.0
    world = world_transforms(motion_glb(character, times, qs), 0.25)
    root = TO_Y_UP @ (qs[0, :3] + 0.25 * (qs[1, :3] - qs[0, :3]))
    assert np.allclose(world["pelvis"][:3, 3], root, atol=1e-6)


def test_overlays_and_scene_are_y_up_nodes(tmp_path: Path) -> None:
    character = get_character("quadruped")
    times, qs = _random_motion("quadruped", 3, seed=1)
    phase = PhaseMarks(0.0, 1.0, ("lf_foot",), np.array([[1.0, 2.0, 3.0]]))
    overlays = Overlays((np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]),), (phase,))
    square = SceneMesh(
        np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.5], [0.0, 1.0, 0.5]]),
        np.array([[0, 1, 2], [0, 2, 3]]),
    )
    glb = motion_glb(character, times, qs, scene=square, overlays=overlays, extras={"a": 1})
    path = tmp_path / "full.glb"
    path.write_bytes(glb)
    (report,) = validate([path])
    assert report["issues"]["numErrors"] == 0, errors_of(report)
    gltf = pygltflib.GLTF2.load_from_bytes(glb)
    names = {node.name for node in gltf.nodes}
    assert {"scene", "com", "contacts", "phase_000"} <= names
    assert gltf.scenes[0].extras == {"gecko": {"a": 1}}
    alone = pygltflib.GLTF2.load_from_bytes(scene_glb(square))
    position = alone.accessors[alone.meshes[0].primitives[0].attributes.POSITION]
    assert position.max == [1.0, 0.5, 0.0] and position.min == [0.0, 0.0, -1.0]


@pytest.mark.parametrize(
    ("times", "rows", "message"),
    [
        (np.zeros(0), 0, "at least one keyframe"),
        (np.array([0.0, 1.0]), 3, "configurations must be"),
        (np.array([1.0, 0.0]), 2, "must not decrease"),
        (np.array([0.0, np.nan]), 2, "non-finite"),
    ],
)
def test_bad_motion_is_refused(times: np.ndarray, rows: int, message: str) -> None:
    character = get_character("humanoid")
    qs = np.tile(np.asarray(character.q_ref), (rows, 1))
    with pytest.raises(ExportError, match=message):
        motion_glb(character, times, qs)


def test_bad_scene_is_refused() -> None:
    with pytest.raises(ExportError, match="face indices"):
        scene_glb(SceneMesh(np.zeros((3, 3)), np.array([[0, 1, 3]])))
