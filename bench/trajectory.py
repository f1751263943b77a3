"""Benchmark of the trajectory package (prints, asserts nothing).

Run: .venv/bin/python bench/trajectory.py [--repeat N]
Medians of repeated runs; ratios to the reference C++ library measured in the same run.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for extra in (ROOT, ROOT / "bench", ROOT / "tests" / "trajectory"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from helpers import random_phase, walking_phases  # noqa: E402

import trajectory  # noqa: E402
from trajectory.equilibrium import project_polygon  # noqa: E402  (uncached)

TABLE2_MS = {1: 0.157, 2: 2.11, 3: 5.14, 4: 14.0, 5: 33.7, 6: 68.19}


def median_time(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """(median, p99) seconds of ``repeat`` calls after one warm-up call."""
    fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)), float(np.percentile(ts, 99))


def ground_phase(rng: np.random.Generator, k: int) -> trajectory.ContactPhase:
    """k patches on uneven ground and walls that hold the character (non-empty region)."""
    while True:
        phase = random_phase(rng, k)
        if trajectory.equilibrium_polygon(phase).A.shape[0] > 0 and not np.array_equal(
            trajectory.equilibrium_polygon(phase).b, [-1.0]
        ):
            return phase


def bench_polytope(repeat: int, n_sets: int) -> None:
    try:
        from bench._oracles import ReferenceEquilibrium

        ref = ReferenceEquilibrium(70.0)
    except ImportError as exc:
        ref = None
        print(f"(reference unavailable: {exc})")
    rng = np.random.default_rng(7)
    print("equilibrium polytope, contacts of 4 points (median over sets of the per-set median)")
    print(f"{'k':>2} {'ours ms':>9} {'ref ms':>9} {'ref/ours':>9} {'2PAC T2 ms':>11}")
    for k in range(1, 7):
        ours, theirs = [], []
        for _ in range(n_sets):
            phase = ground_phase(rng, k)
            ours.append(median_time(lambda p=phase: project_polygon(p), repeat)[0])
            if ref is not None:
                pts = np.vstack([c.points for c in phase.contacts])
                nrm = np.vstack([np.tile(c.normal, (4, 1)) for c in phase.contacts])

                def run_ref(p: np.ndarray = pts, n: np.ndarray = nrm) -> None:
                    ref.set_contacts_fast(p, n, 0.5)
                    ref.eq.getPolytopeInequalities()

                theirs.append(median_time(run_ref, repeat)[0])
        o = np.median(ours) * 1e3
        r = np.median(theirs) * 1e3 if theirs else float("nan")
        print(f"{k:>2} {o:>9.3f} {r:>9.3f} {r / o:>9.2f} {TABLE2_MS[k]:>11.3f}")


def bench_robustness(repeat: int) -> None:
    rng = np.random.default_rng(8)
    phase = ground_phase(rng, 3)
    poly = trajectory.equilibrium_halfspaces(phase)
    centre = np.vstack([c.points for c in phase.contacts]).mean(axis=0)
    coms = [np.array([*(centre[:2] + rng.uniform(-0.2, 0.2, 2)), 1.0]) for _ in range(20)]
    coms = [c for c in coms if poly.contains(c)] or [np.array([*centre[:2], 1.0])]
    ours = median_time(lambda: [trajectory.equilibrium_margin(phase, c) for c in coms], repeat)[0]
    line = f"robustness LP (3 contacts): ours {ours / len(coms) * 1e6:.1f} us"
    try:
        from bench._oracles import ReferenceEquilibrium

        ref = ReferenceEquilibrium(70.0, algorithm="LP")
        pts = np.vstack([c.points for c in phase.contacts])
        nrm = np.vstack([np.tile(c.normal, (4, 1)) for c in phase.contacts])
        ref.set_contacts_fast(pts, nrm, 0.5)
        theirs = median_time(lambda: [ref.robustness(c) for c in coms], repeat)[0]
        line += f", reference computeEquilibriumRobustness {theirs / len(coms) * 1e6:.1f} us"
        line += f" (ref/ours {theirs / ours:.2f})"
    except ImportError:
        pass
    print(line)


def bench_transition(repeat: int) -> None:
    rng = np.random.default_rng(9)
    cases = []
    for _ in range(30):
        a, b = ground_phase(rng, 3), ground_phase(rng, 2)
        kin = trajectory.Halfspaces(
            np.vstack([np.eye(3), -np.eye(3)]), np.array([1.0, 1.0, 1.1, 1.0, 1.0, -0.6])
        )
        eq = trajectory.stack(
            [trajectory.equilibrium_halfspaces(a), trajectory.equilibrium_halfspaces(b)]
        )
        c0 = rng.uniform(-0.3, 0.3, 3) + np.array([0.0, 0.0, 0.9])
        cases.append((eq, trajectory.stack([kin, kin]), c0))
    ts = []
    for _ in range(max(1, repeat // 10)):
        for eq, kin, c in cases:
            t = time.perf_counter()
            trajectory.transition_qp(eq, kin, c)
            ts.append(time.perf_counter() - t)
    print(
        f"transition QP (Eq. 6, {len(ts)} solves): median {np.median(ts) * 1e6:.1f} us, "
        f"p99 {np.percentile(ts, 99) * 1e6:.1f} us"
    )
    phase = ground_phase(rng, 3)
    kin = cases[0][1]
    med, p99 = median_time(
        lambda: trajectory.transition_qp_generators(phase, kin, np.array([0.0, 0.0, 0.9])), repeat
    )
    print(f"transition QP (Eq. 13, 3 contacts): median {med * 1e6:.1f} us, p99 {p99 * 1e6:.1f} us")


def bench_plan(repeat: int) -> None:
    phases = walking_phases(10)
    start = np.array([0.0, 0.0, 0.9])
    for label, kwargs in (
        ("2pac, default (auto -> Eq. 13), no validation", {"n_checks": 0}),
        ("2pac, polytopes (Eq. 6), no validation", {"n_checks": 0, "formulation": "polytope"}),
        ("quasi-static polyline, no validation", {"n_checks": 0, "method": "quasi_static"}),
        ("2pac, default, validation 10 pts/phase", {"n_checks": 10}),
    ):
        med, _ = median_time(
            lambda kw=kwargs: trajectory.plan_com_trajectory(phases, start, **kw), repeat
        )
        print(f"COM trajectory, 10 phases, {label}: median {med * 1e3:.2f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=30)
    parser.add_argument("--sets", type=int, default=8)
    args = parser.parse_args()
    bench_polytope(args.repeat, args.sets)
    bench_robustness(args.repeat)
    bench_transition(args.repeat)
    bench_plan(args.repeat)


if __name__ == "__main__":
    main()
