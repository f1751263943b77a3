"""Twister step benchmark: compute time of one step, in process, as a planning worker runs it.

Usage: ``python bench/step.py [--games 2] [--length 8] [--seed 0] [--repeats 3]
[--character quadruped humanoid hexapod] [--record FILE | --compare FILE]``.

Plays Twister games like ``clients/load_test.py`` does (issue 15): each game starts with the
live fixture's move (``tests/live_fixtures.py`` LIVE_STEP: the quadruped stands at the
origin of the ``twister`` mat and breaks a limb; the humanoid and hexapod stand there and make
an ``auto`` move), then ``auto`` moves that pass the previous answer's state back, a new game
after ``--length`` moves or a refused one; seeds from a fixed stream (``--seed``). Each
request goes through ``service.compute.run_ready`` (what a planning process runs for
``POST /v1/twister/step``: validation, the step, conversion, the result store,
serialisation) after one warm-up request per character (the registry loads
characters and scenes on first use). Prints the median and p90 of the compute time per
character and over all steps (each step run ``--repeats`` times, its fastest kept: other
processes on the machine only ever add time) and the median seconds of motion a solved step
plays; asserts nothing. Target (issue 15): 40
steps/s on 2 cores, so <= 50 ms per step.

``--record FILE`` writes every request and its answer (timings removed) to FILE;
``--compare FILE`` replays FILE's requests (timed the same way) and prints the largest
absolute difference between the recorded and the new answers' numbers (inf where anything
else differs: a status, a contact, a list's length).
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from service import compute, workers  # noqa: E402
from service.settings import Settings  # noqa: E402
from tests.live_fixtures import LIVE_STEP  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402

FIRST_MOVES: dict[str, dict[str, Any]] = {
    "quadruped": dict(LIVE_STEP),
    "humanoid": {**LIVE_STEP, "character": "humanoid", "action": {"kind": "auto"}},
    "hexapod": {**LIVE_STEP, "character": "hexapod", "action": {"kind": "auto"}},
}
BUDGET_S = 2.0  # the load test's step budget
FAR = 600.0  # s: a deadline no step reaches (the time never changes an answer here)


def _p90(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(0.9 * (len(ordered) - 1)))]


def run(request: dict[str, Any]) -> tuple[dict[str, Any], float]:
    """The answer to one step request (as stored) and its compute seconds."""
    body = json.dumps(request)
    start = time.perf_counter()
    ready = compute.run_ready("step", body, int(request["seed"]), time.monotonic() + FAR)
    elapsed = time.perf_counter() - start
    answer = json.loads(ready.body)
    answer.pop("timings", None)
    answer.pop("id", None)
    return answer, elapsed


def games(character: str, count: int, length: int, seed: int) -> list[dict[str, Any]]:
    """Requests of ``count`` games (computed as they go: each passes the state back)."""
    rng = random.Random(seed)
    requests: list[dict[str, Any]] = []
    for _ in range(count):
        state = None
        for move in range(length):
            if state is None:
                if move > 0:
                    break
                request = dict(FIRST_MOVES[character])
            else:
                request = {k: v for k, v in FIRST_MOVES[character].items() if k != "stand_at"}
                request |= {"state": state, "action": {"kind": "auto"}}
            request |= {"seed": rng.randrange(2**31), "time_budget_s": BUDGET_S}
            answer, _ = run(request)
            requests.append(request)
            state = answer["state"] if answer["status"] == "SOLVED" else None
    return requests


def _animated(answer: dict[str, Any]) -> float:
    """s of motion an answer plays (0 for a refused move)."""
    keyframes = answer.get("keyframes") or []
    return float(keyframes[-1]["t"] - keyframes[0]["t"]) if keyframes else 0.0


def difference(a: Any, b: Any, path: str = "") -> tuple[float, str]:
    """Largest absolute difference between two JSON values (inf where they differ in kind)."""
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or a is None:
        return (0.0, "") if a == b else (float("inf"), path)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(float(a) - float(b)), path
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return float("inf"), f"{path} keys {sorted(a.keys() ^ b.keys())}"
        items = [difference(a[k], b[k], f"{path}.{k}") for k in a]
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return float("inf"), f"{path} length {len(a)} != {len(b)}"
        items = [
            difference(x, y, f"{path}[{i}]") for i, (x, y) in enumerate(zip(a, b, strict=True))
        ]
    else:
        return float("inf"), path
    return max(items, default=(0.0, ""), key=lambda item: item[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", type=int, default=2)
    parser.add_argument("--length", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--character", nargs="*", default=list(FIRST_MOVES))
    parser.add_argument(
        "--repeats", type=int, default=3, help="runs per step, the fastest kept (noise)"
    )
    parser.add_argument("--record", type=Path)
    parser.add_argument("--compare", type=Path)
    args = parser.parse_args()

    animated: dict[str, list[float]] = {}  # s of motion per solved step, per character
    home = Path(tempfile.mkdtemp(prefix="gecko-bench-step-"))
    settings = Settings(
        home=home,
        cache_dir=gecko_cache_dir(),
        scenes_dir=home / "scenes",
        characters="humanoid,quadruped,hexapod",
    )
    workers._init_worker(settings.model_dump_json())

    if args.compare is not None:
        recorded = json.loads(args.compare.read_text())
        for character in {r["request"]["character"] for r in recorded}:
            run(dict(FIRST_MOVES[character], seed=0))  # warm-up: load before the clock
        worst, where, times = 0.0, "", []
        by_character: dict[str, list[float]] = {}
        for index, item in enumerate(recorded):
            answer, elapsed = run(item["request"])
            for _ in range(args.repeats - 1):
                elapsed = min(elapsed, run(item["request"])[1])
            times.append(elapsed * 1e3)
            by_character.setdefault(item["request"]["character"], []).append(elapsed * 1e3)
            animated.setdefault(item["request"]["character"], []).append(_animated(answer))
            diff, path = difference(item["answer"], answer)
            if diff > worst:
                worst, where = diff, f"step {index}{path}"
        print(f"{len(recorded)} steps replayed; largest difference {worst:.3g} at {where or '-'}")
    else:
        requests: list[dict[str, Any]] = []
        for character in args.character:
            run(dict(FIRST_MOVES[character], seed=0))  # warm-up: load before the clock
            requests += games(character, args.games, args.length, args.seed)
        times, by_character, record = [], {}, []
        for request in requests:  # timed on a second pass, every character loaded
            answer, elapsed = run(request)
            for _ in range(args.repeats - 1):
                elapsed = min(elapsed, run(request)[1])
            times.append(elapsed * 1e3)
            by_character.setdefault(request["character"], []).append(elapsed * 1e3)
            animated.setdefault(request["character"], []).append(_animated(answer))
            record.append({"request": request, "answer": answer})
        if args.record is not None:
            args.record.write_text(json.dumps(record))
        solved = sum(r["answer"]["status"] == "SOLVED" for r in record)
        print(f"{len(record)} steps, {solved} SOLVED")
    print(f"{'character':12s} {'steps':>5s} {'med ms':>7s} {'p90 ms':>7s} {'motion s':>8s}")
    for character, values in by_character.items():
        motion = [d for d in animated[character] if d > 0.0]
        print(
            f"{character:12s} {len(values):5d} {statistics.median(values):7.1f} "
            f"{_p90(values):7.1f} {statistics.median(motion) if motion else 0.0:8.2f}"
        )
    motion = [d for values in animated.values() for d in values if d > 0.0]
    print(
        f"{'all':12s} {len(times):5d} {statistics.median(times):7.1f} {_p90(times):7.1f} "
        f"{statistics.median(motion) if motion else 0.0:8.2f}"
    )
    print("target (issue 15): <= 50 ms median per step (40 steps/s on 2 cores)")


if __name__ == "__main__":
    main()
