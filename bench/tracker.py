"""Whole-body builder benchmark: CPU per control step, per Twister move, per second of
animation.

Usage: ``python bench/tracker.py [--repeats 5] [--plans NAME ...]``. Plays the chair game of
``tests/scenarios/steps/chair_humanoid.json`` once, recording its motion builds and the
control steps of their tracker, then prints medians of CPU time (``time.process_time``):

- per control step, the tracker's own QP assembly and solve (``objective`` + ``_solve``:
  daqp called directly, limits as bounds) against pink's ``build_ik`` on the same tasks
  and limits (``tests/planner/motion/pink_reference``) solved by qpsolvers' daqp, both
  with the same collision dampers: the measured comparison the project asks for before
  replacing pink;
- per Twister move, the recorded builds replayed (``build_motion`` alone);
- per plan (``tests/scenarios/plans/``, default flat_walk_humanoid and stairs_humanoid): the
  whole planning call and the builder's share, each per second of animation (target
  <= 0.2 s/s for the whole pipeline).

Prints, asserts nothing; on a shared machine compare medians of the same run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

import qpsolvers  # noqa: E402

import planner.motion.builder as builder  # noqa: E402
import planner.motion.sequence as sequence  # noqa: E402
import planner.motion.step as step  # noqa: E402
from planner.motion import tuning  # noqa: E402
from planner.motion.tracker import WholeBodyTracker  # noqa: E402

Call = tuple[tuple[Any, ...], dict[str, Any]]


def _recording(calls: list[Call]) -> Callable[..., Any]:
    original = builder.build_motion

    def build(*args: Any, **kwargs: Any) -> Any:
        calls.append((args, kwargs))
        return original(*args, **kwargs)

    return build


def _play_chair() -> list[Call]:
    """The build_motion calls of the chair game (its Twister moves)."""
    from tests.scenarios.steps import test_steps

    calls: list[Call] = []
    step.build_motion = _recording(calls)
    try:
        test_steps._played("chair_humanoid")
    finally:
        step.build_motion = builder.build_motion
    return calls


def _control_steps(call: Call) -> list[tuple[Any, ...]]:
    """(q, targets, dt, share) of every control step of one build."""
    steps: list[tuple[Any, ...]] = []
    original = WholeBodyTracker.step

    def record(self: WholeBodyTracker, q: Any, targets: Any, dt: float, share: float = 1.0) -> Any:
        steps.append((np.array(q), targets, dt, share))
        return original(self, q, targets, dt, share)

    WholeBodyTracker.step = record  # type: ignore[method-assign]
    try:
        builder.build_motion(*call[0], **call[1])
    finally:
        WholeBodyTracker.step = original  # type: ignore[method-assign]
    return steps


def _per_step(call: Call, steps: list[tuple[Any, ...]]) -> tuple[float, float]:
    """Median CPU ms per control step: own assembly + solve, pink's build_ik + solve (the
    recorded configurations replayed, dampers on)."""
    from tests.planner.motion.pink_reference import PinkReference

    character, bvh = call[0][0], call[0][1]
    obstacles = call[1].get("obstacles", ())
    ours = WholeBodyTracker(character, bvh, obstacles)
    twin = WholeBodyTracker(character, bvh, obstacles)
    reference = PinkReference(twin, (twin.scene, twin.self_clearance))
    own_ms, pink_ms = [], []
    for q, targets, dt, share in steps:
        start = time.process_time()
        qp = ours.objective(q, targets, share)
        ours._solve(qp, dt, True, targets.root_bounded, [])
        own_ms.append(1000.0 * (time.process_time() - start))
        start = time.process_time()
        twin.scene.set_phase(ours.scene.skipped, ours.scene.light)
        problem = reference.problem(q, targets, dt, share)
        qpsolvers.solve_problem(problem, solver=tuning.QP_SOLVER)
        pink_ms.append(1000.0 * (time.process_time() - start))
    return statistics.median(own_ms), statistics.median(pink_ms)


def _plan(name: str) -> tuple[float, float, float]:
    """CPU s of the whole plan, of its builds, and the animation's length (s)."""
    from tests.scenarios.plans import test_plans

    spent = [0.0]
    original = builder.build_motion

    def build(*args: Any, **kwargs: Any) -> Any:
        start = time.process_time()
        try:
            return original(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - start

    sequence.build_motion = build
    try:
        start = time.process_time()
        result, *_ = test_plans._plan(name)
        total = time.process_time() - start
    finally:
        sequence.build_motion = original

    motion = result.value.motion
    keys = motion.keyframes
    return total, spent[0], float(keys[-1].t - keys[0].t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--plans", nargs="*", default=["flat_walk_humanoid", "stairs_humanoid"])
    args = parser.parse_args()
    moves = _play_chair()
    print(f"chair game: {len(moves)} Twister moves")
    if hasattr(WholeBodyTracker, "objective"):
        steps = _control_steps(moves[0])
        pairs = [_per_step(moves[0], steps) for _ in range(args.repeats)]
        own = statistics.median(p[0] for p in pairs)
        pink = statistics.median(p[1] for p in pairs)
        print(
            f"per control step ({len(steps)} steps of move 1, median of {args.repeats}): "
            f"own QP assembly + solve {own:.3f} ms, pink build_ik + solve {pink:.3f} ms "
            f"(x{pink / own:.2f})"
        )
        counts = [len(_control_steps(m)) for m in moves]
        print(f"control steps per move: {counts}")
    per_move = []
    for _ in range(args.repeats):
        for args_, kwargs in moves:
            start = time.process_time()
            builder.build_motion(*args_, **kwargs)
            per_move.append(1000.0 * (time.process_time() - start))
    print(
        f"per Twister move build_motion: median {statistics.median(per_move):.1f} ms "
        f"(min {min(per_move):.1f}, max {max(per_move):.1f}; target ~45 ms)"
    )
    for name in args.plans:
        runs = [_plan(name) for _ in range(max(1, args.repeats // 2))]
        total = statistics.median(r[0] for r in runs)
        built = statistics.median(r[1] for r in runs)
        length = runs[0][2]
        print(
            f"{name}: {length:.2f} s of animation; whole plan {total:.2f} s CPU "
            f"({total / length:.3f} s/s, target 0.2), builds {built:.2f} s "
            f"({built / length:.3f} s/s)"
        )


if __name__ == "__main__":
    main()
