"""End-to-end contact plans on the scenario JSON files of this folder.

A scenario with ``"solved": true`` must be SOLVED at its seed (or, for the plans listed in
``MOTION_SHORTFALL``, APPROXIMATE with a complete contact plan and a whole-body motion whose
report says what is not clean), and its plan must satisfy the
invariants of the issue: every state's contacts on their surfaces, nothing colliding, static
equilibrium with the margin, consecutive states one contact apart with the others unmoved,
keyframes holding the stance contacts within 1 cm and within the joint limits, the COM curve
inside the kinematic polytopes, and the same seed giving the same plan. Scenarios marked
``"solved": false`` are measured by ``bench/planner.py`` only.
"""

from __future__ import annotations

import itertools
import json
from math import comb
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from planner.character import get_character
from planner.contact.checks import check_state, contact_on_surface, hold_error, within_limits
from planner.contact.context import ContactParams, make_context
from planner.contact.planner import ContactPlan, Endpoint, PlanOptions, plan_contact_motion
from planner.contact.sequence import SequenceParams
from planner.contact.state import ContactState
from planner.motion import tuning
from planner.motion.sequence import phase_kinematics
from planner.offline import load_offline_data
from planner.result import PlanResult, PlanStatus
from planner.scene import Scene
from tests.motion_audit import TILT_TOL_DEG, audit_from_domain
from tests.paths import gecko_cache_dir
from tests.scenarios.jumps.scenes import load_scenario_scene

HERE = Path(__file__).parent
SPECS = {p.stem: json.loads(p.read_text()) for p in sorted(HERE.glob("*.json"))}
SOLVED = sorted(name for name, spec in SPECS.items() if spec.get("solved", True))


def scenario_endpoint(spec: dict[str, list[float]]) -> Endpoint:
    """A scenario's ``start`` or ``goal``: ``stand_at`` [x, y, z] or a root ``position``."""
    if "stand_at" in spec:
        return Endpoint(stand_at=np.asarray(spec["stand_at"], dtype=np.float64))
    pose = np.eye(4)
    pose[:3, 3] = spec["position"]
    return Endpoint(root_pose=pose)


def scenario_scene(spec: dict[str, Any]) -> Scene | None:
    """The scene of a scenario: a built-in id, or a ``{"kind", "name"}`` entry."""
    entry = spec["scene"]
    if isinstance(entry, str):
        entry = {"kind": "builtin", "name": entry}
    return load_scenario_scene(entry)


def scenario_options(spec: dict[str, Any]) -> PlanOptions:
    """The plan options of a scenario (``"options": {"limbs": [...], "max_states": n,
    "margin": N, "max_pitch": rad}``, the service's names; defaults otherwise)."""
    options = spec.get("options", {})
    sequence = SequenceParams(
        max_states=int(options.get("max_states", SequenceParams().max_states))
    )
    contact = ContactParams(margin=float(options.get("margin", ContactParams().margin)))
    pitch = options.get("max_pitch")
    return PlanOptions(
        limbs=tuple(options.get("limbs", ())),
        sequence=sequence,
        contact=contact,
        max_pitch=None if pitch is None else float(pitch),
    )


# s: the wall-clock cap of a scenario's plan in these tests. Its ``time_budget_s`` buys the
# work that decides the plan; the cap (the budget itself in the service) is set out of reach
# so that a busy machine answers the same, only later (bench/planner.py times the plans).
CLOCK_CAP_S = 600.0


def _plan(
    name: str, seed_offset: int = 0, nudge: float = 0.0
) -> tuple[PlanResult[ContactPlan], Any, Any, Any]:
    """The plan of scenario ``name`` at its seed plus ``seed_offset``, its start moved
    ``nudge`` m along x."""
    spec = json.loads(json.dumps(SPECS[name]))
    start = spec["start"]
    start["stand_at" if "stand_at" in start else "position"][0] += nudge
    scene = scenario_scene(spec)
    if scene is None:
        pytest.skip(f"scene of {name} not installed (hpp-environments)")
    character = get_character(spec["character"])
    data = load_offline_data(character, gecko_cache_dir())
    result = plan_contact_motion(
        scene,
        character,
        data,
        scenario_endpoint(spec["start"]),
        scenario_endpoint(spec["goal"]),
        rng=np.random.default_rng(int(spec["seed"]) + seed_offset),
        time_budget_s=float(spec["time_budget_s"]),
        options=scenario_options(spec),
        cap_s=CLOCK_CAP_S,
    )
    return result, scene, character, data


@pytest.fixture(scope="module", params=SOLVED)
def planned(request: pytest.FixtureRequest) -> tuple[str, PlanResult[ContactPlan], Any, Any, Any]:
    return (request.param, *_plan(request.param))


# Plans whose contact sequence is complete but whose whole-body motion the builder cannot yet
# make clean (its own checker finds a keyframe colliding or a stance contact slipping over
# 5 mm): they answer APPROXIMATE with the whole plan and say why in the message (a motion that
# still collides is not SOLVED). Measured on the seed of each scenario; SOLVED is accepted too.
MOTION_SHORTFALL: frozenset[str] = frozenset()  # none today: rubble_quadruped left it when
# footholds kept 3 cm of free radius above them (20 of 20 seeds SOLVED, and the next seed with
# its start 1 mm either way)


def test_solved_and_every_state_valid(planned) -> None:  # type: ignore[no-untyped-def]
    name, result, scene, character, data = planned
    if name in MOTION_SHORTFALL and result.status is PlanStatus.APPROXIMATE:
        assert result.message.startswith("whole-body motion:"), result.message
        assert not result.value.motion.quality.complete
        # contact changes planned again for nothing are undone: the answer's states are
        # the ones first planned, animated on 2PAC's curve
        replans = result.value.motion.report["contact_replans"]
        assert not replans or replans[-1].endswith("all undone"), replans
    else:
        assert result.status is PlanStatus.SOLVED, result.message
        assert result.value.motion.quality.complete
    plan = result.value
    assert plan is not None and len(plan.states) >= 3
    # the scenario's own margin (a 5 kg hexapod asks for less than 1 N)
    ctx = make_context(scene, character, data, scenario_options(SPECS[name]).contact)
    for state in plan.states:
        report = check_state(ctx, state)
        assert report.valid, report
        for contact in state.contacts:
            assert contact_on_surface(ctx, contact)
            surface = scene.surfaces[contact.surface]
            assert np.abs(surface.height(contact.points)).max() <= 0.005
            assert float(contact.normal @ surface.normal) >= np.cos(np.radians(5.0))
    for before, after in zip(plan.states, plan.states[1:], strict=False):
        assert before.differs_by_one(after)


def test_goal_contacts_reached(planned) -> None:  # type: ignore[no-untyped-def]
    name, result, *_ = planned
    plan = result.value
    assert plan is not None
    goal = np.asarray(SPECS[name]["goal"].get("stand_at", [np.nan] * 3))
    last = plan.states[-1]
    if np.all(np.isfinite(goal)):
        centre = np.mean([c.position for c in last.contacts], axis=0)
        assert np.linalg.norm(centre[:2] - goal[:2]) <= 0.15


def test_optional_limbs_used(planned) -> None:  # type: ignore[no-untyped-def]
    """A limb a scenario offers (a hand for the handrail) is put to use, then let go."""
    name, result, *_ = planned
    plan = result.value
    assert plan is not None
    for limb in SPECS[name].get("options", {}).get("limbs", []):
        holding = [s for s in plan.states if s.contact(limb) is not None]
        assert len(holding) >= 3, f"{limb} held in {len(holding)} states"
        assert plan.states[-1].contact(limb) is None


def test_keyframes_hold_contacts_and_com_stays_in_kinematic_polytopes(planned) -> None:  # type: ignore[no-untyped-def]
    name, result, scene, character, data = planned
    plan = result.value
    assert plan is not None and plan.motion is not None
    ctx = make_context(scene, character, data, scenario_options(SPECS[name]).contact)
    phases = plan.motion.phases
    assert plan.motion.keyframes
    for key in plan.motion.keyframes:
        assert within_limits(ctx, np.asarray(key.q), tol=1e-4)
        phase = next((ph for ph in phases if ph.t0 - 1e-9 <= key.t <= ph.t1 + 1e-9), None)
        assert phase is not None
        held = [c for c in phase.contacts if c.limb in key.contacts]
        # a slip over 1 cm only where the answer is APPROXIMATE and its report says so
        slip = plan.motion.quality.max_hold_error if result.status is PlanStatus.APPROXIMATE else 0
        assert hold_error(ctx, np.asarray(key.q), held) <= max(0.01, slip + 0.002)
    # the COM curve inside the kinematic polytopes of the phase in force at each sample (a
    # 2PAC window's segment spans several phases)
    for seg in plan.motion.com:
        n = len(seg.control_points) - 1
        for s in np.linspace(0.0, 1.0, 9):
            t = seg.t0 + s * (seg.t1 - seg.t0)
            phase = next(ph for ph in phases if ph.t0 - 1e-9 <= t <= ph.t1 + 1e-9)
            kin = phase_kinematics(data, ContactState(plan.states[0].q, phase.contacts))
            assert kin is not None
            point = sum(
                comb(n, i) * (1 - s) ** (n - i) * s**i * seg.control_points[i] for i in range(n + 1)
            )
            assert float(np.max(kin.violation(np.asarray(point)))) <= 1e-3, (name, t)


# degrees the chest may lean beyond the pelvis's tilt bound while the hands are free
CHEST_LEAN_DEG = 5.0

# Plans whose keyframes still put a link into the scene or the body (measured by
# bench/motion.py; issue 12 stays open for them): the rest of the audit holds there too.
STILL_COLLIDING: frozenset[str] = frozenset()


def test_keyframes_pass_the_independent_audit(planned) -> None:  # type: ignore[no-untyped-def]
    """The URDF's own collision geometry through Pinocchio and coal against the scene mesh
    (tests/motion_audit.py, no planner code): no joint over its speed limit or 10 rad/s, no
    root jump over 5 cm between 30 Hz keyframes, the keyframe COM within 2 cm of its curve
    (p99), every phase animated; no link over 1 cm into the scene but the stance effectors
    and no self-collision over 1 cm, except on the plans listed as still colliding; a
    character whose trunk stays level (all but the hexapod) never tilts over 30 degrees, nor
    its chest over 35 while its hands are free."""
    name, result, scene, character, _ = planned
    motion = result.value.motion
    audit = audit_from_domain(character.id, scene, motion.keyframes, motion.phases, motion.com)
    assert audit.pops == 0 and audit.root_jumps == 0, audit.summary()
    assert audit.com_error_p99_m <= 0.02, audit.summary()
    assert audit.phases_animated == audit.phases, audit.summary()
    if character.max_pitch <= tuning.LEVEL_TRUNK_PITCH:
        assert audit.tilt_max_deg <= TILT_TOL_DEG, audit.summary()
    hands = {"left_hand", "right_hand"}
    touching = {limb for key in motion.keyframes for limb in key.contacts}
    if hands <= {limb.name for limb in character.limbs} and not hands & touching:
        # hands free (a walk, stairs): the chest does not fold over the pelvis to carry the
        # COM (it leaned 69 degrees on stairs_humanoid and hpp_stair_bauzil_talos)
        assert audit.trunk_tilt_max_deg <= TILT_TOL_DEG + CHEST_LEAN_DEG, audit.summary()
    if name not in STILL_COLLIDING:
        assert audit.penetrating_frames == 0, audit.summary()
        assert audit.self_collision_frames == 0, audit.summary()


def test_the_trunk_never_swivels(planned) -> None:  # type: ignore[no-untyped-def]
    """Between two keyframes the trunk turns about its own vertical axis at most
    ``ROOT_YAW_SPEED`` (2.5 rad/s): it does not snap from side to side to help a foot reach
    (it did at 4.3 rad/s on rubble, where the planned states turn at most 9 degrees)."""
    _, result, *_ = planned
    keyframes = result.value.motion.keyframes
    for a, b in itertools.pairwise(keyframes):
        turn = Rotation.from_quat(a.q[3:7]).inv() * Rotation.from_quat(b.q[3:7])
        speed = abs(turn.as_rotvec()[2]) / (b.t - a.t)  # about a's own z axis
        assert speed <= tuning.ROOT_YAW_SPEED * 1.05, (a.t, speed)


def test_free_arms_move_at_the_pace_of_a_gesture(planned) -> None:  # type: ignore[no-untyped-def]
    """The joints of a limb that never touches anything (the humanoid's and Talos's arms on a
    walk) change speed by at most ``FREE_LIMB_ACCELERATION`` per second between keyframes
    (10 % over it at most; twice it where the bound yields to keeping the arm off the body or
    the scene, at 1 % of the keyframes at most), but for the blend into the goal posture (its
    last ``END_BLEND_S``): they helped the COM by swinging forward to horizontal and back in
    0.15 s (100 rad/s^2 at the 99th percentile on hpp_stair_bauzil_talos)."""
    name, result, *_ = planned
    keyframes = result.value.motion.keyframes
    character = get_character(SPECS[name]["character"])
    touching = {limb for key in keyframes for limb in key.contacts}
    shared = {int(i) for limb in touching for i in character.limb(limb).idx_v}
    free = sorted(
        int(i)
        for limb in character.limbs
        if limb.name not in touching
        for i in limb.idx_v
        if int(i) not in shared
    )
    if not free:
        pytest.skip("every limb touches something")
    model = character.model
    t_blend = keyframes[-1].t - tuning.END_BLEND_S
    speeds = [
        (b.t, pin.difference(model, a.q, b.q)[free] / (b.t - a.t))
        for a, b in itertools.pairwise(keyframes)
    ]
    bound = tuning.FREE_LIMB_ACCELERATION
    over = []
    for (t0, v0), (t1, v1) in itertools.pairwise(speeds):
        if t1 > t_blend:
            break
        acceleration = float(np.max(np.abs(v1 - v0))) / (t1 - t0)
        assert acceleration <= 2.0 * bound, (t1, acceleration)
        if acceleration > 1.1 * bound:
            over.append((t1, acceleration))
    assert len(over) <= 0.01 * len(keyframes), over


def test_a_dynamic_com_slows_only_from_where_the_body_could_not_follow(planned) -> None:  # type: ignore[no-untyped-def]
    """A plan on a dynamic COM gives each phase its factor on the brisk durations, one of
    ``DYNAMIC_SLOWDOWNS`` (a trial the body could not follow is kept but for a window around
    the failing phase, which is slowed, or stops between phases where slowing cannot help);
    where the factors differ the report says which phase failed and why. The keyframes
    stay evenly spaced across the joins (0.5 to 1.5 periods) and the COM curve is C2 there."""
    _check_dynamic_curve(planned[1])


def _check_dynamic_curve(result: PlanResult[ContactPlan]) -> None:
    """The dynamic COM's invariants of ``test_a_dynamic_com_slows_only...``, and the
    motion animating the plan's own states (re-planned ones included), one change apart."""
    plan = result.value
    assert plan is not None and plan.motion is not None
    assert plan.motion.states == plan.states
    assert len(plan.motion.phases) == len(plan.states)
    for a, b in itertools.pairwise(plan.states):
        assert b.differs_by_one(a)
    motion = plan.motion
    report = motion.report
    if report["com_method"] not in ("2pac+dynamic", "2pac+dynamic+rest_to_rest"):
        assert report["dynamic_slowdowns"] is None and report["dynamic_refused"]
        return
    factors = report["dynamic_slowdowns"]
    assert len(factors) == len(result.value.states)
    trials = [str(t) for t in report["dynamic_trials"]]
    # the weight shifts lengthened to their COM's travel when no curve passed otherwise
    stretched = any("weight shifts lengthened" in t for t in trials)
    if report["overlapped_swings"]:  # tried whole, at one of its own factors
        assert len(set(factors)) == 1 and factors[0] in tuning.OVERLAP_PACES
    elif stretched:
        assert all(f >= min(tuning.DYNAMIC_SLOWDOWNS) for f in factors)
    else:
        assert all(f in tuning.DYNAMIC_SLOWDOWNS for f in factors)
    assert report["dynamic_slowdown"] == max(factors)
    if len(set(factors)) > 1:  # a trial refused at a phase, or no curve for the whole plan
        assert trials[0].startswith(("phase ", "no curve passes Eq. 1"))
    methods = report["phase_methods"]
    assert set(methods) <= {"2pac+dynamic", "rest_to_rest"}
    if "rest_to_rest" in methods:  # a window stopping between phases, and why
        assert report["com_method"] == "2pac+dynamic+rest_to_rest"
        assert any("stop at rest between phases" in str(t) for t in report["dynamic_trials"])
    gaps = np.diff([k.t for k in motion.keyframes])
    assert gaps.min() >= 0.5 / 30.0 - 1e-9 and gaps.max() <= 1.5 / 30.0 + 1e-9
    for a, b in itertools.pairwise(motion.com):
        pa, pb = np.asarray(a.control_points), np.asarray(b.control_points)
        va = (pa[-1] - pa[-2]) * (len(pa) - 1) / (a.t1 - a.t0)
        vb = (pb[1] - pb[0]) * (len(pb) - 1) / (b.t1 - b.t0)
        np.testing.assert_allclose(pa[-1], pb[0], atol=1e-6)
        np.testing.assert_allclose(va, vb, atol=1e-4)


def test_a_neighbouring_seed_and_a_nudged_start_solve_too(planned) -> None:  # type: ignore[no-untyped-def]
    """No scenario sits on a knife edge: with the next seed and its start moved 1 mm, the
    plan is as good (SOLVED, or for the plans of ``MOTION_SHORTFALL`` a complete contact
    plan whose motion report says what is not clean)."""
    name = planned[0]
    result = _plan(name, seed_offset=1, nudge=0.001)[0]
    _check_dynamic_curve(result)  # re-planned contact changes joined like the rest
    if name in MOTION_SHORTFALL and result.status is PlanStatus.APPROXIMATE:
        assert result.message.startswith("whole-body motion:"), result.message
    elif name in KNIFE_EDGE and result.status is not PlanStatus.SOLVED:
        pytest.xfail(f"{KNIFE_EDGE[name]}: {result.message}")
    else:
        assert result.status is PlanStatus.SOLVED, result.message


# Scenarios that solve at their seed but not always at the next one with a nudged start
# (issue 12 item 6 stays open for them): the test records how they fail instead.
KNIFE_EDGE: dict[str, str] = {}


# Seeds further from a scenario's own at which its plan once fell short (issue 12: no
# scenario on a knife edge), held to the invariants of the scenario's own seed.
FURTHER_SEEDS = (
    # phase 56's hand hold is out of the tracked body's reach even stopping at rest: the
    # contact changes re-planned there are kept, on 2PAC's curve (the trial builds ran out)
    ("climbing_wall_humanoid", 4),
    # stepping up, the swing foot behind the body, the trunk leaned back 41 degrees before
    # the tracker bounded a level trunk's tilt
    ("stairs_humanoid", 12),
    # its first walk stalls unable to release a leg it left behind; walked on from there,
    # every retry stalled again at 3 m of 4.1 m, started over on a new guide it solves
    ("stairs_handrail_humanoid", 2),
    # a front foot set on the ground hard against a rock's side drove its shin 40 to 60 mm
    # into the rock stepping up, before footholds kept 3 cm of free radius above them
    ("rubble_quadruped", 7),
    # walked on twice from where its first walk stalled, then started over: four walks
    # stalled with a fifth of the search spent before a fifth and sixth walk were allowed;
    # later, reaching for a stair's foothold, the body dropped 0.26 m and tilted its trunk
    # 57 degrees, and no motion could follow (a state's trunk is now bounded)
    ("hpp_stair_bauzil_talos", 11),
    # the searched guide turned Talos 30 to 56 degrees off the way it climbed, its hips at
    # their yaw and roll limits: a stance foot slipped 8 mm (the guide now faces its way)
    ("hpp_stair_bauzil_talos", 9),
    # stepping down, a transition point held the COM 10 cm above the double-support posture
    # the contact planner found, and the straight leg landed 17 mm short of its tread
    ("stairs_down_humanoid", 2),
)


@pytest.mark.parametrize(("name", "offset"), FURTHER_SEEDS)
def test_further_seeds_hold_the_invariants_too(name: str, offset: int) -> None:
    planned = (name, *_plan(name, seed_offset=offset))
    for check in (
        test_solved_and_every_state_valid,
        test_goal_contacts_reached,
        test_optional_limbs_used,
        test_keyframes_hold_contacts_and_com_stays_in_kinematic_polytopes,
        test_keyframes_pass_the_independent_audit,
        test_a_dynamic_com_slows_only_from_where_the_body_could_not_follow,
    ):
        check(planned)


def test_same_seed_same_plan(planned) -> None:  # type: ignore[no-untyped-def]
    name, result, *_ = planned
    again = _plan(name)[0]
    assert again.status is result.status and again.message == result.message
    timeless = {k: v for k, v in result.stats.items() if "second" not in k}
    assert {k: v for k, v in again.stats.items() if "second" not in k} == timeless
    assert result.value is not None and again.value is not None
    assert len(again.value.states) == len(result.value.states)
    for a, b in zip(result.value.states, again.value.states, strict=True):
        assert np.array_equal(a.q, b.q)
    # the keyframes too, bit for bit: nothing an earlier plan of the process left behind (a
    # pooled collision data's GJK guesses once did) may move them
    frames = zip(result.value.motion.keyframes, again.value.motion.keyframes, strict=True)
    for a, b in frames:
        assert a.t == b.t and np.array_equal(a.q, b.q)


@pytest.mark.parametrize("name", ["flat_walk_humanoid", "hpp_ground_talos"])
def test_strides_use_the_legs_reach_on_open_ground(name: str) -> None:
    """On flat open ground the bipeds stride at least 0.4 m (issue 13): each foot moves that
    far between its consecutive contacts, at the median."""
    result, _, _, _ = _plan(name)
    assert result.status is PlanStatus.SOLVED, result.message
    last: dict[str, np.ndarray] = {}
    strides = []
    for state in result.value.states:
        for contact in state.contacts:
            previous = last.get(contact.limb)
            if previous is not None and float(np.linalg.norm(contact.position - previous)) > 1e-6:
                strides.append(float(np.linalg.norm(contact.position - previous)))
            last[contact.limb] = contact.position
    assert strides and float(np.median(strides)) >= 0.4, strides
