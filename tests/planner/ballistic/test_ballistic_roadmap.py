"""Jump roadmap: invariants of every edge and path, persistence, directedness, statuses."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from planner.ballistic.roadmap import (
    GOAL,
    START,
    Connection,
    EdgeStatus,
    Roadmap,
    RoadmapNodes,
    RoadmapParams,
    build_roadmap,
    query_roadmap,
)
from planner.ballistic.steering import jump_at, verify_jumps
from planner.ballistic.synthetic import BoxWorld, Platforms, PlatformSampler
from planner.result import PlanStatus
from tests.planner.ballistic.ballistic_helpers import GAP, dense_collides, gap_scene

PARAMS = RoadmapParams(
    v0max=5.5,
    vimpmax=8.0,
    connection=Connection.RADIUS,
    neighbours=24,
    max_gap=GAP,
    scene_key="three-platforms",
)


def node(x: float, y: float, z: float) -> RoadmapNodes:
    return RoadmapNodes.single([x, y, z], [0, 0, 0, 1], [0, 0, 1], 1.0)


def build(
    params: RoadmapParams = PARAMS, n: int = 160, seed: int = 5, world: BoxWorld | None = None
) -> Roadmap:
    plat, nominal = gap_scene()
    checker = (world or nominal).inflated(GAP)
    res = build_roadmap(
        PlatformSampler(plat, root_height=0.4, mu=1.0, margin=0.15),
        n,
        params,
        rng=np.random.default_rng(seed),
        collides_many=checker,
    )
    assert res.status is PlanStatus.SOLVED and res.value is not None
    return res.value


@pytest.fixture(scope="module")
def roadmap() -> Roadmap:
    return build()


def test_every_edge_is_a_valid_free_jump(roadmap: Roadmap) -> None:
    _, world = gap_scene()
    nodes, edges = roadmap.nodes, roadmap.edges
    assert len(nodes) == 160 and len(edges) > 500
    assert np.all(edges.status == EdgeStatus.VALID)
    assert np.all(edges.src != edges.dst)
    pairs = edges.src * len(nodes) + edges.dst
    assert len(np.unique(pairs)) == len(pairs)
    p, ax, mu = nodes.positions, nodes.cone_axes, nodes.mus
    assert np.all(
        verify_jumps(
            p[edges.src],
            p[edges.dst],
            edges.t,
            ax[edges.src],
            mu[edges.src],
            ax[edges.dst],
            mu[edges.dst],
            v0max=PARAMS.v0max,
            vimpmax=PARAMS.vimpmax,
        )
    )
    assert np.all((edges.t >= edges.t_lo) & (edges.t <= edges.t_hi))
    rng = np.random.default_rng(0)
    q = nodes.orientations
    for e in rng.choice(len(edges), size=60, replace=False):
        jump = jump_at(p[edges.src[e]], p[edges.dst[e]], float(edges.t[e]))
        assert jump.duration == pytest.approx(edges.duration[e])
        assert not dense_collides(jump, q[edges.src[e]], q[edges.dst[e]], world)
    # Jumps between platforms exist (the pieces are 1 m apart).
    platform = np.digitize(p[:, 0], [2.5, 5.5])
    assert np.any(platform[edges.src] != platform[edges.dst])


def test_query_returns_a_valid_jump_sequence(roadmap: Roadmap) -> None:
    _, world = gap_scene()
    start, goal = node(0.5, 1.0, 0.4), node(7.5, 1.0, 0.4)
    res = roadmap.query(start, goal, collides_many=world.inflated(GAP))
    assert res.status is PlanStatus.SOLVED and res.value is not None
    path = res.value
    assert path.nodes[0] == START and path.nodes[-1] == GOAL and len(path) >= 2
    assert np.allclose(path.positions[0], start.positions[0])
    assert np.allclose(path.positions[-1], goal.positions[0])
    for k, jump in enumerate(path.jumps()):
        tau = jump.duration
        landed = jump.p0 + jump.v0 * tau + 0.5 * np.array([0, 0, -9.81]) * tau**2
        assert np.linalg.norm(landed - path.positions[k + 1]) <= 1e-3
        assert np.linalg.norm(jump.v0) <= PARAMS.v0max * (1 + 1e-9)
        assert np.linalg.norm(jump.vimp) <= PARAMS.vimpmax * (1 + 1e-9)
        assert jump.v0[2] / np.linalg.norm(jump.v0) >= np.cos(np.arctan(1.0)) - 1e-9
        assert -jump.vimp[2] / np.linalg.norm(jump.vimp) >= np.cos(np.arctan(1.0)) - 1e-9
        assert not dense_collides(jump, path.orientations[k], path.orientations[k + 1], world)
    assert path.cost == pytest.approx(float(path.duration.sum()))


def test_a_node_whose_stance_is_refused_is_routed_around(roadmap: Roadmap) -> None:
    """``node_clear`` vetoes nodes (a whole-body stance that collides where only the trunk
    was checked): the path avoids every refused node, each node is asked once, and the
    answer is a valid path all the same."""
    _, world = gap_scene()
    start, goal = node(0.5, 1.0, 0.4), node(7.5, 1.0, 0.4)
    first = roadmap.query(start, goal, collides_many=world.inflated(GAP)).value
    assert first is not None
    vetoed = {int(k) for k in first.nodes[1:-1]}
    asked: list[int] = []

    def clear(i: int) -> bool:
        asked.append(i)
        return i not in vetoed

    res = roadmap.query(start, goal, collides_many=world.inflated(GAP), node_clear=clear)
    assert res.status is PlanStatus.SOLVED and res.value is not None
    assert not vetoed & {int(k) for k in res.value.nodes[1:-1]}
    assert res.stats["nodes_refused"] == len(vetoed)
    assert len(asked) == len(set(asked))
    assert START not in asked and GOAL not in asked
    nothing = roadmap.query(
        start, goal, collides_many=world.inflated(GAP), node_clear=lambda i: False
    )
    assert nothing.status is PlanStatus.INFEASIBLE


def test_refused_jumps_are_left_out(roadmap: Roadmap) -> None:
    """``refused`` jumps (node label pairs, START and GOAL among them) never appear in the
    answer, which is still a valid path; refusing every jump of each answer in turn ends in
    INFEASIBLE, not in a loop."""
    _, world = gap_scene()
    start, goal = node(0.5, 1.0, 0.4), node(7.5, 1.0, 0.4)
    first = roadmap.query(start, goal, collides_many=world.inflated(GAP)).value
    assert first is not None
    refused = [(int(first.nodes[0]), int(first.nodes[1]))]  # the jump from START
    second = roadmap.query(start, goal, collides_many=world.inflated(GAP), refused=refused).value
    assert second is not None and second.nodes[0] == START and second.nodes[-1] == GOAL
    jumps = set(zip(second.nodes[:-1].tolist(), second.nodes[1:].tolist(), strict=True))
    assert not jumps & set(refused)
    for jump in second.jumps():
        assert np.linalg.norm(jump.v0) <= PARAMS.v0max * (1 + 1e-9)
    refused = []
    for _ in range(200):
        res = roadmap.query(start, goal, collides_many=world.inflated(GAP), refused=refused)
        if res.value is None:
            assert res.status is PlanStatus.INFEASIBLE
            break
        path = res.value.nodes.tolist()
        refused += list(itertools.pairwise(path))
    else:
        pytest.fail("refusing every jump found never ran out of paths")


def test_save_load_answers_identically(roadmap: Roadmap, tmp_path: Path) -> None:
    _, world = gap_scene()
    file = tmp_path / "roadmap.npz"
    roadmap.save(file)
    loaded = Roadmap.load(file, expected=PARAMS)
    assert loaded.digest == roadmap.digest
    for name in ("src", "dst", "t", "cost", "status"):
        assert np.array_equal(getattr(loaded.edges, name), getattr(roadmap.edges, name))
    assert np.array_equal(
        loaded.nodes.contacts["support_point"], roadmap.nodes.contacts["support_point"]
    )
    start, goal = node(0.5, 1.0, 0.4), node(7.5, 1.0, 0.4)
    a = roadmap.query(start, goal, collides_many=world.inflated(GAP))
    b = loaded.query(start, goal, collides_many=world.inflated(GAP))
    assert a.status is b.status is PlanStatus.SOLVED
    assert a.value is not None and b.value is not None
    assert np.array_equal(a.value.nodes, b.value.nodes)
    assert np.array_equal(a.value.t, b.value.t)
    assert a.value.cost == b.value.cost
    with pytest.raises(ValueError, match="different parameters"):
        Roadmap.load(file, expected=RoadmapParams(v0max=6.0, vimpmax=8.0))


def test_load_rejects_foreign_files(tmp_path: Path) -> None:
    bogus = tmp_path / "bogus.npz"
    np.savez(bogus, x=np.zeros(3))
    with pytest.raises(ValueError, match="not a"):
        Roadmap.load(bogus)


def test_build_is_deterministic() -> None:
    a, b = build(n=60, seed=9), build(n=60, seed=9)
    assert np.array_equal(a.nodes.positions, b.nodes.positions)
    assert np.array_equal(a.edges.src, b.edges.src) and np.array_equal(a.edges.t, b.edges.t)


def test_directed_edges_under_asymmetric_bounds() -> None:
    # Low takeoff bound, high landing bound: down from the raised middle platform is easy,
    # up onto it is not.
    params = RoadmapParams(
        v0max=4.0, vimpmax=9.0, connection=Connection.RADIUS, neighbours=40, max_gap=GAP
    )
    rm = build(params, n=150, seed=3)
    z = rm.nodes.positions[:, 2]
    up = z[rm.edges.dst] > z[rm.edges.src] + 0.3
    down = z[rm.edges.dst] < z[rm.edges.src] - 0.3
    assert down.sum() > 5 * max(1, up.sum())
    pairs = set(zip(rm.edges.src.tolist(), rm.edges.dst.tolist(), strict=True))
    one_way = [(i, j) for i, j in pairs if (j, i) not in pairs]
    assert len(one_way) > 0


def test_lazy_roadmap_checks_along_the_path() -> None:
    _, world = gap_scene()
    params = RoadmapParams(
        v0max=5.5, vimpmax=8.0, connection=Connection.RADIUS, neighbours=24, max_gap=GAP, lazy=True
    )
    rm = build(params, n=120, seed=2)
    assert np.all(rm.edges.status == EdgeStatus.UNKNOWN)
    start, goal = node(0.5, 1.0, 0.4), node(7.5, 1.0, 0.4)
    res = query_roadmap(rm, start, goal, collides_many=world.inflated(GAP))
    assert res.status is PlanStatus.SOLVED and res.value is not None
    for k, jump in enumerate(res.value.jumps()):
        orient = res.value.orientations
        assert not dense_collides(jump, orient[k], orient[k + 1], world)


def test_knearest_connection_builds() -> None:
    params = RoadmapParams(
        v0max=5.5, vimpmax=8.0, connection=Connection.KNEAREST, neighbours=8, max_gap=GAP
    )
    rm = build(params, n=80, seed=4)
    assert len(rm.edges) > 0
    out_degree = np.bincount(rm.edges.src, minlength=80)
    assert out_degree.max() <= 2 * 8 + 8  # own neighbours plus being someone's neighbour


def test_progress_and_termination() -> None:
    plat, world = gap_scene()
    sampler = PlatformSampler(plat, root_height=0.4)
    seen: list[float] = []
    res = build_roadmap(
        sampler,
        50,
        PARAMS,
        rng=np.random.default_rng(0),
        collides_many=world,
        progress=seen.append,
        batch=10,
    )
    assert res.status is PlanStatus.SOLVED
    assert seen == sorted(seen) and seen[-1] == 1.0
    stopped = build_roadmap(sampler, 50, PARAMS, rng=np.random.default_rng(0), until=lambda: True)
    assert stopped.status is PlanStatus.TIMEOUT and stopped.value is None
    calls = iter(range(1000))
    partial = build_roadmap(
        sampler, 50, PARAMS, rng=np.random.default_rng(0), until=lambda: next(calls) >= 2, batch=10
    )
    assert partial.status is PlanStatus.APPROXIMATE and partial.value is not None
    assert 0 < len(partial.value.nodes) < 50


def test_query_statuses(roadmap: Roadmap) -> None:
    _, world = gap_scene()
    here = node(0.5, 1.0, 0.4)
    same = roadmap.query(here, node(0.5, 1.0, 0.4))
    assert same.status is PlanStatus.SOLVED and same.value is not None and len(same.value) == 0
    far = node(50.0, 50.0, 0.4)
    assert roadmap.query(far, here).status is PlanStatus.INVALID_START
    assert roadmap.query(here, far).status is PlanStatus.INVALID_GOAL
    closure = RoadmapNodes.single([0.5, 1.0, 0.4], [0, 0, 0, 1], [0, 0, 0], 1.0)
    assert roadmap.query(closure, node(7.5, 1, 0.4)).status is PlanStatus.INVALID_START
    timed = roadmap.query(here, node(7.5, 1, 0.4), collides_many=world, until=lambda: True)
    assert timed.status is PlanStatus.TIMEOUT


def test_unconnected_goal_is_infeasible() -> None:
    # Two far platforms: the goal is reachable from its own platform only.
    plat = Platforms(lo=[[0, 0], [30, 0]], hi=[[2, 2], [32, 2]], top=[0, 0])
    lo, hi = plat.boxes()
    world = BoxWorld(centres=[[0, 0, 0]], radius=0.1, box_lo=lo, box_hi=hi)
    res = build_roadmap(
        PlatformSampler(plat, root_height=0.4),
        60,
        PARAMS,
        rng=np.random.default_rng(1),
        collides_many=world,
    )
    assert res.value is not None
    out = res.value.query(node(1, 1, 0.4), node(31, 1, 0.4), collides_many=world)
    assert out.status is PlanStatus.INFEASIBLE


def test_nodes_validate() -> None:
    with pytest.raises(ValueError, match="N rows"):
        RoadmapNodes(np.zeros((2, 3)), np.ones((1, 4)), np.zeros((2, 3)), np.ones(2))
    with pytest.raises(ValueError, match="contacts"):
        RoadmapNodes(
            np.zeros((2, 3)), np.ones((2, 4)), np.zeros((2, 3)), np.ones(2), {"x": np.zeros(3)}
        )


@pytest.mark.parametrize("spread", [8.0, 2000.0])
def test_radius_candidates_are_uniform_subsets_of_the_ball(spread: float) -> None:
    from scipy.spatial import cKDTree

    from planner.ballistic.roadmap import _candidates

    rng = np.random.default_rng(0)
    points = np.column_stack(
        [rng.uniform(0, spread, 3000), rng.uniform(0, 2, 3000), np.zeros(3000)]
    )
    params = RoadmapParams(v0max=5.0, vimpmax=5.0, connection=Connection.RADIUS, neighbours=10)
    lists = _candidates(cKDTree(points), points, params, np.random.default_rng(1))
    radius = params.connection_radius
    for i, row in enumerate(lists):
        assert len(row) <= 11 and len(np.unique(row)) == len(row)
        assert np.all(np.linalg.norm(points[row] - points[i], axis=1) <= radius + 1e-12)
    chosen = np.concatenate(lists)
    if spread < 100:  # dense balls: no bias toward low node indices
        assert abs(chosen.mean() / 3000 - 0.5) < 0.05
