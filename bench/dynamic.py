"""Benchmark of the dynamic COM QP (``trajectory.dynamic_com``) on the calls of real plans.

Usage: ``python bench/dynamic.py [--repeat 5] [--scenario NAME ...]`` (default scenarios:
flat_walk_humanoid, stairs_humanoid; names are the JSON files of tests/scenarios/plans/).
Plans each scenario once at its seed, recording the arguments of every ``dynamic_com`` call
(the first curve and the slower windows of ``planner/motion/sequence.py``), then times each
call again, median of ``--repeat`` runs, two ways in the same run:

- old: every inequality row in the QP from the start, Clarabel at its default tolerances
  (1e-8) with iterative refinement and rescaling, 12 collocation times in every phase (what
  ``dynamic_com`` did before ``lazy_rows`` and ``sample_spacing``);
- whole: as the plan calls it but every round a round of the whole QP
  (``local_repair=False``: what ``dynamic_com`` did before the repair windows);
- new: as the plan calls it (rows on the curve alone added when needed, tolerances
  ``SOLVER_TOLERANCE``, refinement ``SOLVER_REFINEMENT``, rescaling ``SOLVER_EQUILIBRATION``,
  the plan's sample spacing, a few failing phases solved again in windows).

Prints per call the QP size, the three medians, the speed-ups of new over old and over whole,
and the largest difference between the control points of the old and new curves (m), then
per plan the sums over its calls (the plan's dynamic COM stage). Prints, asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

import trajectory  # noqa: E402
import trajectory.dynamic as dynamic  # noqa: E402
from planner.character import get_character  # noqa: E402
from planner.contact.planner import plan_contact_motion  # noqa: E402
from planner.offline import load_offline_data  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402
from tests.scenarios.plans.test_plans import (  # noqa: E402
    scenario_endpoint,
    scenario_options,
    scenario_scene,
)

PLANS = ROOT / "tests" / "scenarios" / "plans"
DEFAULT_SCENARIOS = ("flat_walk_humanoid", "stairs_humanoid")

Call = tuple[tuple[Any, ...], dict[str, Any]]


def record_calls(name: str) -> list[Call]:
    """The arguments of every ``trajectory.dynamic_com`` and ``solve_dynamic_com`` call while
    planning ``name``."""
    spec = json.loads((PLANS / f"{name}.json").read_text())
    scene = scenario_scene(spec)
    if scene is None:
        print(f"{name}: scene not installed, skipped")
        return []
    character = get_character(spec["character"])
    data = load_offline_data(character, gecko_cache_dir())
    calls: list[Call] = []
    original, original_outcome = trajectory.dynamic_com, trajectory.solve_dynamic_com

    def recording(*args: Any, **kwargs: Any) -> trajectory.DynamicCom | None:
        calls.append((args, kwargs))
        return original(*args, **kwargs)

    def recording_outcome(*args: Any, **kwargs: Any) -> trajectory.DynamicOutcome:
        calls.append((args, kwargs))
        return original_outcome(*args, **kwargs)

    trajectory.dynamic_com = recording  # type: ignore[assignment]
    trajectory.solve_dynamic_com = recording_outcome  # type: ignore[assignment]
    try:
        plan_contact_motion(
            scene,
            character,
            data,
            scenario_endpoint(spec["start"]),
            scenario_endpoint(spec["goal"]),
            rng=np.random.default_rng(int(spec["seed"])),
            time_budget_s=float(spec["time_budget_s"]),
            options=scenario_options(spec),
        )
    finally:
        trajectory.dynamic_com, trajectory.solve_dynamic_com = original, original_outcome
    return calls


@contextmanager
def old_way() -> Iterator[None]:
    """``dynamic_com`` as before lazy rows: Clarabel's default tolerances, refinement and
    rescaling (the caller also passes ``lazy_rows=False``)."""
    saved = dynamic.SOLVER_TOLERANCE, dynamic.SOLVER_REFINEMENT, dynamic.SOLVER_EQUILIBRATION
    dynamic.SOLVER_TOLERANCE, dynamic.SOLVER_REFINEMENT, dynamic.SOLVER_EQUILIBRATION = (
        1e-8,
        True,
        True,
    )
    try:
        yield
    finally:
        dynamic.SOLVER_TOLERANCE, dynamic.SOLVER_REFINEMENT, dynamic.SOLVER_EQUILIBRATION = saved


def timed(fn: Callable[[], trajectory.DynamicCom | None], repeat: int) -> tuple[float, Any]:
    """(median seconds of ``repeat`` calls, the last answer)."""
    ts, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - start)
    return float(np.median(ts)), out


def control_points(result: trajectory.DynamicCom | None) -> np.ndarray | None:
    if result is None:
        return None
    return np.concatenate([s.control_points for s in result.curve.segments])


def bench_scenario(name: str, repeat: int) -> None:
    calls = record_calls(name)
    total_old = total_whole = total_new = 0.0
    print(f"{name}: {len(calls)} dynamic_com calls")
    print(
        f"{'call':>4} {'phases':>6} {'old ms':>9} {'whole ms':>9} {'new ms':>9} {'x old':>6} "
        f"{'x whole':>7} {'max diff m':>11} answer"
    )
    for i, (args, kwargs) in enumerate(calls):
        base = kwargs.get("settings") or trajectory.DynamicSettings()
        every_row = dataclasses.replace(
            base, lazy_rows=False, sample_spacing=0.0, local_repair=False
        )
        whole_rounds = dataclasses.replace(base, local_repair=False)

        def run_old(
            a: tuple[Any, ...] = args, k: dict[str, Any] = kwargs, s: Any = every_row
        ) -> Any:
            with old_way():
                return trajectory.dynamic_com(*a, **{**k, "settings": s})

        def run_whole(
            a: tuple[Any, ...] = args, k: dict[str, Any] = kwargs, s: Any = whole_rounds
        ) -> Any:
            return trajectory.dynamic_com(*a, **{**k, "settings": s})

        def run_new(a: tuple[Any, ...] = args, k: dict[str, Any] = kwargs) -> Any:
            return trajectory.dynamic_com(*a, **k)

        t_old, r_old = timed(run_old, repeat)
        t_whole, _ = timed(run_whole, repeat)
        t_new, r_new = timed(run_new, repeat)
        total_old += t_old
        total_whole += t_whole
        total_new += t_new
        p_old, p_new = control_points(r_old), control_points(r_new)
        if p_old is None or p_new is None:
            diff = "-"
            same = "both None" if p_old is None and p_new is None else "DIFFERENT (None)"
        else:
            diff = f"{float(np.abs(p_old - p_new).max()):.1e}"
            same = "same" if r_old.valid == r_new.valid else "DIFFERENT (valid)"
            same += f", valid {r_new.valid}, rounds {r_old.iterations}/{r_new.iterations}"
        print(
            f"{i:>4} {len(args[0]):>6} {t_old * 1e3:>9.1f} {t_whole * 1e3:>9.1f} "
            f"{t_new * 1e3:>9.1f} {t_old / t_new:>6.1f} {t_whole / t_new:>7.2f} {diff:>11} {same}"
        )
    if calls:
        print(
            f"{name}: dynamic COM stage (sum of the calls' medians) old {total_old:.3f} s, "
            f"whole rounds {total_whole:.3f} s, new {total_new:.3f} s, "
            f"x{total_old / total_new:.1f} over old, x{total_whole / total_new:.2f} over whole\n"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--scenario", nargs="*", default=list(DEFAULT_SCENARIOS))
    args = parser.parse_args()
    for name in args.scenario:
        bench_scenario(name, args.repeat)


if __name__ == "__main__":
    main()
