"""POST /v1/plans over HTTP, through the worker process pool."""

from __future__ import annotations

import time
import typing
from typing import Any

import httpx
import numpy as np
import pytest

from planner.character import MAX_PITCH
from planner.motion.sequence import MAX_SPEED, MIN_SPEED
from service import schemas
from trajectory.transition import COST_KINDS

pytestmark = pytest.mark.anyio

WALK = {
    "character": "humanoid",
    "scene": "flat",
    "start": {"stand_at": [0.0, 0.0, 0.0]},
    "goal": {"stand_at": [1.0, 0.0, 0.0]},
    "seed": 7,
    "time_budget_s": 20,
}


def _without_timings(body: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in body.items() if k != "timings"}


async def test_plan_walk_answers_with_phases_and_keyframes(client: httpx.AsyncClient) -> None:
    response = await client.post("/v1/plans", json=WALK, timeout=120)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["seed"] == 7
    assert body["status"] in {"SOLVED", "APPROXIMATE"}
    assert len(body["states"]) >= 2
    assert len(body["phases"]) == len(body["states"])
    times = [k["t"] for k in body["keyframes"]]
    assert times == sorted(times)
    assert body["com"][0]["t0"] == pytest.approx(0.0)
    for a, b in zip(body["com"], body["com"][1:], strict=False):
        assert a["t1"] == pytest.approx(b["t0"])
    for a, b in zip(body["states"], body["states"][1:], strict=False):
        limbs_a = {c["limb"] for c in a["contacts"]}
        limbs_b = {c["limb"] for c in b["contacts"]}
        assert len(limbs_a ^ limbs_b) == 1, "consecutive states differ by one contact"
    for key in ("endpoints", "root_path", "contacts", "motion"):
        assert key in body["timings"]
    quat = body["keyframes"][0]["root"]["orientation"]
    assert np.linalg.norm(quat) == pytest.approx(1.0)


async def test_plan_holds_the_handrail_when_offered_a_hand(client: httpx.AsyncClient) -> None:
    request = {
        "character": "humanoid",
        "scene": "stairs",
        "start": {"stand_at": [0.4, 0.1, 0.0]},
        "goal": {"stand_at": [3.1, 0.1, 0.9]},
        "options": {"limbs": ["left_hand"]},
        "seed": 1,
        "time_budget_s": 30,
    }
    response = await client.post("/v1/plans", json=request, timeout=120)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["status"] == "SOLVED", body["message"]
    held = [p for p in body["phases"] if any(c["limb"] == "left_hand" for c in p["contacts"])]
    assert held, "the hand never took the rail"
    for phase in held:  # on the banister: its top is 0.75 m above the nosings, at least
        hand = next(c for c in phase["contacts"] if c["limb"] == "left_hand")
        assert min(point[2] for point in hand["points"]) > 0.75
    assert all(c["limb"] != "left_hand" for c in body["states"][-1]["contacts"])


async def test_same_seed_same_answer(client: httpx.AsyncClient) -> None:
    first = (await client.post("/v1/plans", json=WALK, timeout=120)).json()
    second = (await client.post("/v1/plans", json=WALK, timeout=120)).json()
    assert _without_timings(first) == _without_timings(second)
    # the work budget, not the clock, decided: the report says the cap did not bind
    assert first["report"]["clock_cap_hit"] is False


async def test_seed_is_drawn_and_echoed(client: httpx.AsyncClient) -> None:
    request = {**WALK, "goal": {"stand_at": [0.3, 0.0, 0.0]}}
    request.pop("seed")
    body = (await client.post("/v1/plans", json=request, timeout=120)).json()
    assert isinstance(body["seed"], int)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"time_budget_s": 61}, "time_budget_s"),
        ({"time_budget_s": 0}, "time_budget_s"),
        ({"start": {"stand_at": [0, 0, 0], "position": [0, 0, 1]}}, "start"),
        ({"start": {}}, "start"),
        ({"goal": {"position": [0, 0, 1], "orientation": [0, 0, 0, 0]}}, "goal"),
        ({"options": {"rate": 1000}}, "options.rate"),
        ({"options": {"limbs": ["tail"]}}, "options.limbs"),
        ({"options": {"limbs": ["left_hand"] * 17}}, "options.limbs"),
        ({"options": {"max_pitch": 0.9}}, "options.max_pitch"),
        ({"options": {"max_pitch": -0.1}}, "options.max_pitch"),
        ({"seed": -1}, "seed"),
        ({"unexpected": 1}, "unexpected"),
        ({"options": {"speed": 0.1}}, "options.speed"),
        ({"options": {"speed": 4}}, "options.speed"),
        ({"options": {"transition_cost": "silly"}}, "options.transition_cost"),
        ({"options": {"cost_strength": 3}}, "options.cost_strength"),
        ({"options": {"overlap_swings": "sometimes"}}, "options.overlap_swings"),
        ({"options": {"attractors": [{"transition": -1, "point": [0, 0, 1]}]}}, "options.attr"),
        ({"options": {"attractors": [{"transition": 0, "point": [0, 1]}]}}, "options.attr"),
        ({"options": {"attractors": [{"transition": 0, "point": [0, 0, 1]}] * 65}}, "options.attr"),
    ],
)
async def test_bad_requests_name_the_field(
    client: httpx.AsyncClient, change: dict[str, Any], field: str
) -> None:
    response = await client.post("/v1/plans", json={**WALK, **change})
    assert response.status_code == 422, response.text
    error = response.json()["error"]
    assert error["field"].startswith(field)


async def test_a_quadruped_overlaps_its_swings_unless_asked_not_to(
    client: httpx.AsyncClient,
) -> None:
    walk = {**WALK, "character": "quadruped", "goal": {"stand_at": [1.5, 0.0, 0.0]}}
    answers = {}
    for overlap in (True, False):
        request = {**walk, "options": {"overlap_swings": overlap}}
        response = await client.post("/v1/plans", json=request, timeout=120)
        assert response.status_code == 200, response.text
        answers[overlap] = body = response.json()
        assert body["status"] == "SOLVED"
        assert len(body["phases"]) == len(body["states"])
        for a, b in zip(body["phases"], body["phases"][1:], strict=False):
            limbs_a = {c["limb"] for c in a["contacts"]}
            limbs_b = {c["limb"] for c in b["contacts"]}
            assert len(limbs_a ^ limbs_b) == 1, "one contact change per phase"
        # the states are the balanced ones planned, the same either way
        assert [len(s["contacts"]) for s in body["states"]].count(2) == 0
    overlapped, alone = answers[True], answers[False]
    assert overlapped["states"] == alone["states"]
    assert overlapped["report"]["overlapped_swings"] > 0
    assert alone["report"]["overlapped_swings"] == 0
    for body in (overlapped, alone):
        both_up = [k for k, p in enumerate(body["phases"]) if len(p["contacts"]) == 2]
        assert body["report"]["overlapped_phases"] == both_up
    assert min(len(p["contacts"]) for p in overlapped["phases"]) == 2  # diagonal legs up
    assert min(len(p["contacts"]) for p in alone["phases"]) == 3
    assert overlapped["keyframes"][-1]["t"] < 0.8 * alone["keyframes"][-1]["t"]


@pytest.mark.parametrize(("key", "value"), [("character", "nobody"), ("scene", "nowhere")])
async def test_unknown_ids_are_404(client: httpx.AsyncClient, key: str, value: str) -> None:
    response = await client.post("/v1/plans", json={**WALK, key: value}, timeout=60)
    assert response.status_code == 404
    assert response.json()["error"]["field"] == key


async def test_unreachable_goal_stops_within_budget(client: httpx.AsyncClient) -> None:
    # the goal stands inside the closed pen: good ground that no path reaches
    request = {**WALK, "scene": "pen", "goal": {"stand_at": [3.0, 0.0, 0.0]}, "time_budget_s": 1}
    await client.get("/health")
    started = time.monotonic()
    response = await client.post("/v1/plans", json=request, timeout=60)
    elapsed = time.monotonic() - started
    assert response.status_code == 200
    assert response.json()["status"] in {"TIMEOUT", "INFEASIBLE"}
    # a hang guard only, far from any machine's speed: the budget itself is checked on a
    # virtual clock in tests/planner/contact/test_plan_budget.py and timed by bench/planner.py
    assert elapsed < 1.0 + 60.0


def test_service_bounds_are_the_planner_bounds() -> None:
    """The schema repeats the planner's bounds (clients import the schemas, never planner)."""
    assert schemas.MAX_PITCH == MAX_PITCH
    assert (schemas.MIN_SPEED, schemas.MAX_SPEED) == (MIN_SPEED, MAX_SPEED)
    assert set(typing.get_args(schemas.TransitionCostKind)) == set(COST_KINDS)


async def test_speed_cost_and_attractors_shape_the_com(client: httpx.AsyncClient) -> None:
    """The paper's user controls over HTTP: a slower plan is longer; "low" lowers the
    transition points; an attractor in balance is honoured where asked, one in the air is
    refused with its reason, one past the plan's changes too."""
    short = {**WALK, "goal": {"stand_at": [0.6, 0.0, 0.0]}}
    plain = (await client.post("/v1/plans", json=short, timeout=120)).json()
    assert plain["report"]["com_method"].startswith("2pac")
    assert len(plain["report"]["phase_methods"]) == len(plain["phases"])
    # a slower plan is longer with the same contacts (at speed 1 the dynamic COM is already
    # brisk: asking for more keeps the fastest curve the body follows cleanly, see README)
    slow = {**short, "options": {"speed": 0.5}}
    slower = (await client.post("/v1/plans", json=slow, timeout=120)).json()
    assert slower["states"] == plain["states"]
    assert slower["keyframes"][-1]["t"] > 1.25 * plain["keyframes"][-1]["t"]
    assert slower["report"]["speed"] == 0.5

    def change_times(body: dict[str, Any]) -> np.ndarray:
        return np.array([p["t1"] for p in body["phases"][:-1]])

    low = {**short, "options": {"transition_cost": "low", "cost_strength": 1.0}}
    lowered = (await client.post("/v1/plans", json=low, timeout=120)).json()
    assert lowered["report"]["transition_cost"] == "low"
    assert lowered["states"] == plain["states"]

    def com_at_changes(body: dict[str, Any]) -> np.ndarray:
        out = []
        for t in change_times(body):
            segment = next(s for s in body["com"] if s["t0"] <= t <= s["t1"])
            points = np.asarray(segment["control_points"])
            u = (t - segment["t0"]) / max(segment["t1"] - segment["t0"], 1e-12)
            while len(points) > 1:
                points = (1 - u) * points[:-1] + u * points[1:]
            out.append(points[0])
        return np.array(out)

    assert com_at_changes(lowered)[:, 2].mean() < com_at_changes(plain)[:, 2].mean() - 0.01
    # as low as the body goes (the states' COMs less COM_BELOW_STATES), and played cleanly
    assert com_at_changes(lowered)[:, 2].min() > com_at_changes(plain)[:, 2].min() - 0.3
    assert lowered["status"] == "SOLVED", lowered["message"]
    first = com_at_changes(plain)[0]
    # over the middle of the support the first change leaves (balanced for both phases),
    # at the height the COM has there
    fewer = min(plain["phases"][:2], key=lambda p: len(p["contacts"]))
    support = np.array([p for c in fewer["contacts"] for p in c["points"]]).mean(axis=0)
    balanced = np.array([support[0], support[1], first[2]])
    asked = {
        **short,
        "options": {
            "attractors": [
                {"transition": 0, "point": balanced.tolist()},
                {"transition": 1, "point": [0.0, 0.0, 5.0]},
                {"transition": 999, "point": first.tolist()},
            ]
        },
    }
    placed = (await client.post("/v1/plans", json=asked, timeout=120)).json()
    verdicts = placed["report"]["attractors"]
    assert [v["honoured"] for v in verdicts] == [True, False, False], verdicts
    assert "equilibrium" in verdicts[1]["reason"] or "reach" in verdicts[1]["reason"]
    assert "phase changes" in verdicts[2]["reason"]
