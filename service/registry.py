"""The service's registry: characters with their offline data, built-in and uploaded scenes.

Uploaded scenes are stored as ``<id>.npz`` (float64 vertices, int64 faces) plus ``<id>.json``
(name) in the scenes directory; both are written to temporary files and renamed into place, so a
failed upload leaves nothing behind.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from planner.character import (
    Character,
    builtin_character_ids,
    character_spec_path,
    load_character,
    real_robot_ids,
)
from planner.offline import OfflineData, load_offline_data
from planner.scene import Scene, build_scene, builtin_scene_ids, load_builtin_scene
from planner.scene.collision import bvh_cache_path
from service.files import is_temporary

log = logging.getLogger("gecko.registry")


@dataclass(frozen=True, slots=True)
class CharacterEntry:
    """A served character and its offline reachability data."""

    character: Character
    data: OfflineData


class Registry:
    """Characters (loaded at start) and scenes (built-in on first use, uploaded from disk)."""

    def __init__(
        self,
        *,
        cache_dir: Path,
        scenes_dir: Path,
        character_ids: list[str] | None = None,
        build_missing_data: bool = True,
        data_seed: int = 0,
    ) -> None:
        self.cache_dir = cache_dir
        self.scenes_dir = scenes_dir
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        self.scenes_dir.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self._scenes: dict[str, Scene] = {}
        self._characters: dict[str, CharacterEntry] = {}
        self._build_missing_data = build_missing_data
        self._data_seed = data_seed
        self.character_ids: tuple[str, ...] = tuple(
            character_ids if character_ids is not None else default_character_ids()
        )

    # -- characters ---------------------------------------------------------------------------

    def preload(self) -> None:
        """Load every served character and its offline data now (the service does at start)."""
        for character_id in self.character_ids:
            self.get_character(character_id)

    @property
    def characters(self) -> dict[str, CharacterEntry]:
        """Every served character, loading those not loaded yet."""
        return {cid: entry for cid in self.character_ids if (entry := self.get_character(cid))}

    def get_character(self, character_id: str) -> CharacterEntry | None:
        """The served character with this id and its offline data; None if not served."""
        if character_id not in self.character_ids:
            return None
        with self._lock:
            entry = self._characters.get(character_id)
            if entry is None:
                character = load_character(character_spec_path(character_id))
                data = load_offline_data(
                    character,
                    self.cache_dir,
                    seed=self._data_seed,
                    build_if_missing=self._build_missing_data,
                    progress=False,
                )
                entry = CharacterEntry(character, data)
                self._characters[character_id] = entry
            return entry

    # -- scenes -------------------------------------------------------------------------------

    @staticmethod
    def builtin_scene_ids() -> tuple[str, ...]:
        return tuple(builtin_scene_ids())

    def uploaded_scene_ids(self) -> list[str]:
        """Ids of the uploaded scenes on disk (temporary files of writes never count)."""
        return sorted(
            path.stem
            for path in self.scenes_dir.glob("*.json")
            if not is_temporary(path.name) and _is_safe_id(path.stem)
        )

    def scene_ids(self) -> list[str]:
        return [*self.builtin_scene_ids(), *self.uploaded_scene_ids()]

    def is_builtin(self, scene_id: str) -> bool:
        return scene_id in self.builtin_scene_ids()

    def get_scene(self, scene_id: str) -> Scene | None:
        """The scene with this id, loading it on first use; None if unknown."""
        with self._lock:
            cached = self._scenes.get(scene_id)
        if cached is not None:
            if self.is_builtin(scene_id) or self._meta_file(scene_id).exists():
                return cached
            with self._lock:  # deleted (perhaps by another process) since it was loaded
                self._scenes.pop(scene_id, None)
            return None
        if self.is_builtin(scene_id):
            scene = load_builtin_scene(scene_id, cache_dir=self.cache_dir)
        else:
            scene_file = self.scenes_dir / f"{scene_id}.npz"
            meta_file = self._meta_file(scene_id)
            if not (_is_safe_id(scene_id) and scene_file.exists() and meta_file.exists()):
                return None
            meta = json.loads(meta_file.read_text())
            with np.load(scene_file) as arrays:
                mesh = trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)
            scene = build_scene(
                mesh, scene_id=scene_id, name=str(meta.get("name", "")), cache_dir=self.cache_dir
            )
        with self._lock:
            self._scenes.setdefault(scene_id, scene)
            return self._scenes[scene_id]

    def add_uploaded_scene(self, mesh: trimesh.Trimesh, name: str) -> Scene:
        """Build a scene from an uploaded mesh and persist it atomically; returns the scene.

        The id is a content hash of the mesh, so uploading the same mesh twice gives one id.
        """
        scene = build_scene(mesh, name=name, cache_dir=self.cache_dir)
        existing = self.get_scene(scene.id)
        if existing is not None:
            return existing
        _atomic_write_npz(
            self.scenes_dir / f"{scene.id}.npz",
            vertices=np.asarray(scene.vertices, dtype=np.float64),
            faces=np.asarray(scene.faces, dtype=np.int64),
        )
        try:
            _atomic_write_text(self.scenes_dir / f"{scene.id}.json", json.dumps({"name": name}))
        except BaseException:
            (self.scenes_dir / f"{scene.id}.npz").unlink(missing_ok=True)
            raise
        with self._lock:
            self._scenes[scene.id] = scene
        return scene

    def _meta_file(self, scene_id: str) -> Path:
        return self.scenes_dir / f"{scene_id}.json"

    def delete_uploaded_scene(self, scene_id: str) -> bool:
        """Remove an uploaded scene: its mesh, its metadata and its cached BVH; False if there
        was no such uploaded scene. Built-in scenes are never removed (the caller refuses)."""
        if self.is_builtin(scene_id) or not _is_safe_id(scene_id):
            return False
        meta_file = self._meta_file(scene_id)
        existed = meta_file.exists()
        # The metadata goes first: without it the scene is no longer listed nor loaded.
        meta_file.unlink(missing_ok=True)
        (self.scenes_dir / f"{scene_id}.npz").unlink(missing_ok=True)
        with self._lock:
            scene = self._scenes.pop(scene_id, None)
        # An uploaded scene's id is its content hash, which also keys its BVH cache file.
        content_hash = scene.content_hash if scene is not None else scene_id
        bvh_cache_path(self.cache_dir, content_hash).unlink(missing_ok=True)
        return existed


def default_character_ids() -> list[str]:
    """Built-in characters plus the real robots whose data package is installed."""
    return [*builtin_character_ids(), *real_robot_ids()]


def _is_safe_id(identifier: str) -> bool:
    return identifier.isalnum() and len(identifier) <= 128


def _atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _atomic_write_npz(path: Path, **arrays: np.ndarray) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as handle:
            np.savez(handle, **arrays)  # type: ignore[arg-type]
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
