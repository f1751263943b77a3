"""Offline data: workspaces, COM constraints, sample databases, determinism and the cache."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner.character import (
    Character,
    builtin_character_ids,
    character_spec_path,
    get_character,
    load_character,
    real_robot_ids,
)
from planner.offline import (
    OfflineData,
    OfflineParams,
    build_offline_data,
    load_offline_data,
)
from planner.offline import data as data_module
from planner.offline.build import build_all
from planner.offline.cli import main
from tests.paths import gecko_cache_dir

SMALL = OfflineParams(
    workspace_samples=3000, database_samples=800, com_samples=3000, chunk_size=1500
)


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("offline-cache")


@pytest.fixture(scope="module")
def built(cache_dir: Path) -> dict[str, OfflineData]:
    return {
        cid: load_offline_data(get_character(cid), cache_dir, seed=0, params=SMALL)
        for cid in builtin_character_ids()
    }


def _com_in_effector_frames(character: Character, q: np.ndarray) -> list[np.ndarray]:
    data = character.model.createData()
    pin.framesForwardKinematics(character.model, data, q)
    com = pin.centerOfMass(character.model, data, q)
    out = []
    for limb in character.limbs:
        oMf = data.oMf[limb.frame_id]
        # patch contacts: the effector frame; point contacts: the root frame's axes
        axes = oMf.rotation if limb.contact == "patch" else data.oMi[1].rotation
        out.append(np.asarray(axes).T @ (com - oMf.translation))
    return out


@pytest.mark.parametrize("cid", builtin_character_ids())
def test_workspace_and_com_contain_their_samples(cid: str, built: dict[str, OfflineData]) -> None:
    character = get_character(cid)
    data = built[cid]
    assert data.built
    limbs, com = build_all(character, SMALL, 0)  # the very samples behind the stored hulls
    for i, limb in enumerate(character.limbs):
        ws = data.limb(limb.name).workspace
        positions = limbs[i]["positions"]
        assert len(positions) == SMALL.workspace_samples
        assert np.all(ws.contains(positions, tolerance=1e-7))
        centre = positions.mean(axis=0)
        assert np.all(ws.contains(centre[None]))
        # beyond a boundary point, seen from an interior point, everything is outside
        assert not np.any(ws.contains(centre + 1.2 * (ws.vertices - centre)))
        assert not np.any(ws.contains(centre + np.array([[5.0, 0, 0], [0, 0, -5.0]])))
        con = data.com_constraint(limb.name)
        assert con.sample_count == SMALL.com_samples
        assert np.all(com[:, i] @ con.polytope.A.T <= con.polytope.b + 1e-7)
        com_centre = com[:, i].mean(axis=0)
        outside = com_centre + 1.2 * (con.polytope.vertices - com_centre)
        assert not np.any(con.polytope.contains(outside))
        assert not np.any(con.polytope.contains(np.array([[0.0, 0.0, -3.0], [4.0, 4.0, 4.0]])))


@pytest.mark.parametrize("cid", builtin_character_ids())
def test_reference_com_strictly_inside(cid: str, built: dict[str, OfflineData]) -> None:
    character = get_character(cid)
    data = built[cid]
    for limb, com in zip(
        character.limbs, _com_in_effector_frames(character, character.q_ref), strict=True
    ):
        poly = data.com_constraint(limb.name).polytope
        assert np.max(poly.A @ com - poly.b) < -1e-3


@pytest.mark.parametrize("cid", builtin_character_ids())
def test_database_content(cid: str, built: dict[str, OfflineData]) -> None:
    character = get_character(cid)
    model = character.model
    pdata = model.createData()
    for limb in character.limbs:
        db = built[cid].limb(limb.name).database
        assert len(db) == SMALL.database_samples
        assert np.all(np.diff(db.cost) >= 0)  # ranked: closest to the reference first
        cols = np.asarray(limb.idx_q) - 7
        assert np.all(db.q >= character.lower[cols]) and np.all(db.q <= character.upper[cols])
        assert np.all(built[cid].limb(limb.name).workspace.contains(db.positions, 1e-7))
        for k in (0, len(db) // 2, len(db) - 1):
            q = np.array(character.q_ref)
            q[:7] = [0, 0, 0, 0, 0, 0, 1]
            q[limb.idx_q] = db.q[k]
            pin.framesForwardKinematics(model, pdata, q)
            oMf = pdata.oMf[limb.frame_id]
            np.testing.assert_allclose(db.positions[k], oMf.translation, atol=1e-10)
            np.testing.assert_allclose(db.rotations[k], oMf.rotation, atol=1e-10)
            jac = pin.computeFrameJacobian(model, pdata, q, limb.frame_id, pin.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(db.jacobians[k], jac[:, limb.idx_v], atol=1e-10)


def test_spatial_queries_match_brute_force(built: dict[str, OfflineData]) -> None:
    db = built["humanoid"].limb("left_foot").database
    rng = np.random.default_rng(5)
    for radius in (0.02, 0.07, 0.3):
        points = db.positions[rng.integers(0, len(db), 4)] + rng.normal(0, 0.05, (4, 3))
        got = db.samples_near(points, radius)
        d = np.linalg.norm(db.positions[:, None] - points[None], axis=2).min(axis=1)
        np.testing.assert_array_equal(got, np.nonzero(d <= radius)[0])
    lo, hi = db.positions.min(axis=0), db.positions.max(axis=0)
    for _ in range(5):
        a, b = rng.uniform(lo, hi), rng.uniform(lo, hi)
        low, high = np.minimum(a, b), np.maximum(a, b)
        got = db.samples_in_box(low, high)
        inside = np.all((db.positions >= low) & (db.positions <= high), axis=1)
        np.testing.assert_array_equal(got, np.nonzero(inside)[0])
    assert len(db.samples_near(np.array([[10.0, 10.0, 10.0]]), 0.1)) == 0
    np.testing.assert_array_equal(db.samples_in_box(lo - 1, hi + 1), np.arange(len(db)))


def _arrays(data: OfflineData) -> list[np.ndarray]:
    out = []
    for limb in data.limbs:
        db = limb.database
        out += [
            limb.workspace.A,
            limb.workspace.b,
            limb.workspace.vertices,
            db.q,
            db.positions,
            db.rotations,
            db.jacobians,
            db.cost,
            db.keys,
            db.starts,
            db.order,
        ]
    for con in data.com_constraints:
        out += [con.polytope.A, con.polytope.b, con.polytope.vertices]
    return out


def test_same_seed_same_data() -> None:
    character = get_character("quadruped")
    params = OfflineParams(
        workspace_samples=1500, database_samples=300, com_samples=1500, chunk_size=700
    )
    a = build_offline_data(character, seed=3, params=params)
    b = build_offline_data(character, seed=3, params=params)
    c = build_offline_data(character, seed=4, params=params)
    assert a.cache_key == b.cache_key != c.cache_key
    for x, y in zip(_arrays(a), _arrays(b), strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.limbs[0].database.q, c.limbs[0].database.q)


def test_cache_hit_loads_without_recomputing(
    cache_dir: Path, built: dict[str, OfflineData], monkeypatch: pytest.MonkeyPatch
) -> None:
    def fail(*args: object, **kwargs: object) -> None:
        raise AssertionError("recomputed on a cache hit")

    monkeypatch.setattr(data_module, "build_all", fail)
    for cid in builtin_character_ids():
        start = time.perf_counter()
        loaded = load_offline_data(get_character(cid), cache_dir, seed=0, params=SMALL)
        elapsed = time.perf_counter() - start
        assert not loaded.built
        assert loaded.cache_key == built[cid].cache_key
        print(f"{cid}: cache hit in {elapsed * 1e3:.1f} ms")
        for x, y in zip(_arrays(loaded), _arrays(built[cid]), strict=True):
            np.testing.assert_array_equal(x, y)
    with pytest.raises(FileNotFoundError):
        load_offline_data(
            get_character("quadruped"), cache_dir, seed=99, params=SMALL, build_if_missing=False
        )


def test_changed_urdf_invalidates_cache(tmp_path: Path) -> None:
    src = character_spec_path("quadruped").parent
    copy = tmp_path / "quadruped"
    shutil.copytree(src, copy)
    params = OfflineParams(
        workspace_samples=1000, database_samples=200, com_samples=1000, chunk_size=500
    )
    cache = tmp_path / "cache"
    first = load_offline_data(load_character(copy / "quadruped.yaml"), cache, params=params)
    again = load_offline_data(load_character(copy / "quadruped.yaml"), cache, params=params)
    assert first.built and not again.built
    urdf = copy / "quadruped.urdf"
    text = urdf.read_text()
    assert 'lower="-2.6"' in text
    urdf.write_text(text.replace('lower="-2.6"', 'lower="-2.5"', 1))
    changed = load_offline_data(load_character(copy / "quadruped.yaml"), cache, params=params)
    assert changed.built
    assert changed.cache_key != first.cache_key


@pytest.mark.skipif(not real_robot_ids(), reason="example-robot-data is not installed")
@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_real_robot_offline_data(cid: str, tmp_path: Path) -> None:
    character = get_character(cid)
    params = OfflineParams(
        workspace_samples=1500, database_samples=300, com_samples=1500, chunk_size=1500
    )
    data = load_offline_data(character, tmp_path, params=params)
    assert data.built and len(data.limbs) == len(character.limbs)
    for limb, com in zip(
        character.limbs, _com_in_effector_frames(character, character.q_ref), strict=True
    ):
        poly = data.com_constraint(limb.name).polytope
        assert np.max(poly.A @ com - poly.b) < 0.0
        assert len(data.limb(limb.name).database) == 300


def test_cli_builds_then_hits_cache(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = [
        "--character",
        "quadruped",
        "--cache-dir",
        str(tmp_path),
        "--samples",
        "600",
        "--database-samples",
        "100",
        "--no-progress",
    ]
    assert main(args) == 0
    assert "quadruped: built" in capsys.readouterr().out
    assert main(args) == 0
    assert "quadruped: cached" in capsys.readouterr().out
    assert main(["--character", "dragon", "--cache-dir", str(tmp_path)]) == 2


def test_default_sizes_in_the_shared_cache() -> None:
    """The service's data: production sizes (>= 1e5 samples, >= 1e4 database entries)."""
    character = get_character("humanoid")
    data = load_offline_data(character, gecko_cache_dir())
    assert data.params == OfflineParams()
    for limb in data.limbs:
        assert limb.workspace_sample_count >= 100_000
        assert len(limb.database) >= 10_000
    for con, com in zip(
        data.com_constraints, _com_in_effector_frames(character, character.q_ref), strict=True
    ):
        assert con.sample_count >= 100_000
        assert np.max(con.polytope.A @ com - con.polytope.b) < -1e-3


def test_corrupt_cache_file_is_rebuilt(tmp_path: Path) -> None:
    character = get_character("quadruped")
    params = OfflineParams(workspace_samples=500, database_samples=100, com_samples=500)
    first = load_offline_data(character, tmp_path, params=params)
    assert first.path is not None
    first.path.write_bytes(b"not a zip file")
    again = load_offline_data(character, tmp_path, params=params)
    assert again.built
    assert not load_offline_data(character, tmp_path, params=params).built
