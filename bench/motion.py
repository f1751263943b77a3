"""Motion-quality benchmark: the keyframes of every reference scenario through the independent
auditor (``tests/motion_audit.py``), per scenario over seeds.

Usage: ``python bench/motion.py [--seeds 20] [--scenario NAME ...] [--nudge MM] [--twister]
[--jumps]``. Plans are the JSON files of ``tests/scenarios/plans/`` (seed = the scenario's seed
+ i); ``--nudge MM`` also moves run i's start horizontally by up to MM millimetres (a point of
the disc drawn from seed + i, the planner's own draws untouched): on level ground the seed
hardly changes a plan, and a start a millimetre away may (the hexapod's walk);
``--twister`` adds the games of ``tests/scenarios/twister/`` (every successful move audited),
``--jumps`` the scenarios of ``tests/scenarios/jumps/`` (root jumps not counted in flights).
Prints, asserts nothing. Figures (motion-quality.md): success (SOLVED fraction; Twister: moves
ok), frames with a non-stance link > 1 cm inside the scene ("pen"), the worst such depth and
link, frames with a stance link > 1 cm inside the scene more than 5 cm from its contact points
("far"), stance effector distance from its contact (max, mm), frames with self-collision > 1 cm,
keyframe pairs with a joint over 10 rad/s or its URDF limit (and the fastest), root jumps
> 5 cm per 30 Hz step per run, keyframe COM vs COM curve (p99, mm), root tilt (max, deg),
trunk tilt (the most tilted body carrying two effectors or more: a humanoid's chest; max,
deg), phases animated, pace (m/s), frames with a still COM (< 1 cm/s), seconds of computation per
second of animation (median, and its 90th percentile: s/s90), seconds of auditing per run
(median).

After the plans, a pace table (issue 13) per plan scenario: average progress (m/s, start to
end COM over the animation), median stride (m, a contact's move between two consecutive
contacts of its limb), frames with a still COM, dynamic validity (Eq. 1: mean fraction of
valid samples per phase, and the share of phases valid throughout) beside 2PAC's Table 3
where the paper has the kind of scene, contact changes per plan (median), seconds of
computation per contact change (whole pipeline, median), and on flat ground how far the
keyframe COM rises and falls (bob: its height range over the plan, mm, median), and the
pairs of swings overlapped (ovl, median; ``planner.motion.overlap``).
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import statistics
import sys
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from planner.character import get_character  # noqa: E402
from planner.contact.planner import plan_contact_motion  # noqa: E402
from planner.offline import load_offline_data  # noqa: E402
from tests.motion_audit import MotionAudit, audit_from_domain  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402
from tests.scenarios.plans.test_plans import (  # noqa: E402
    scenario_endpoint,
    scenario_options,
    scenario_scene,
)

PLANS = ROOT / "tests" / "scenarios" / "plans"
TWISTER = ROOT / "tests" / "scenarios" / "twister"
TARGETS = (
    "targets (issue 12): penetrating, self-collision, pops and root jumps 0 beside every "
    "scenario; COM p99 <= 20 mm; tilt <= 30 deg on walks and stairs; every phase animated; "
    "success no lower than today's; <= 0.2 s of computation per animation second"
)


@dataclass
class Tally:
    """Figures pooled over the runs (and moves) of one scenario."""

    runs: int = 0
    solved: int = 0
    frames: int = 0
    pairs: int = 0
    penetrating: int = 0
    stance_far: int = 0
    worst_pen: float = 0.0
    worst_link: str = ""
    stance_error: float = math.nan
    self_frames: int = 0
    pops: int = 0
    max_speed: float = 0.0
    root_jumps: int = 0
    com_errors: list[float] = field(default_factory=list)
    tilt: float = math.nan
    trunk_tilt: float = math.nan
    coverage: list[float] = field(default_factory=list)
    pace: list[float] = field(default_factory=list)
    still: float = 0.0
    cost: list[float] = field(default_factory=list)
    audit_s: list[float] = field(default_factory=list)
    notes: set[str] = field(default_factory=set)
    strides: list[float] = field(default_factory=list)
    changes: list[int] = field(default_factory=list)
    per_change: list[float] = field(default_factory=list)
    validity: list[float] = field(default_factory=list)
    bob: list[float] = field(default_factory=list)
    overlapped: list[int] = field(default_factory=list)

    def add(self, audit: MotionAudit) -> None:
        self.frames += audit.frames
        self.pairs += audit.pairs
        self.penetrating += audit.penetrating_frames
        self.stance_far += audit.stance_penetrating_frames
        if audit.worst_penetration_m > self.worst_pen:
            self.worst_pen, self.worst_link = (
                audit.worst_penetration_m,
                audit.worst_penetration_link,
            )
        if math.isfinite(audit.stance_contact_error_m):
            self.stance_error = float(np.nanmax([self.stance_error, audit.stance_contact_error_m]))
        self.self_frames += audit.self_collision_frames
        self.pops += audit.pops
        self.max_speed = max(self.max_speed, audit.max_joint_speed)
        self.root_jumps += audit.root_jumps
        self.com_errors.extend(float(e) for e in audit.com_error if math.isfinite(e))
        if audit.frames:
            self.tilt = float(np.nanmax([self.tilt, audit.tilt_max_deg]))
            self.trunk_tilt = float(np.nanmax([self.trunk_tilt, audit.trunk_tilt_max_deg]))
        if math.isfinite(audit.coverage):
            self.coverage.append(audit.coverage)
        if math.isfinite(audit.pace_m_per_s):
            self.pace.append(audit.pace_m_per_s)
        if math.isfinite(audit.still_com_fraction):
            self.still += audit.still_com_fraction * audit.frames
        self.notes.update(audit.notes)

    def row(self, name: str) -> str:
        def pct(count: float, total: int) -> str:
            return f"{count / total:6.1%}" if total else f"{'-':>6s}"

        def med(values: list[float], fmt: str) -> str:
            return format(statistics.median(values), fmt) if values else "-"

        p99 = f"{1e3 * np.percentile(self.com_errors, 99):.0f}" if self.com_errors else "-"
        p90 = f"{np.percentile(self.cost, 90):.3f}" if self.cost else "-"
        link = self.worst_link if len(self.worst_link) <= 20 else self.worst_link[:19] + "~"
        worst = f"{1e3 * self.worst_pen:.0f} {link}" if self.worst_pen > 0 else "-"
        stance = f"{1e3 * self.stance_error:.1f}" if math.isfinite(self.stance_error) else "-"
        cover = f"{statistics.mean(self.coverage):.0%}" if self.coverage else "-"
        tilt = f"{self.tilt:.0f}" if math.isfinite(self.tilt) else "-"
        trunk = f"{self.trunk_tilt:.0f}" if math.isfinite(self.trunk_tilt) else "-"
        jumps = f"{self.root_jumps / max(1, self.runs):.1f}"
        return (
            f"{name:32s} {pct(self.solved, self.runs):>6s} {pct(self.penetrating, self.frames)} "
            f"{worst:>24s} {pct(self.stance_far, self.frames)} {stance:>7s} "
            f"{pct(self.self_frames, self.frames)} "
            f"{pct(self.pops, self.pairs)} {self.max_speed:6.1f} {jumps:>6s} {p99:>6s} "
            f"{tilt:>5s} {trunk:>5s} {cover:>5s} {med(self.pace, '.3f'):>6s} "
            f"{pct(self.still, self.frames)} {med(self.cost, '.3f'):>6s} {p90:>6s} "
            f"{med(self.audit_s, '.1f'):>6s}"
        )


HEADER = (
    f"{'scenario':32s} {'ok':>6s} {'pen':>6s} {'worst mm (link)':>24s} {'far':>6s} "
    f"{'stance':>7s} "
    f"{'self':>6s} {'pops':>6s} {'rad/s':>6s} {'jumps':>6s} {'COM99':>6s} {'tilt':>5s} "
    f"{'trunk':>5s} "
    f"{'cover':>5s} {'pace':>6s} {'still':>6s} {'s/s':>6s} {'s/s90':>6s} {'aud s':>6s}"
)


# 2PAC Table 3: share of dynamically valid samples per kind of scene (paper, section 8)
PAPER_VALIDITY = {"stair": "97 %", "climbing": "56 %", "slope": "85 %", "chair": "100 %"}
PACE_HEADER = (
    f"{'scenario':32s} {'pace':>6s} {'stride':>6s} {'still':>6s} {'valid':>6s} "
    f"{'whole':>6s} {'paper':>6s} {'chg':>5s} {'s/chg':>6s} {'bob mm':>6s} {'ovl':>4s}"
)


def _strides(states: Any) -> list[float]:
    """Per limb, how far (m) each contact moved from the same limb's previous contact."""
    last: dict[str, Any] = {}
    out = []
    for state in states:
        for contact in state.contacts:
            previous = last.get(contact.limb)
            moved = 0.0 if previous is None else float(np.linalg.norm(contact.position - previous))
            if moved > 1e-6:
                out.append(moved)
            last[contact.limb] = contact.position
    return out


def _pace_row(name: str, tally: Tally) -> str:
    def med(values: list[Any], fmt: str) -> str:
        return format(statistics.median(values), fmt) if values else "-"

    still = f"{tally.still / tally.frames:6.1%}" if tally.frames else "-"
    valid = f"{statistics.mean(tally.validity):6.1%}" if tally.validity else "-"
    whole = (
        f"{sum(v >= 1.0 for v in tally.validity) / len(tally.validity):6.1%}"
        if tally.validity
        else "-"
    )
    paper = next((v for k, v in PAPER_VALIDITY.items() if k in name), "-")
    return (
        f"{name:32s} {med(tally.pace, '.3f'):>6s} {med(tally.strides, '.2f'):>6s} {still:>6s} "
        f"{valid:>6s} {whole:>6s} {paper:>6s} {med(tally.changes, '.0f'):>5s} "
        f"{med(tally.per_change, '.3f'):>6s} {med([1e3 * b for b in tally.bob], '.0f'):>6s} "
        f"{med(tally.overlapped, '.0f'):>4s}"
    )


def _duration(keyframes: Any) -> float:
    return float(keyframes[-1].t - keyframes[0].t) if len(keyframes) >= 2 else 0.0


def _audit(tally: Tally, *args: Any, **kwargs: Any) -> MotionAudit:
    start = time.perf_counter()
    audit = audit_from_domain(*args, **kwargs)
    tally.audit_s.append(time.perf_counter() - start)
    tally.add(audit)
    return audit


MAX_NUDGE_MM = 50.0  # a nudge, not another scenario: a start moved further may not stand
NUDGE_STREAM = 7  # the second word of the seed of a start's nudge (any constant will do)


def nudged_start(start: dict[str, Any], seed: int, radius_m: float) -> dict[str, Any]:
    """A scenario's ``start`` (``stand_at`` or root ``position``, m) moved horizontally to a
    point of the disc of ``radius_m`` around it, drawn from ``seed`` (a stream of its own:
    the planner's draws from the same seed are not changed); the start itself at 0."""
    moved = copy.deepcopy(start)
    if radius_m <= 0.0:
        return moved
    draw = np.random.default_rng([seed, NUDGE_STREAM]).random(2)
    r, angle = radius_m * math.sqrt(float(draw[0])), 2.0 * math.pi * float(draw[1])
    point = moved["stand_at" if "stand_at" in moved else "position"]
    point[0] += r * math.cos(angle)
    point[1] += r * math.sin(angle)
    return moved


def bench_plans(
    files: Iterable[Path], seeds: int, clock_cap_s: float | None = None, nudge_m: float = 0.0
) -> list[tuple[str, Tally]]:
    """Audit every plan scenario over ``seeds`` seeds (starts nudged up to ``nudge_m`` m:
    :func:`nudged_start`); the tallies for the pace table."""
    tallies = []
    for file in files:
        spec = json.loads(file.read_text())
        scene = scenario_scene(spec)
        if scene is None:
            print(f"{file.stem:32s} skipped: scene not installed", flush=True)
            continue
        character = get_character(spec["character"])
        data = load_offline_data(character, gecko_cache_dir())
        tally = Tally()
        wall = time.perf_counter()
        for i in range(seeds):
            seed = int(spec["seed"]) + i
            start = time.perf_counter()
            result = plan_contact_motion(
                scene,
                character,
                data,
                scenario_endpoint(nudged_start(spec["start"], seed, nudge_m)),
                scenario_endpoint(spec["goal"]),
                rng=np.random.default_rng(seed),
                time_budget_s=float(spec["time_budget_s"]),
                options=scenario_options(spec),
                cap_s=clock_cap_s,
            )
            seconds = time.perf_counter() - start
            if result.stats.get("clock_cap_hit"):
                print(
                    f"{file.stem} seed {seed}: the wall-clock cap stopped "
                    "the work before its budget (a busy machine?): its figures are cut; "
                    "--clock-cap raises the cap",
                    file=sys.stderr,
                )
            tally.runs += 1
            tally.solved += result.status.value == "SOLVED"
            plan = result.value
            motion = None if plan is None else plan.motion
            if plan is not None and len(plan.states) > 1:
                tally.changes.append(len(plan.states) - 1)
                tally.per_change.append(seconds / (len(plan.states) - 1))
                tally.strides.extend(_strides(plan.states))
            if motion is None or not motion.keyframes:
                continue
            tally.overlapped.append(int(motion.report.get("overlapped_swings", 0)))
            report = motion.report.get("dynamic_validity", [])
            tally.validity.extend(float(r["fraction_valid"]) for r in report)
            duration = _duration(motion.keyframes)
            if duration > 0:
                tally.cost.append(seconds / duration)
            audit = _audit(
                tally, spec["character"], scene, motion.keyframes, motion.phases, motion.com
            )
            if spec["scene"] == "flat" and len(audit.coms):
                tally.bob.append(float(np.ptp(audit.coms[:, 2])))
        print(f"{tally.row(file.stem)}  [{time.perf_counter() - wall:.0f} s]", flush=True)
        for note in sorted(tally.notes):
            print(f"{'':32s} note: {note}")
        tallies.append((file.stem, tally))
    return tallies


def bench_twister(seeds: int) -> None:
    from tests.planner.contact.twister_game import play

    for file in sorted(TWISTER.glob("*.json")):
        spec = json.loads(file.read_text())
        tally = Tally()
        wall = time.perf_counter()
        for i in range(seeds):
            game = dict(spec, seed=int(spec["seed"]) + i)
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / file.name
                path.write_text(json.dumps(game))
                moves = play(path)
            tally.runs += 1
            tally.solved += sum(m.result.ok for m in moves) / max(1, len(moves))
            compute = sum(m.result.timings.get("total", 0.0) for m in moves)
            animated = 0.0
            for move in moves:
                result = move.result
                if not result.ok or not result.keyframes:
                    continue
                animated += _duration(result.keyframes)
                _audit(
                    tally,
                    move.ctx.character.id,
                    move.ctx.scene,
                    result.keyframes,
                    result.phases,
                    result.com,
                )
            if animated > 0:
                tally.cost.append(compute / animated)
        label = f"twister {file.stem}"
        print(f"{tally.row(label)}  [{time.perf_counter() - wall:.0f} s]", flush=True)


def bench_jumps(seeds: int) -> None:
    """Jump scenarios through the auditor, then per scenario the jump figures: keyframe COM
    against each jump's parabola in flight (max, mm; the jump's takeoff position and
    velocity taken as the COM's), the peak finite-difference COM acceleration of the
    keyframes within 0.1 s of a takeoff and of a landing (m/s^2), and the push and landing
    accelerations the plan asked for (max)."""
    from planner.ballistic.planner import plan_jumps
    from tests.scenarios.jumps.scenario import scenarios

    extra: list[str] = []
    for scenario in scenarios():
        loaded = scenario.load()
        label = f"jump {scenario.name}"
        if loaded is None:
            print(f"{label:32s} skipped: scene not installed", flush=True)
            continue
        scene, character, data = loaded
        tally = Tally()
        wall = time.perf_counter()
        figures: dict[str, list[float]] = {"parabola": [], "takeoff": [], "landing": []}
        planned: list[float] = []
        for i in range(seeds):
            start = time.perf_counter()
            result = plan_jumps(
                scene,
                character,
                data,
                scenario.end("start"),
                scenario.end("goal"),
                rng=np.random.default_rng(scenario.seed + i),
                params=scenario.params(),
            )
            seconds = time.perf_counter() - start
            tally.runs += 1
            tally.solved += result.status.value == "SOLVED"
            plan = result.value
            if plan is None or not plan.keyframes:
                continue
            duration = _duration(plan.keyframes)
            if duration > 0:
                tally.cost.append(seconds / duration)
            # old answers have no push/landing times: their flights are break..create
            flights = [
                (getattr(j, "push_start", j.contact_break), getattr(j, "rest", j.contact_create))
                for j in plan.jumps
            ]
            phases = getattr(plan, "phases", ()) or _jump_phases(plan)
            start = time.perf_counter()
            audit = audit_from_domain(
                character.id, scene, plan.keyframes, phases, getattr(plan, "com", ()), flights
            )
            tally.audit_s.append(time.perf_counter() - start)
            tally.add(audit)
            _jump_figures(plan, audit, figures, planned)
        print(f"{tally.row(label)}  [{time.perf_counter() - wall:.0f} s]", flush=True)

        def top(values: list[float]) -> str:
            return f"{max(values):8.1f}" if values else f"{'-':>8s}"

        extra.append(
            f"{label:32s} {top([1e3 * v for v in figures['parabola']])} "
            f"{top(figures['takeoff'])} {top(figures['landing'])} {top(planned)}"
        )
    print(
        f"\n{'jump scenario':32s} {'par. mm':>8s} {'a takeoff':>8s} {'a landing':>8s} "
        f"{'planned':>8s}  (max over seeds; COM accelerations m/s^2, 3 g = 29.4)"
    )
    for line in extra:
        print(line)


def _jump_figures(
    plan: Any, audit: MotionAudit, figures: dict[str, list[float]], planned: list[float]
) -> None:
    """Append a jump plan's parabola error (m), peak COM accelerations near takeoffs and
    landings (m/s^2, finite differences of the auditor's keyframe COMs) and the planned
    push and landing accelerations (m/s^2)."""
    gravity = np.array([0.0, 0.0, -9.81])
    times, coms = audit.times, audit.coms
    if len(times) < 3:
        return
    steps = np.diff(times)
    accel = np.linalg.norm(coms[2:] - 2.0 * coms[1:-1] + coms[:-2], axis=1) / (
        steps[1:] * steps[:-1]
    )
    middle = times[1:-1]
    for jump in plan.jumps:
        inside = (times >= jump.contact_break - 1e-9) & (times <= jump.contact_create + 1e-9)
        tau = times[inside] - jump.contact_break
        expect = (
            jump.takeoff.position
            + np.outer(tau, jump.takeoff.velocity)
            + 0.5 * np.outer(tau**2, gravity)
        )
        if inside.any():
            figures["parabola"].append(float(np.linalg.norm(coms[inside] - expect, axis=1).max()))
        for key, when in (("takeoff", jump.contact_break), ("landing", jump.contact_create)):
            near = np.abs(middle - when) <= 0.1
            if near.any():
                figures[key].append(float(accel[near].max()))
        for name in ("push_acceleration", "landing_acceleration"):
            if hasattr(jump, name):
                planned.append(float(np.linalg.norm(getattr(jump, name))))


@dataclass(frozen=True)
class _Contact:
    limb: str
    points: Any


@dataclass(frozen=True)
class _Phase:
    t0: float
    t1: float
    contacts: tuple[_Contact, ...]


def _jump_phases(plan: Any) -> list[_Phase]:
    """Stance phases of a jump plan: before each takeoff (its contacts) and after the last
    landing (its contacts), each contact one point."""
    phases = []
    t = float(plan.keyframes[0].t)
    for jump in plan.jumps:
        contacts = tuple(_Contact(c.limb, np.asarray(c.point)[None]) for c in jump.takeoff.contacts)
        phases.append(_Phase(t, float(jump.contact_break), contacts))
        t = float(jump.contact_create)
    if plan.jumps:
        last = plan.jumps[-1].landing.contacts
        contacts = tuple(_Contact(c.limb, np.asarray(c.point)[None]) for c in last)
        phases.append(_Phase(t, float(plan.keyframes[-1].t), contacts))
    return phases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--scenario", action="append", default=[])
    parser.add_argument("--twister", action="store_true", help="also the Twister games")
    parser.add_argument("--jumps", action="store_true", help="also the jump scenarios")
    parser.add_argument(
        "--clock-cap",
        type=float,
        default=None,
        help="s of wall clock a plan may take (default: its time budget, as in the service); "
        "a larger cap keeps a busy machine's clock from cutting the work (the work budget, "
        "not the clock, decides the answer)",
    )
    parser.add_argument(
        "--nudge",
        type=float,
        default=0.0,
        metavar="MM",
        help="move each run's start horizontally by up to MM millimetres (drawn from its "
        f"seed; at most {MAX_NUDGE_MM:g}); 0 (the default): the scenario's own start",
    )
    args = parser.parse_args()
    if not 0.0 <= args.nudge <= MAX_NUDGE_MM:
        parser.error(f"--nudge: between 0 and {MAX_NUDGE_MM:g} mm, got {args.nudge:g}")
    files = sorted(PLANS.glob("*.json"))
    if args.scenario:
        files = [f for f in files if f.stem in args.scenario]
    print(TARGETS)
    if args.nudge:
        print(f"starts nudged by up to {args.nudge:g} mm")
    print(HEADER, flush=True)
    tallies = bench_plans(files, args.seeds, args.clock_cap, 1e-3 * args.nudge)
    print(
        "\npace (issue 13 targets: humanoid flat >= 0.5 m/s with validity >= 97 %, stairs >= "
        "0.25 m/s, quadruped flat >= 0.5 m/s; <= 0.05 s per contact change)"
    )
    print(PACE_HEADER)
    for name, tally in tallies:
        print(_pace_row(name, tally), flush=True)
    if args.twister:
        bench_twister(args.seeds)
    if args.jumps:
        bench_jumps(args.seeds)


if __name__ == "__main__":
    main()
