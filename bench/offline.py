"""Benchmark: offline data build time per built-in character (default sizes) and load time
from the cache. Prints medians; asserts nothing.

    .venv/bin/python bench/offline.py [--repeat-build 1] [--repeat-load 20] [--character ID]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

# The repository root first: bench/planner.py must not shadow the planner package.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.character import builtin_character_ids, get_character
from planner.offline import OfflineParams, load_offline_data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--character", action="append", help="default: the built-in ones")
    parser.add_argument("--repeat-build", type=int, default=1)
    parser.add_argument("--repeat-load", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    params = OfflineParams()
    print(f"default sizes: {params}")
    print(
        f"{'character':<10} {'build median (s)':>17} {'load median (ms)':>17} {'load max (ms)':>14}"
    )
    for cid in args.character or builtin_character_ids():
        character = get_character(cid)
        builds = []
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.repeat_build):
                start = time.perf_counter()
                load_offline_data(character, Path(tmp) / str(k), seed=args.seed, params=params)
                builds.append(time.perf_counter() - start)
            loads = []
            for _ in range(args.repeat_load):
                start = time.perf_counter()
                data = load_offline_data(character, Path(tmp) / "0", seed=args.seed, params=params)
                loads.append(time.perf_counter() - start)
                assert not data.built
        print(
            f"{cid:<10} {statistics.median(builds):>17.2f} "
            f"{statistics.median(loads) * 1e3:>17.1f} {max(loads) * 1e3:>14.1f}"
        )


if __name__ == "__main__":
    main()
