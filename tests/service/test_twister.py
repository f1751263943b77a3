"""POST /v1/twister/step over HTTP: moves, chained states, structured failures, bad input."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

pytestmark = pytest.mark.anyio


def _limbs(state: dict[str, Any]) -> set[str]:
    return {c["limb"] for c in state["contacts"]}


async def _step(client: httpx.AsyncClient, **body: Any) -> dict[str, Any]:
    request = {"character": "quadruped", "scene": "twister", "seed": 3, **body}
    response = await client.post("/v1/twister/step", json=request, timeout=120)
    assert response.status_code == 200, response.text
    return dict(response.json())


async def test_break_then_create_chains_states(client: httpx.AsyncClient) -> None:
    detail = (await client.get("/v1/characters/quadruped")).json()
    limb = detail["limbs"][0]["name"]
    first = await _step(client, stand_at=[0.0, 0.0, 0.0], action={"kind": "break", "limb": limb})
    assert first["status"] == "SOLVED", first["failure"]
    assert limb not in _limbs(first["state"])
    assert first["keyframes"] and first["phases"] and first["com"]
    second = await _step(client, state=first["state"], action={"kind": "create", "limb": limb})
    assert second["status"] == "SOLVED", second["failure"]
    assert _limbs(second["state"]) == _limbs(first["state"]) | {limb}
    assert len(_limbs(second["state"]) ^ _limbs(first["state"])) == 1


async def test_humanoid_sits_on_the_chair_and_stands_up(client: httpx.AsyncClient) -> None:
    """The chair scenario over HTTP: stand facing away from the seat, sit on both sit bones,
    get up again; every answer chains from the previous state."""
    chair = {"character": "humanoid", "scene": "chair"}
    first = await _step(
        client,
        **chair,
        stand_at=[0.15, 0.0, 0.0],
        yaw=3.141592653589793,
        action={"kind": "create", "limb": "left_seat", "target": [0.3, -0.09, 0.45]},
    )
    assert first["status"] == "SOLVED", first["failure"]
    sat = await _step(
        client,
        **chair,
        state=first["state"],
        action={"kind": "create", "limb": "right_seat", "target": [0.3, 0.09, 0.45]},
    )
    assert sat["status"] == "SOLVED", sat["failure"]
    assert {"left_seat", "right_seat"} <= _limbs(sat["state"])
    seat_heights = [
        p[2] for c in sat["state"]["contacts"] if c["limb"].endswith("seat") for p in c["points"]
    ]
    assert seat_heights == pytest.approx([0.45] * len(seat_heights), abs=5e-3)
    state = sat["state"]
    for limb in ("right_seat", "left_seat"):
        up = await _step(client, **chair, state=state, action={"kind": "break", "limb": limb})
        assert up["status"] == "SOLVED", up["failure"]
        state = up["state"]
    assert _limbs(state) == {"left_foot", "right_foot"}


async def test_impossible_move_is_a_structured_failure(client: httpx.AsyncClient) -> None:
    detail = (await client.get("/v1/characters/quadruped")).json()
    limb = detail["limbs"][0]["name"]
    answer = await _step(client, stand_at=[0.0, 0.0, 0.0], action={"kind": "create", "limb": limb})
    assert answer["status"] == "INFEASIBLE"
    assert answer["failure"]["reason"] == "ALREADY_IN_CONTACT"
    assert answer["failure"]["limb"] == limb


async def test_same_seed_same_step(client: httpx.AsyncClient) -> None:
    first = await _step(client, stand_at=[0.0, 0.0, 0.0], action={"kind": "auto"})
    second = await _step(client, stand_at=[0.0, 0.0, 0.0], action={"kind": "auto"})
    first.pop("timings")
    second.pop("timings")
    assert first == second
    assert first["report"]["clock_cap_hit"] is False  # the seed decided, not the clock


@pytest.mark.parametrize(
    ("body", "status", "field"),
    [
        ({"action": {"kind": "create"}, "stand_at": [0, 0, 0]}, 422, "action"),
        ({"action": {"kind": "dance", "limb": "x"}, "stand_at": [0, 0, 0]}, 422, "action.kind"),
        ({"action": {"kind": "auto"}}, 422, "body"),
        ({"action": {"kind": "auto"}, "stand_at": [0, 0, 0], "yaw": 9.0}, 422, "yaw"),
        ({"action": {"kind": "break", "limb": "tail"}, "stand_at": [0, 0, 0]}, 422, "action.limb"),
        (
            {"action": {"kind": "auto"}, "stand_at": [0, 0, 0], "options": {"speed": 5}},
            422,
            "options.speed",
        ),
        (
            {"action": {"kind": "auto"}, "stand_at": [0, 0, 0], "options": {"lookahead": 0.2}},
            422,
            "options.lookahead",
        ),
        (
            {"action": {"kind": "auto"}, "stand_at": [0, 0, 0], "time_budget_s": 100},
            422,
            "time_budget_s",
        ),
        (
            {"action": {"kind": "auto"}, "stand_at": [0, 0, 0], "character": "ghost"},
            404,
            "character",
        ),
        (
            {
                "action": {"kind": "auto"},
                "stand_at": [0, 0, 0],
                "others": [
                    {
                        "character": "ghost",
                        "configuration": {"root": {"position": [1, 0, 1]}, "joints": {}},
                    }
                ],
            },
            404,
            "others.0.character",
        ),
    ],
)
async def test_bad_requests(
    client: httpx.AsyncClient, body: dict[str, Any], status: int, field: str
) -> None:
    request = {"character": "quadruped", "scene": "twister", **body}
    response = await client.post("/v1/twister/step", json=request, timeout=120)
    assert response.status_code == status, response.text
    assert response.json()["error"]["field"].startswith(field)


async def test_speed_times_the_step(client: httpx.AsyncClient) -> None:
    """``options.speed`` divides a step's durations, as for a plan; the report says it."""
    move = {"stand_at": [0.0, 0.0, 0.0], "action": {"kind": "break", "limb": "lf_foot"}}
    nominal = await _step(client, **move)
    fast = await _step(client, **move, options={"speed": 2.0})
    assert nominal["status"] == fast["status"] == "SOLVED"
    assert fast["report"]["speed"] == 2.0 and nominal["report"]["speed"] == 1.0
    assert fast["phases"][-1]["t1"] < nominal["phases"][-1]["t1"]
    assert fast["state"] == nominal["state"]  # the same move, only faster
