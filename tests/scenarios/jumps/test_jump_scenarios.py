"""Jump scenarios: every jump obeys the physics, the bounds and the scene; keyframes follow the
parabola and hold the contacts; answers are reproducible and survive a roadmap save/load."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from planner.ballistic.arc import arc_length, slerp
from planner.ballistic.keyframes import LimbCollider
from planner.ballistic.planner import JumpPlan, RoadmapStore, plan_jumps
from planner.ballistic.roadmap import Roadmap
from planner.ballistic.steering import jump_at
from planner.kinematics import frame_placement
from planner.poses import quaternion_to_matrix
from planner.result import PlanResult, PlanStatus
from tests.scenarios.jumps.scenario import Scenario, scenarios

G = np.array([0.0, 0.0, -9.81])
SCENARIOS = {s.name: s for s in scenarios()}


@cache
def _loaded(name: str) -> tuple[object, ...] | None:
    return SCENARIOS[name].load()


@cache
def _planned(name: str) -> PlanResult[JumpPlan]:
    scenario = SCENARIOS[name]
    loaded = _loaded(name)
    assert loaded is not None
    scene, character, data = loaded
    return plan_jumps(
        scene,  # type: ignore[arg-type]
        character,  # type: ignore[arg-type]
        data,  # type: ignore[arg-type]
        scenario.end("start"),
        scenario.end("goal"),
        rng=np.random.default_rng(scenario.seed),
        params=scenario.params(),
    )


def _plan(name: str) -> JumpPlan:
    if _loaded(name) is None:
        pytest.skip(f"scene of {name} not installed (hpp-environments)")
    result = _planned(name)
    assert result.status is PlanStatus.SOLVED, result.message
    assert result.value is not None
    return result.value


def _in_cone(v: np.ndarray, axis: np.ndarray, mu: float) -> bool:
    cos = float(v @ axis) / (np.linalg.norm(v) * np.linalg.norm(axis))
    return bool(cos >= np.cos(np.arctan(mu)) - 1e-9)


NAMES = sorted(SCENARIOS)


def test_scenarios_exist() -> None:
    kinds = {(s.spec["scene"]["name"], s.spec["character"]) for s in SCENARIOS.values()}
    for character in ("humanoid", "quadruped", "hexapod"):
        assert ("gaps", character) in kinds
    names = {s.spec["scene"]["name"] for s in SCENARIOS.values()}
    assert {"pond", "rooftops"} <= names
    assert any(s.spec["scene"]["kind"] == "hpp" for s in SCENARIOS.values())


@pytest.mark.parametrize("name", NAMES)
def test_jumps_physics_and_bounds(name: str) -> None:
    plan = _plan(name)
    params = SCENARIOS[name].params().roadmap
    assert len(plan.jumps) >= 1
    for jump in plan.jumps:
        p0, v0, big_t = jump.takeoff.position, jump.takeoff.velocity, jump.duration
        landed = p0 + v0 * big_t + 0.5 * G * big_t**2
        assert np.linalg.norm(landed - jump.landing.position) <= 1e-3
        assert np.allclose(v0 + G * big_t, jump.landing.velocity, atol=1e-9)
        assert _in_cone(v0, jump.takeoff.cone_axis, jump.takeoff.cone_mu)
        assert _in_cone(-jump.landing.velocity, jump.landing.cone_axis, jump.landing.cone_mu)
        assert np.linalg.norm(v0) <= params.v0max * (1 + 1e-9)
        assert np.linalg.norm(jump.landing.velocity) <= params.vimpmax * (1 + 1e-9)
        assert jump.takeoff.contacts and jump.landing.contacts
        # The cone comes from the contacts reported.
        normals = np.array([c.normal for c in jump.takeoff.contacts])
        axis = normals.sum(axis=0) / np.linalg.norm(normals.sum(axis=0))
        assert np.allclose(axis, jump.takeoff.cone_axis, atol=1e-9)
        assert jump.takeoff.cone_mu == min(c.mu for c in jump.takeoff.contacts)


@pytest.mark.parametrize("name", NAMES)
def test_trunk_free_along_arcs_dense(name: str) -> None:
    """The nominal (uninflated) trunk is free every 5 mm of arc, independently of the planner."""
    plan = _plan(name)
    loaded = _loaded(name)
    assert loaded is not None
    scene, character, _ = loaded
    path = plan.path
    for i, jump in enumerate(plan.jumps):
        arc = jump_at(jump.takeoff.position, jump.landing.position, float(path.t[i]))
        length = float(arc_length(arc.xdot, arc.v0[2], arc.duration))
        tau = np.linspace(0.0, arc.duration, max(3, int(np.ceil(length / 0.005)) + 1))
        poses = np.zeros((len(tau), 4, 4))
        poses[:, :3, :3] = quaternion_to_matrix(
            slerp(path.orientations[i], path.orientations[i + 1], tau / arc.duration)
        )
        poses[:, :3, 3] = arc.position(tau)
        poses[:, 3, 3] = 1.0
        for shape in character.trunk:  # type: ignore[attr-defined]
            assert not scene.collision.collides_many(shape, poses).any()  # type: ignore[attr-defined]


@pytest.mark.parametrize("name", NAMES)
def test_keyframes_follow_parabola_and_hold_contacts(name: str) -> None:
    plan = _plan(name)
    loaded = _loaded(name)
    assert loaded is not None
    _, character, _ = loaded
    model = character.model  # type: ignore[attr-defined]
    times = np.array([k.t for k in plan.keyframes])
    assert np.all(np.diff(times) > 0)
    assert times[0] == 0.0
    assert times[-1] == pytest.approx(sum(j.duration for j in plan.jumps), abs=1e-9)
    for jump in plan.jumps:
        t_end = jump.t_start + jump.duration
        assert jump.t_start <= jump.contact_break < jump.contact_create <= t_end
        inside = [k for k in plan.keyframes if jump.t_start - 1e-12 <= k.t <= t_end + 1e-12]
        assert len(inside) >= 5
        for frame in inside:
            tau = frame.t - jump.t_start
            expect = jump.takeoff.position + jump.takeoff.velocity * tau + 0.5 * G * tau**2
            assert np.linalg.norm(frame.q[:3] - expect) <= 1e-6
            holding = []
            if frame.t <= jump.contact_break + 1e-12:
                holding = list(jump.takeoff.contacts)
            elif frame.t >= jump.contact_create - 1e-12:
                holding = list(jump.landing.contacts)
            else:
                assert frame.contacts == ()
            assert set(frame.contacts) == {c.limb for c in holding}
            for contact in holding:
                limb = character.limb(contact.limb)  # type: ignore[attr-defined]
                pose = frame_placement(model, frame.q, limb.effector_frame)
                point = pose[:3, :3] @ limb.offset + pose[:3, 3]
                assert np.linalg.norm(point - contact.point) <= 0.01, (contact.limb, frame.t)


@pytest.mark.parametrize("name", NAMES)
def test_flight_limbs_mostly_free(name: str) -> None:
    """Colliding limbs are re-sampled; the frames left colliding are few and reported."""
    plan = _plan(name)
    loaded = _loaded(name)
    assert loaded is not None
    scene, character, _ = loaded
    checker = LimbCollider(character, scene)  # type: ignore[arg-type]
    flight = [k for k in plan.keyframes if not k.contacts]
    left = sum(bool(checker.colliding(k.q).any()) for k in flight)
    assert left == sum(j.limb_collisions for j in plan.jumps)
    assert left <= 0.05 * len(flight)


def _same(a: JumpPlan, b: JumpPlan) -> None:
    assert len(a.jumps) == len(b.jumps)
    for x, y in zip(a.jumps, b.jumps, strict=True):
        assert np.array_equal(x.takeoff.position, y.takeoff.position)
        assert np.array_equal(x.takeoff.velocity, y.takeoff.velocity)
        assert x.duration == y.duration
        assert [c.limb for c in x.takeoff.contacts] == [c.limb for c in y.takeoff.contacts]
    assert len(a.keyframes) == len(b.keyframes)
    for x, y in zip(a.keyframes, b.keyframes, strict=True):
        assert x.t == y.t and np.array_equal(x.q, y.q) and x.contacts == y.contacts
    assert np.array_equal(a.path.nodes, b.path.nodes)


def test_same_seed_same_answer() -> None:
    name = "gaps_hexapod"
    first = _plan(name)
    scenario = SCENARIOS[name]
    loaded = _loaded(name)
    assert loaded is not None
    scene, character, data = loaded
    again = plan_jumps(
        scene,  # type: ignore[arg-type]
        character,  # type: ignore[arg-type]
        data,  # type: ignore[arg-type]
        scenario.end("start"),
        scenario.end("goal"),
        rng=np.random.default_rng(scenario.seed),
        params=scenario.params(),
    )
    assert again.value is not None
    _same(first, again.value)


@pytest.mark.parametrize("name", ["gaps_quadruped", "pond_quadruped"])
def test_saved_roadmap_answers_identically(name: str, tmp_path: Path) -> None:
    plan = _plan(name)
    scenario = SCENARIOS[name]
    loaded = _loaded(name)
    assert loaded is not None
    scene, character, data = loaded
    plan.roadmap.save(tmp_path / "roadmap.npz")
    reloaded = Roadmap.load(tmp_path / "roadmap.npz", expected=plan.roadmap.params)

    def run(roadmap: Roadmap) -> JumpPlan:
        result = plan_jumps(
            scene,  # type: ignore[arg-type]
            character,  # type: ignore[arg-type]
            data,  # type: ignore[arg-type]
            scenario.end("start"),
            scenario.end("goal"),
            rng=np.random.default_rng(scenario.seed),
            roadmap=roadmap,
            params=scenario.params(),
        )
        assert result.value is not None
        return result.value

    _same(run(plan.roadmap), run(reloaded))


def test_roadmap_store(tmp_path: Path) -> None:
    scenario: Scenario = SCENARIOS["hpp_ground_jump_easy_hexapod"]
    if _loaded(scenario.name) is None:
        pytest.skip("hpp-environments not installed")
    scene, character, data = _loaded(scenario.name)  # type: ignore[misc]
    params = scenario.params()
    store = RoadmapStore(tmp_path)
    seen: list[float] = []
    rid = store.build(scene, character, data, params, 60, seed=3, progress=seen.append)
    assert store.exists(rid) and seen[-1] == 1.0
    info = store.info(rid)
    assert info is not None and info["status"] == "ready" and info["nodes"] == 60
    assert info["bytes"] > 0
    # A new store on the same directory (a restart) finds it; same inputs give the same id.
    again = RoadmapStore(tmp_path)
    assert again.build(scene, character, data, params, 60, seed=3) == rid
    assert again.load(rid).params == store.load(rid).params
    assert RoadmapStore.roadmap_id(scene, character, data, params, 60, 4) != rid
    assert not list(tmp_path.glob("*.tmp"))
    assert store.params(rid) == params
    # The endpoint's path: load roadmap and parameters by id, then plan on them.
    result = plan_jumps(
        scene,
        character,
        data,
        scenario.end("start"),
        scenario.end("goal"),
        rng=np.random.default_rng(0),
        roadmap=store.load(rid),
        params=store.params(rid),
    )
    assert result.status in (PlanStatus.SOLVED, PlanStatus.INFEASIBLE)
    assert store.info("0" * 24) is None
