"""Ballistic jump benchmarks (printed, never asserted).

Run: .venv/bin/python bench/jumps.py [--quick]

- steering throughput (pairs per second, batched) and the range pre-filter;
- roadmap build time, node and edge counts on a synthetic platforms scene;
- query time (median over random start/goal pairs), save/load time;
- per scenario of ``tests/scenarios/jumps`` (real scenes and characters): roadmap build time
  and node count (eager and lazy edges), query time, time per jump including keyframes
  (stance contact generation, contact phases, flight), contact generation per stance.

Jump paper Table 1 for comparison: roadmap build 0.51 to 107 s; one jump 0.12 to 1.39 s on
average; contact generation 25 to 77 ms (one core of a Xeon E5-1630 v3 at 3.7 GHz).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.ballistic.roadmap import (
    Connection,
    Roadmap,
    RoadmapNodes,
    RoadmapParams,
    build_roadmap,
)
from planner.ballistic.steering import range_prefilter, steer
from planner.ballistic.synthetic import BoxWorld, Platforms, PlatformSampler


def median_seconds(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench_steering(quick: bool) -> None:
    rng = np.random.default_rng(0)
    print("== steering (closed form, batched) ==")
    print(f"{'batch':>9} {'median s':>10} {'pairs/s':>12} {'ok %':>6}")
    for n in (1_000, 10_000, 100_000) if quick else (1_000, 10_000, 100_000, 1_000_000):
        p0 = rng.uniform(-4, 4, (n, 3))
        p1 = rng.uniform(-4, 4, (n, 3))
        n0 = np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.3, size=(n, 3))
        n1 = np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.3, size=(n, 3))

        def run(
            p0: np.ndarray = p0, p1: np.ndarray = p1, n0: np.ndarray = n0, n1: np.ndarray = n1
        ) -> object:
            return steer(p0, p1, n0, 1.0, n1, 1.0, v0max=7.0, vimpmax=10.0)

        seconds = median_seconds(run, 3 if n >= 100_000 else 7)
        ok = float(np.mean(steer(p0, p1, n0, 1.0, n1, 1.0, v0max=7.0, vimpmax=10.0).ok))
        print(f"{n:>9} {seconds:>10.4f} {n / seconds:>12.0f} {100 * ok:>6.1f}")
    n = 1_000_000
    p0, p1 = rng.uniform(-4, 4, (n, 3)), rng.uniform(-4, 4, (n, 3))
    seconds = median_seconds(lambda: range_prefilter(p0, p1, 7.0, 10.0), 5)
    print(f"range pre-filter: {n / seconds:.0f} pairs/s")
    # The roadmap's case: every pair already passed the pre-filter.
    keep = range_prefilter(p0, p1, 7.0, 10.0)
    a, b = p0[keep][:100_000], p1[keep][:100_000]
    up = np.array([0.0, 0.0, 1.0])
    seconds = median_seconds(lambda: steer(a, b, up, 1.0, up, 1.0, v0max=7.0, vimpmax=10.0), 3)
    print(f"steering after the pre-filter: {len(a) / seconds:.0f} pairs/s (batch {len(a)})")


def platforms_scene(rng: np.random.Generator, side: int) -> tuple[Platforms, BoxWorld]:
    """side x side platforms 2 x 2 m, 1 m gaps, heights in [0, 1] m, a pillar per gap row."""
    ij = np.array([(i, j) for i in range(side) for j in range(side)], dtype=float)
    lo = ij * 3.0
    hi = lo + 2.0
    top = rng.uniform(0.0, 1.0, len(ij))
    plat = Platforms(lo=lo, hi=hi, top=top)
    blo, bhi = plat.boxes()
    pillars_lo = np.array(
        [[3.0 * i + 2.4, 3.0 * j, -1.0] for i in range(side - 1) for j in range(side)]
    )
    pillars_hi = pillars_lo + np.array([0.2, 1.0, 2.5])
    world = BoxWorld(
        centres=[[-0.2, 0, 0], [0, 0, 0], [0.2, 0, 0]],
        radius=0.15,
        box_lo=np.vstack([blo, pillars_lo]),
        box_hi=np.vstack([bhi, pillars_hi]),
    )
    return plat, world


def bench_roadmap(quick: bool) -> None:
    rng = np.random.default_rng(1)
    plat, world = platforms_scene(rng, 4)
    checker = world.inflated(0.05)
    sampler = PlatformSampler(plat, root_height=0.45, mu=1.0, margin=0.2)
    print("\n== roadmap on synthetic platforms (4 x 4 platforms, 12 pillars) ==")
    print(
        f"{'nodes':>6} {'mode':>9} {'conn':>9} {'build s':>8} {'edges':>7} {'searches':>9} "
        f"{'query ms':>9} {'solved':>7} {'jumps':>6}"
    )
    sizes = (250, 1000) if quick else (250, 1000, 4000, 10000)
    for n_nodes in sizes:
        for lazy in (False, True) if n_nodes <= 1000 else (True,):
            params = RoadmapParams(
                v0max=6.0,
                vimpmax=9.0,
                connection=Connection.RADIUS,
                neighbours=24,
                max_gap=0.05,
                lazy=lazy,
                scene_key="bench",
            )
            start = time.perf_counter()
            res = build_roadmap(
                sampler, n_nodes, params, rng=np.random.default_rng(n_nodes), collides_many=checker
            )
            build_s = time.perf_counter() - start
            roadmap = res.value
            assert roadmap is not None
            ends = sampler.sample(40, rng=np.random.default_rng(99))
            times, solved, jumps = [], 0, []
            for k in range(20):
                s_node = ends.take(np.array([2 * k]))
                g_node = ends.take(np.array([2 * k + 1]))
                t0 = time.perf_counter()
                out = roadmap.query(s_node, g_node, collides_many=checker)
                times.append(time.perf_counter() - t0)
                if out.value is not None:
                    solved += 1
                    jumps.append(len(out.value))
            stats = roadmap.stats
            print(
                f"{len(roadmap.nodes):>6} {'lazy' if lazy else 'eager':>9} "
                f"{params.connection.value:>9} {build_s:>8.2f} {len(roadmap.edges):>7} "
                f"{stats.get('searches', 0)!s:>9} {1e3 * statistics.median(times):>9.2f} "
                f"{solved:>4}/20 {statistics.mean(jumps) if jumps else 0:>6.1f}"
            )
    with tempfile.TemporaryDirectory() as tmp:
        file = Path(tmp) / "roadmap.npz"
        save_s = median_seconds(lambda: roadmap.save(file), 3)
        load_s = median_seconds(lambda: Roadmap.load(file, expected=roadmap.params), 3)
        size = file.stat().st_size
    print(
        f"save {1e3 * save_s:.1f} ms, load {1e3 * load_s:.1f} ms, file {size / 1e6:.2f} MB "
        f"({len(roadmap.nodes)} nodes, {len(roadmap.edges)} edges, last roadmap above)"
    )
    # A single query on a prebuilt roadmap, start and goal on the far corners.
    corner_a = RoadmapNodes.single([1.0, 1.0, plat.top[0] + 0.45], [0, 0, 0, 1], [0, 0, 1], 1.0)
    last = len(plat.top) - 1
    corner_b = RoadmapNodes.single(
        [10.0, 10.0, plat.top[last] + 0.45], [0, 0, 0, 1], [0, 0, 1], 1.0
    )
    seconds = median_seconds(lambda: roadmap.query(corner_a, corner_b, collides_many=checker), 5)
    out = roadmap.query(corner_a, corner_b, collides_many=checker)
    print(
        f"corner-to-corner query: {1e3 * seconds:.2f} ms, status {out.status.value}, "
        f"{len(out.value) if out.value is not None else 0} jumps"
    )


TABLE1 = (
    "jump paper Table 1 (one core, Xeon E5-1630 v3): roadmap 0.51-107 s (22-1256 nodes); "
    "one jump 0.12-1.39 s average; contact generation 25-77 ms"
)


def bench_scenarios(quick: bool) -> None:
    from planner.ballistic.nodes import ReducedModel, SceneSampler
    from planner.ballistic.planner import plan_jumps
    from planner.ballistic.roadmap import build_roadmap as build
    from planner.ballistic.stance import NodeStancer
    from tests.scenarios.jumps.scenario import scenarios

    print("\n== scenarios (real scenes and characters; tests/scenarios/jumps) ==")
    print(TABLE1)
    print(
        f"{'scenario':<30} {'nodes':>6} {'eager s':>8} {'lazy s':>7} {'edges':>6} "
        f"{'query ms':>9} {'jumps':>6} {'ms/jump':>8} {'kf ms/jump':>10} {'contact ms':>10}"
    )
    for scenario in scenarios():
        loaded = scenario.load()
        if loaded is None:
            print(f"{scenario.name:<30} skipped (scene not installed)")
            continue
        scene, character, data = loaded
        params = scenario.params()
        rparams = params.roadmap_params(scene, character, data)
        model = ReducedModel.build(scene, character, data, margin=rparams.max_gap / 2)
        sampler = SceneSampler(model, params.limbs_needed(character))
        eager_s = float("nan")
        if not quick:
            start = time.perf_counter()
            build(
                sampler,
                params.n_nodes,
                replace(rparams, lazy=False),
                rng=np.random.default_rng(scenario.seed),
                collides_many=model.collider,
            )
            eager_s = time.perf_counter() - start
        start = time.perf_counter()
        built = build(
            sampler,
            params.n_nodes,
            rparams,
            rng=np.random.default_rng(scenario.seed),
            collides_many=model.collider,
        )
        lazy_s = time.perf_counter() - start
        roadmap = built.value
        assert roadmap is not None

        results = [
            plan_jumps(
                scene,
                character,
                data,
                scenario.end("start"),
                scenario.end("goal"),
                rng=np.random.default_rng(scenario.seed),
                roadmap=roadmap,
                params=params,
            )
            for _ in range(3)
        ]
        plans = [r.value for r in results]
        if any(p is None for p in plans):
            print(f"{scenario.name:<30} not solved: {results[0].status}")
            continue
        plans_ok = [p for p in plans if p is not None]
        n_jumps = len(plans_ok[0].jumps)
        query_ms = 1e3 * statistics.median(p.timings["query"] for p in plans_ok)
        kf_ms = 1e3 * statistics.median(p.timings["keyframes"] for p in plans_ok) / n_jumps
        per_jump = 1e3 * statistics.median(p.timings["total"] for p in plans_ok) / n_jumps
        # Contact generation: one stance (all contacts of a node) from scratch.
        stancer = NodeStancer(character, data)
        nodes = roadmap.nodes
        k = min(len(nodes), 20)
        t0 = time.perf_counter()
        for i in range(k):
            stancer.stance(
                nodes.positions[i],
                nodes.orientations[i],
                nodes.contacts["active"][i],
                nodes.contacts["points"][i],
                nodes.contacts["normals"][i],
            )
        contact_ms = 1e3 * (time.perf_counter() - t0) / k
        print(
            f"{scenario.name:<30} {len(roadmap.nodes):>6} {eager_s:>8.2f} {lazy_s:>7.2f} "
            f"{len(roadmap.edges):>6} {query_ms:>9.2f} {n_jumps:>6} {per_jump:>8.1f} "
            f"{kf_ms:>10.1f} {contact_ms:>10.1f}"
        )
    print("ms/jump: plan_jumps on the prebuilt roadmap (end points, query, keyframes) / jumps")


def bench_paper_sized() -> None:
    """Roadmap build at the paper's node count on the pond (paper: 47 nodes in 0.76 s)."""

    from planner.ballistic.planner import JumpParams, RoadmapStore
    from planner.character import get_character
    from planner.offline import load_offline_data
    from planner.scene import build_scene
    from tests.paths import gecko_cache_dir
    from tests.scenarios.jumps.scenes import pond_mesh

    character = get_character("quadruped")
    data = load_offline_data(character, gecko_cache_dir())
    scene = build_scene(pond_mesh(), scene_id="pond", cache_dir=gecko_cache_dir())
    print("\n== paper-sized roadmap: pond, 47 nodes (paper: 0.76 s) ==")
    for lazy in (True, False):
        params = JumpParams(
            roadmap=RoadmapParams(v0max=5.0, vimpmax=7.0, max_gap=0.1, lazy=lazy),
            min_limbs=2,
            n_nodes=47,
        )
        times = []
        for seed in range(5):
            with tempfile.TemporaryDirectory() as directory:
                start = time.perf_counter()
                RoadmapStore(directory).build(scene, character, data, params, 47, seed)
                times.append(time.perf_counter() - start)
        median = statistics.median(times)
        mode = "lazy edges " if lazy else "eager edges"
        print(f"  {mode}: median {median:.3f} s, {0.76 / median:.1f}x faster than the paper")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes")
    args = parser.parse_args()
    bench_steering(args.quick)
    bench_roadmap(args.quick)
    bench_scenarios(args.quick)
    bench_paper_sized()


if __name__ == "__main__":
    main()
