"""Contact-planner benchmark: success rate and time per stage, per scenario, over seeds.

Usage: ``python bench/planner.py [--seeds 20] [--scenario NAME ...]``. Scenarios are the
JSON files of ``tests/scenarios/plans/``. Prints, asserts nothing; ``work`` is the largest
share of its work budget a seed used (100 %: the budget stopped it) and ``capped`` the plans
the wall-clock cap stopped first (0 on a machine fast enough to replay every answer). Targets
on the 2-core machine: success >= 90 % on every built-in scenario, about 10 contact changes
<= 0.5 s median.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from planner.character import get_character  # noqa: E402
from planner.contact.planner import plan_contact_motion  # noqa: E402
from planner.offline import load_offline_data  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402
from tests.scenarios.plans.test_plans import (  # noqa: E402
    scenario_endpoint,
    scenario_options,
    scenario_scene,
)

SCENARIOS = ROOT / "tests" / "scenarios" / "plans"


def _p90(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(0.9 * (len(ordered) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--scenario", action="append", default=[])
    parser.add_argument("--no-twister", action="store_true", help="skip the Twister games")
    args = parser.parse_args()
    files = sorted(SCENARIOS.glob("*.json"))
    if args.scenario:
        files = [f for f in files if f.stem in args.scenario]
    print(
        f"{'scenario':28s} {'ok':>5s} {'med s':>7s} {'p90 s':>7s} {'path':>6s} "
        f"{'contacts':>8s} {'motion':>7s} {'changes':>7s} {'work':>5s} {'capped':>6s}"
    )
    for file in files:
        spec = json.loads(file.read_text())
        character = get_character(spec["character"])
        data = load_offline_data(character, gecko_cache_dir())
        scene = scenario_scene(spec)
        if scene is None:
            print(f"{file.stem:28s} skipped: scene not installed")
            continue
        totals, stages, changes, solved = [], {"root_path": [], "contacts": [], "motion": []}, [], 0
        work, capped = [], 0  # share of the work budget used; plans the clock cap stopped
        for seed in range(args.seeds):
            start = time.perf_counter()
            result = plan_contact_motion(
                scene,
                character,
                data,
                scenario_endpoint(spec["start"]),
                scenario_endpoint(spec["goal"]),
                rng=np.random.default_rng(seed),
                time_budget_s=float(spec["time_budget_s"]),
                options=scenario_options(spec),
            )
            totals.append(time.perf_counter() - start)
            solved += result.status.value == "SOLVED"
            used, units = result.stats.get("work_used", 0.0), result.stats.get("work_units", 1.0)
            work.append(float(used) / float(units))
            capped += bool(result.stats.get("clock_cap_hit", False))
            plan = result.value
            if plan is not None:
                for stage, values in stages.items():
                    values.append(plan.timings.get(stage, 0.0))
                changes.append(max(0, len(plan.states) - 1))
        med = {k: statistics.median(v) if v else float("nan") for k, v in stages.items()}
        print(
            f"{file.stem:28s} {solved / args.seeds:5.0%} {statistics.median(totals):7.2f} "
            f"{_p90(totals):7.2f} {med['root_path']:6.2f} {med['contacts']:8.2f} "
            f"{med['motion']:7.2f} {statistics.median(changes) if changes else 0:7.1f} "
            f"{max(work):5.0%} {capped:6d}"
        )


def unreachable_goal(seeds: int) -> None:
    """Answer time of a 1 s plan to a goal inside the closed pen (target: within 1.5 s)."""
    from tests.planner.contact.contact_helpers import character_and_data, plan_into_the_pen, scene

    character_and_data("humanoid"), scene("pen")  # loaded before the clock starts
    times, statuses = [], set()
    for seed in range(seeds):
        start = time.perf_counter()
        result = plan_into_the_pen(seed)
        times.append(time.perf_counter() - start)
        statuses.add(result.status.value)
    print(
        f"\n{'unreachable goal, 1 s budget':28s} med {statistics.median(times):.3f} s, "
        f"max {max(times):.3f} s, status {'/'.join(sorted(statuses))}"
    )


def twister_games() -> None:
    """Median time per Twister step over the 20-move games of tests/scenarios/twister."""
    from tests.planner.contact.twister_game import SCENARIOS as GAMES
    from tests.planner.contact.twister_game import play

    print(f"\n{'twister game':28s} {'moves':>5s} {'ok':>5s} {'med ms':>7s} {'p90 ms':>7s}")
    for file in sorted(GAMES.glob("*.json")):
        moves = play(file)
        times = [m.result.timings.get("total", 0.0) * 1e3 for m in moves]
        solved = sum(m.result.ok for m in moves) / max(1, len(moves))
        print(
            f"{file.stem:28s} {len(moves):5d} {solved:5.0%} {statistics.median(times):7.1f} "
            f"{_p90(times):7.1f}"
        )


if __name__ == "__main__":
    main()
    unreachable_goal(5)
    if "--no-twister" not in sys.argv:
        twister_games()
