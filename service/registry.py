"""The service's registry: characters with their offline data, built-in and uploaded scenes.

Uploaded scenes are stored in the scenes directory as ``<id>.npz`` (float64 vertices, int64
faces), ``<id>.json`` (name and summary: counts and bounds, so listings never load a scene) and
``<id>.detail.json`` (details with surfaces, as the API answers them); building the scene also
caches its BVH in the cache directory (``<id>-coal<version>.bvh``: the id is the mesh's content
hash), the largest of its files by far (~550 bytes a triangle, some 15 times the mesh file).
All are written to temporary files and renamed into place, metadata last, so a failed upload
leaves nothing behind. Together, BVH included, they are bounded by a quota, and a DELETE
removes them all; in memory, a few recently used ones are kept.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
from planner.scene import (
    Scene,
    build_scene,
    builtin_scene_ids,
    content_hash,
    load_builtin_scene,
)
from planner.scene.collision import bvh_cache_bytes, bvh_cache_path
from planner.scene.io import validate_arrays
from service.files import is_temporary
from service.quota import QuotaExceeded, directory_lock

log = logging.getLogger("gecko.registry")
META_VERSION = 2  # metadata with a stored summary (version 1: the name only)
META_ALLOWANCE_BYTES = 4096  # room kept for a scene's metadata file before it is written
DETAIL_SUFFIX = ".detail.json"  # an uploaded scene's details (surfaces), as GET answers them


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
        max_loaded_scenes: int = 8,
    ) -> None:
        self.cache_dir = cache_dir
        self.scenes_dir = scenes_dir
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        self.scenes_dir.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self.max_loaded_scenes = max_loaded_scenes
        self._builtin: dict[str, Scene] = {}
        self._uploaded: OrderedDict[str, Scene] = OrderedDict()
        self._scene_loads = 0
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
            if not is_temporary(path.name)
            and not path.name.endswith(DETAIL_SUFFIX)
            and _is_safe_id(path.stem)
        )

    def scene_ids(self) -> list[str]:
        return [*self.builtin_scene_ids(), *self.uploaded_scene_ids()]

    def is_builtin(self, scene_id: str) -> bool:
        return scene_id in self.builtin_scene_ids()

    @property
    def scene_loads(self) -> int:
        """Scenes this registry has built (surfaces extracted, BVH loaded or built) so far."""
        return self._scene_loads

    def loaded_scene_ids(self) -> list[str]:
        """Uploaded scenes held in memory now, least recently used first."""
        with self._lock:
            return list(self._uploaded)

    def get_scene(self, scene_id: str) -> Scene | None:
        """The scene with this id, loading it on first use; None if unknown.

        Built-in scenes stay loaded; at most ``max_loaded_scenes`` uploaded ones do, the least
        recently used unloaded first (they load again from disk when asked for).
        """
        builtin = self.is_builtin(scene_id)
        with self._lock:
            cached = self._builtin.get(scene_id) if builtin else self._uploaded.get(scene_id)
            if cached is not None and not builtin:
                self._uploaded.move_to_end(scene_id)
        if cached is not None:
            if builtin or self._meta_file(scene_id).exists():
                return cached
            with self._lock:  # deleted (perhaps by another process) since it was loaded
                self._uploaded.pop(scene_id, None)
            return None
        if builtin:
            scene = load_builtin_scene(scene_id, cache_dir=self.cache_dir)
        else:
            scene_file = self._mesh_file(scene_id)
            meta_file = self._meta_file(scene_id)
            if not (_is_safe_id(scene_id) and scene_file.exists() and meta_file.exists()):
                return None
            meta = json.loads(meta_file.read_text())
            with np.load(scene_file) as arrays:
                mesh = trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)
            scene = build_scene(
                mesh, scene_id=scene_id, name=str(meta.get("name", "")), cache_dir=self.cache_dir
            )
        return self._keep(scene, builtin=builtin)

    def _keep(self, scene: Scene, *, builtin: bool) -> Scene:
        """Hold a freshly built scene (the one already held if another thread was first)."""
        with self._lock:
            self._scene_loads += 1
            if builtin:
                return self._builtin.setdefault(scene.id, scene)
            held = self._uploaded.setdefault(scene.id, scene)
            self._uploaded.move_to_end(scene.id)
            while len(self._uploaded) > self.max_loaded_scenes:
                evicted, _ = self._uploaded.popitem(last=False)
                log.debug("scene %s unloaded (least recently used)", evicted)
            return held

    def scene_mesh(self, scene_id: str) -> tuple[str, np.ndarray, np.ndarray] | None:
        """A scene's name, float64 (n, 3) vertices (metres, world frame) and int64 (m, 3)
        faces; None if unknown. An uploaded scene not loaded is read from its mesh file, not
        loaded (no surfaces, no BVH)."""
        if self.is_builtin(scene_id):
            builtin = self.get_scene(scene_id)
            return None if builtin is None else (builtin.name, builtin.vertices, builtin.faces)
        with self._lock:
            held = self._uploaded.get(scene_id)
        if held is not None and self._meta_file(scene_id).exists():
            return held.name, held.vertices, held.faces
        if not _is_safe_id(scene_id):
            return None
        try:
            meta = json.loads(self._meta_file(scene_id).read_text())
            with np.load(self._mesh_file(scene_id)) as arrays:
                vertices = np.asarray(arrays["vertices"], dtype=np.float64)
                faces = np.asarray(arrays["faces"], dtype=np.int64)
        except FileNotFoundError:
            return None
        return str(meta.get("name", "")), vertices, faces

    def scene_summary(self, scene_id: str) -> StoredSummary | None:
        """An uploaded scene's summary from its stored metadata, without loading the scene;
        None if unknown or stored before summaries were (see :meth:`upgrade_metadata`)."""
        if not _is_safe_id(scene_id):
            return None
        try:
            meta = json.loads(self._meta_file(scene_id).read_text())
        except (OSError, ValueError):
            return None
        return StoredSummary.from_meta(scene_id, meta)

    def upgrade_metadata(self, scene_id: str) -> StoredSummary | None:
        """Load an uploaded scene stored without a summary and store its summary; None if
        unknown. Raises whatever loading a broken stored scene raises."""
        scene = self.get_scene(scene_id)
        if scene is None or self.is_builtin(scene_id):
            return None
        summary = StoredSummary.of(scene)
        _atomic_write_text(self._meta_file(scene_id), json.dumps(summary.to_meta()))
        return summary

    def uploaded_bytes(self) -> int:
        """Bytes the uploaded scenes take on disk: their files in the scenes directory (mesh,
        metadata, details) and their cached BVHs in the cache directory. The temporary files
        of uploads in progress do not count, nor the BVH of a scene not yet listed."""
        total = 0
        for path in self.scenes_dir.iterdir():
            if is_temporary(path.name) or path.suffix not in (".npz", ".json"):
                continue
            total += _size(path)
            scene_id = path.name.removesuffix(".json")
            if path.suffix == ".json" and _is_safe_id(scene_id):  # metadata: a listed scene
                total += _size(bvh_cache_path(self.cache_dir, scene_id))
        return total

    def add_uploaded_scene(
        self,
        mesh: trimesh.Trimesh,
        name: str,
        *,
        quota_bytes: int | None = None,
        describe: Callable[[Scene], str] | None = None,
        keep: bool = True,
    ) -> Scene:
        """Build a scene from an uploaded mesh and persist it atomically; returns the scene.

        The id is a content hash of the mesh, so uploading the same mesh twice gives one id
        (and takes no more room). ``describe(scene)``, when given, is the scene's details
        (JSON text) stored beside it for :meth:`stored_detail`. ``quota_bytes`` bounds
        :meth:`uploaded_bytes` after the write: the mesh file is written and measured, and the
        BVH's size foreseen from the counts (:func:`bvh_cache_bytes`), before surfaces and BVH
        are built; the check is repeated with the files' real sizes, BVH included, under a
        lock shared by every process before the files are renamed into place (a refused
        scene's BVH is removed again). Raises :class:`QuotaExceeded`.
        ``keep=False``: the new scene is not held in memory (a process that only stores).
        """
        vertices, faces = validate_arrays(mesh.vertices, mesh.faces)
        scene_id = content_hash(vertices, faces)
        existing = self.get_scene(scene_id)
        if existing is not None:
            return existing
        mesh_tmp = _temporary_npz(
            self.scenes_dir,
            vertices=np.asarray(vertices, dtype=np.float64),
            faces=np.asarray(faces, dtype=np.int64),
        )
        written = [mesh_tmp]
        try:
            mesh_bytes = mesh_tmp.stat().st_size
            bvh_file = bvh_cache_path(self.cache_dir, scene_id)
            if quota_bytes is not None:
                bvh_bytes = _size(bvh_file) or bvh_cache_bytes(len(faces), len(vertices))
                self._check_quota(quota_bytes, mesh_bytes + META_ALLOWANCE_BYTES + bvh_bytes)
            scene = build_scene(mesh, scene_id=scene_id, name=name, cache_dir=self.cache_dir)
            files = {self._mesh_file(scene_id): mesh_tmp}
            if describe is not None:
                detail_tmp = _temporary_text(self.scenes_dir, describe(scene), ".json")
                written.append(detail_tmp)
                files[self._detail_file(scene_id)] = detail_tmp
            meta_tmp = _temporary_text(
                self.scenes_dir, json.dumps(StoredSummary.of(scene).to_meta()), ".json"
            )
            written.append(meta_tmp)
            # The metadata goes last: with it the scene is listed, and its other files are there.
            files[self._meta_file(scene_id)] = meta_tmp
            with directory_lock(self.scenes_dir):
                if quota_bytes is not None:
                    adding = sum(_size(path) for path in (*written, bvh_file))
                    try:
                        self._check_quota(quota_bytes, adding)
                    except QuotaExceeded:
                        bvh_file.unlink(missing_ok=True)
                        raise
                for final, temporary in files.items():
                    os.replace(temporary, final)
        finally:
            for temporary in written:
                temporary.unlink(missing_ok=True)
        if not keep:
            with self._lock:
                self._scene_loads += 1
            return scene
        return self._keep(scene, builtin=False)

    def stored_detail(self, scene_id: str) -> str | None:
        """An uploaded scene's details as stored at upload (JSON text); None if unknown or
        stored without them."""
        if self.is_builtin(scene_id) or not _is_safe_id(scene_id):
            return None
        if not self._meta_file(scene_id).exists():
            return None
        try:
            return self._detail_file(scene_id).read_text()
        except OSError:
            return None

    def store_detail(self, scene_id: str, text: str) -> None:
        """Store the details (JSON text) of an uploaded scene stored without them."""
        if _is_safe_id(scene_id) and self._meta_file(scene_id).exists():
            _atomic_write_text(self._detail_file(scene_id), text)

    def _check_quota(self, quota_bytes: int, adding: int) -> None:
        used = self.uploaded_bytes()
        if used + adding > quota_bytes:
            raise QuotaExceeded(
                store="uploaded scenes", used=used, adding=adding, quota=quota_bytes
            )

    def _meta_file(self, scene_id: str) -> Path:
        return self.scenes_dir / f"{scene_id}.json"

    def _mesh_file(self, scene_id: str) -> Path:
        return self.scenes_dir / f"{scene_id}.npz"

    def _detail_file(self, scene_id: str) -> Path:
        return self.scenes_dir / f"{scene_id}{DETAIL_SUFFIX}"

    def delete_uploaded_scene(self, scene_id: str) -> bool:
        """Remove an uploaded scene: its mesh, its metadata, its cached BVH and its place in
        memory; False if there was no such uploaded scene. Built-in scenes are never removed
        (the caller refuses). Other processes drop their copy when they next ask for it."""
        if self.is_builtin(scene_id) or not _is_safe_id(scene_id):
            return False
        meta_file = self._meta_file(scene_id)
        with directory_lock(self.scenes_dir):
            existed = meta_file.exists()
            # The metadata goes first: without it the scene is no longer listed nor loaded.
            meta_file.unlink(missing_ok=True)
            self._mesh_file(scene_id).unlink(missing_ok=True)
            self._detail_file(scene_id).unlink(missing_ok=True)
        with self._lock:
            scene = self._uploaded.pop(scene_id, None)
        # An uploaded scene's id is its content hash, which also keys its BVH cache file.
        content_hash = scene.content_hash if scene is not None else scene_id
        bvh_cache_path(self.cache_dir, content_hash).unlink(missing_ok=True)
        return existed


@dataclass(frozen=True, slots=True)
class StoredSummary:
    """What a listing shows of a scene, stored in an uploaded scene's metadata.

    bounds : ((3,), (3,)) axis-aligned min and max corners, metres, world frame.
    """

    name: str
    triangle_count: int
    vertex_count: int
    surface_count: int
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]

    @classmethod
    def of(cls, scene: Scene) -> StoredSummary:
        low, high = (tuple(float(x) for x in corner) for corner in scene.bounds)
        return cls(
            name=scene.name,
            triangle_count=int(scene.triangle_count),
            vertex_count=len(scene.vertices),
            surface_count=len(scene.surfaces),
            bounds=(low, high),  # type: ignore[arg-type]
        )

    def to_meta(self) -> dict[str, Any]:
        """The metadata file's content (JSON-ready)."""
        return {
            "version": META_VERSION,
            "name": self.name,
            "triangle_count": self.triangle_count,
            "vertex_count": self.vertex_count,
            "surface_count": self.surface_count,
            "bounds": [list(self.bounds[0]), list(self.bounds[1])],
        }

    @classmethod
    def from_meta(cls, scene_id: str, meta: object) -> StoredSummary | None:
        """The summary stored in ``meta``; None for metadata older than summaries."""
        if not isinstance(meta, dict) or meta.get("version") != META_VERSION:
            return None
        try:
            low, high = ([float(x) for x in corner] for corner in meta["bounds"])
            return cls(
                name=str(meta["name"]),
                triangle_count=int(meta["triangle_count"]),
                vertex_count=int(meta["vertex_count"]),
                surface_count=int(meta["surface_count"]),
                bounds=((low[0], low[1], low[2]), (high[0], high[1], high[2])),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            log.warning("metadata of scene %s is unreadable: %r", scene_id, exc)
            return None


def default_character_ids() -> list[str]:
    """Built-in characters plus the real robots whose data package is installed."""
    return [*builtin_character_ids(), *real_robot_ids()]


def _is_safe_id(identifier: str) -> bool:
    return identifier.isalnum() and len(identifier) <= 128


def _size(path: Path) -> int:
    """A file's size in bytes; 0 when it is not there (never written, or removed meanwhile)."""
    try:
        return path.stat().st_size
    except OSError:
        return 0


def _temporary_text(directory: Path, text: str, suffix: str) -> Path:
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=suffix)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def _temporary_npz(directory: Path, **arrays: np.ndarray) -> Path:
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as handle:
            np.savez(handle, **arrays)  # type: ignore[arg-type]
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def _atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
