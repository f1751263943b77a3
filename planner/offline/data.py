"""Offline data of a character: values, on-disk cache (one .npz, no pickle) and loading.

The cache key hashes everything the data depends on: the URDF text, the spec text, the
character's collision shapes, the parameters, the seed and :data:`CODE_VERSION` (bump it
whenever the computation changes).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.character.model import Character
from planner.offline.build import OfflineParams, build_all
from planner.offline.database import SampleDatabase
from planner.shapes import ConvexPolytope

CODE_VERSION = "offline-4"
"""Version of the offline computation; part of the cache key (3: capsule-mode shapes end at
their tip frames, patch effectors carry a contact plate; 4: the self-collision test of the
samples measures a capsule against a sphere (a foot) to the capsule's nearest point, not to
its first end, and drops the postures where they overlap)."""

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class LimbOfflineData:
    """One limb's offline data, root frame.

    workspace : Wk, convex hull of ``workspace_sample_count`` collision-free effector frame
    origins (m). database : ranked, voxel-indexed sample database.
    """

    name: str
    workspace: ConvexPolytope
    workspace_sample_count: int
    database: SampleDatabase


@dataclass(frozen=True, slots=True)
class ComConstraint:
    """Kinematic COM constraint of one effector (2PAC Eq. 3), in the effector frame.

    polytope : convex hull of the COM of ``sample_count`` collision-free whole-body samples,
    ``polytope.A @ c <= polytope.b`` (m).
    """

    limb: str
    effector_frame: str
    polytope: ConvexPolytope
    sample_count: int


@dataclass(frozen=True, slots=True)
class OfflineData:
    """Everything computed offline for a character. ``built`` is True when computed by the
    call that returned it, False when loaded from the cache."""

    character_id: str
    cache_key: str
    seed: int
    params: OfflineParams
    limbs: tuple[LimbOfflineData, ...]
    com_constraints: tuple[ComConstraint, ...]
    built: bool
    path: Path | None

    def limb(self, name: str) -> LimbOfflineData:
        """Data of the limb called ``name``; KeyError if absent."""
        for limb in self.limbs:
            if limb.name == name:
                return limb
        raise KeyError(f"no limb {name!r} in the offline data of {self.character_id!r}")

    def com_constraint(self, limb: str) -> ComConstraint:
        """COM constraint of the effector of limb ``limb``; KeyError if absent."""
        for con in self.com_constraints:
            if con.limb == limb:
                return con
        raise KeyError(f"no COM constraint for limb {limb!r}")


def default_cache_dir() -> Path:
    """``$GECKO_CACHE_DIR`` or ``~/.cache/gecko/offline``."""
    env = os.environ.get("GECKO_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "gecko" / "offline"


def cache_key(character: Character, params: OfflineParams, seed: int) -> str:
    """Hex SHA-256 of the inputs of the offline data."""
    payload = json.dumps(
        {
            "code": CODE_VERSION,
            "id": character.id,
            "urdf": character.urdf_text,
            "spec": character.spec_text,
            "geometry": _geometry_digest(character),
            "params": params.as_dict(),
            "seed": int(seed),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()


def _geometry_digest(character: Character) -> str:
    """Hex SHA-256 of the character's collision shapes (names, joints, placements, sizes):
    the limb databases are filtered by self-collision, so the data depends on them."""
    digest = hashlib.sha256()
    for obj in character.geometry.geometryObjects:
        geometry = obj.geometry
        sizes = [
            getattr(geometry, name)
            for name in ("radius", "halfLength", "halfSide")
            if hasattr(geometry, name)
        ]
        placement = np.asarray(obj.placement.homogeneous, dtype=np.float64)
        digest.update(
            f"{obj.name}|{int(obj.parentJoint)}|{type(geometry).__name__}|".encode()
            + np.round(placement, 9).tobytes()
            + np.round(np.hstack([np.ravel(v) for v in sizes] or [np.zeros(1)]), 9).tobytes()
        )
    return digest.hexdigest()


def cache_path(character: Character, cache_dir: Path, key: str) -> Path:
    """File of the cached data: ``<cache_dir>/<id>-<key[:16]>.npz``."""
    return Path(cache_dir) / f"{character.id}-{key[:16]}.npz"


def _arrays(
    character: Character,
    params: OfflineParams,
    seed: int,
    key: str,
    progress: Callable[[int], object] | None,
) -> dict[str, NDArray[Any]]:
    limbs, com = build_all(character, params, seed, progress)
    out: dict[str, NDArray[Any]] = {"cache_key": np.array(key)}
    for i, arrays in enumerate(limbs):
        hull = ConvexPolytope.from_points(arrays["positions"])
        out[f"limb{i}_ws_vertices"] = hull.vertices
        out[f"limb{i}_ws_A"] = hull.A
        out[f"limb{i}_ws_b"] = hull.b
        out[f"limb{i}_ws_count"] = np.array(len(arrays["positions"]))
        db = SampleDatabase.build(
            arrays["db_q"],
            arrays["db_positions"],
            arrays["db_rotations"],
            arrays["db_jacobians"],
            arrays["db_cost"],
            params.voxel_size,
        )
        out[f"limb{i}_db_q"] = db.q
        out[f"limb{i}_db_positions"] = db.positions
        out[f"limb{i}_db_rotations"] = db.rotations
        out[f"limb{i}_db_jacobians"] = db.jacobians
        out[f"limb{i}_db_cost"] = db.cost
        hull = ConvexPolytope.from_points(com[:, i])
        out[f"limb{i}_com_vertices"] = hull.vertices
        out[f"limb{i}_com_A"] = hull.A
        out[f"limb{i}_com_b"] = hull.b
        out[f"limb{i}_com_count"] = np.array(len(com))
    return out


def _from_arrays(
    character: Character,
    arrays: Any,
    params: OfflineParams,
    seed: int,
    key: str,
    built: bool,
    path: Path | None,
) -> OfflineData:
    limbs = []
    coms = []
    for i, limb in enumerate(character.limbs):
        ws = ConvexPolytope(
            arrays[f"limb{i}_ws_vertices"], arrays[f"limb{i}_ws_A"], arrays[f"limb{i}_ws_b"]
        )
        db = SampleDatabase.build(
            arrays[f"limb{i}_db_q"],
            arrays[f"limb{i}_db_positions"],
            arrays[f"limb{i}_db_rotations"],
            arrays[f"limb{i}_db_jacobians"],
            arrays[f"limb{i}_db_cost"],
            params.voxel_size,
            presorted=True,
        )
        limbs.append(LimbOfflineData(limb.name, ws, int(arrays[f"limb{i}_ws_count"]), db))
        com = ConvexPolytope(
            arrays[f"limb{i}_com_vertices"], arrays[f"limb{i}_com_A"], arrays[f"limb{i}_com_b"]
        )
        coms.append(
            ComConstraint(limb.name, limb.effector_frame, com, int(arrays[f"limb{i}_com_count"]))
        )
    return OfflineData(character.id, key, seed, params, tuple(limbs), tuple(coms), built, path)


def build_offline_data(
    character: Character,
    seed: int = 0,
    params: OfflineParams | None = None,
    progress: Callable[[int], object] | None = None,
) -> OfflineData:
    """Compute the offline data without touching the cache (``built`` True, ``path`` None)."""
    params = params or OfflineParams()
    key = cache_key(character, params, seed)
    arrays = _arrays(character, params, seed, key, progress)
    return _from_arrays(character, arrays, params, seed, key, True, None)


def total_samples(character: Character, params: OfflineParams) -> int:
    """Number of collision-free samples a build draws (progress-bar total)."""
    return len(character.limbs) * params.workspace_samples + params.com_samples


def load_offline_data(
    character: Character,
    cache_dir: str | Path | None = None,
    seed: int = 0,
    params: OfflineParams | None = None,
    build_if_missing: bool = True,
    progress: bool = False,
) -> OfflineData:
    """The character's offline data from ``cache_dir`` (default :func:`default_cache_dir`),
    built and saved first when missing.

    Raises FileNotFoundError when missing and ``build_if_missing`` is False.
    """
    params = params or OfflineParams()
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = cache_key(character, params, seed)
    path = cache_path(character, directory, key)
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as stored:
                if str(stored["cache_key"]) == key:
                    arrays = {name: stored[name] for name in stored.files}
                    return _from_arrays(character, arrays, params, seed, key, False, path)
        except (OSError, ValueError, KeyError, zipfile.BadZipFile):
            pass  # unreadable or truncated file: rebuild and overwrite it
    if not build_if_missing:
        raise FileNotFoundError(f"no offline data for {character.id!r} in {directory}")
    bar: Any = None
    update: Callable[[int], object] | None = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total_samples(character, params), desc=character.id, unit="sample")
        update = bar.update
    try:
        arrays = _arrays(character, params, seed, key, update)
    finally:
        if bar is not None:
            bar.close()
    directory.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, suffix=".npz.tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            np.savez(handle, allow_pickle=False, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return _from_arrays(character, arrays, params, seed, key, True, path)
