"""Seeds stay within 2^53 - 1, so JavaScript (and any JSON reader using doubles) replays them."""

from __future__ import annotations

import json

import httpx
import pytest

from service.routes.results import draw_seed
from service.schemas import MAX_SEED

pytestmark = pytest.mark.anyio

STEP = {
    "character": "quadruped",
    "scene": "twister",
    "stand_at": [0.0, 0.0, 0.0],
    "action": {"kind": "break", "limb": "lf_foot"},
    "time_budget_s": 5,
}
PLAN = {
    "character": "humanoid",
    "scene": "flat",
    "start": {"stand_at": [0, 0, 0]},
    "goal": {"stand_at": [0.5, 0, 0]},
}
JUMP = {
    "character": "quadruped",
    "scene": "gaps",
    "start": {"stand_at": [0.75, 0, 0.6]},
    "goal": {"stand_at": [8.25, 0, 1.0]},
}
ROADMAP = {"character": "quadruped", "scene": "gaps", "nodes": 10}
REQUESTS = {
    "/v1/twister/step": STEP,
    "/v1/plans": PLAN,
    "/v1/jumps": JUMP,
    "/v1/roadmaps": ROADMAP,
}


def test_max_seed_is_exact_as_a_double() -> None:
    assert MAX_SEED == 2**53 - 1
    assert int(float(MAX_SEED)) == MAX_SEED
    assert int(float(MAX_SEED + 2)) != MAX_SEED + 2  # the first integer a double cannot hold


def test_drawn_seeds_are_bounded_and_vary() -> None:
    seeds = [draw_seed() for _ in range(2000)]
    assert all(0 <= seed <= MAX_SEED for seed in seeds)
    assert len(set(seeds)) == len(seeds)
    assert max(seeds) > 2**50  # drawn over the whole range, not a small one
    assert all(json.loads(json.dumps(float(seed))) == seed for seed in seeds)


@pytest.mark.parametrize("path", list(REQUESTS))
@pytest.mark.parametrize("seed", [MAX_SEED + 1, 2**63 - 1, -1])
async def test_seeds_out_of_range_are_refused_naming_the_field(
    client: httpx.AsyncClient, path: str, seed: int
) -> None:
    response = await client.post(path, json={**REQUESTS[path], "seed": seed})
    assert response.status_code == 422, response.text
    error = response.json()["error"]
    assert error["field"] == "seed"
    assert "seed" in error["message"]


async def test_openapi_states_the_seed_bound(client: httpx.AsyncClient) -> None:
    spec = (await client.get("/openapi.json")).json()
    schema = spec["components"]["schemas"]["PlanRequest"]["properties"]["seed"]
    bounded = [option for option in schema["anyOf"] if option.get("type") == "integer"]
    assert bounded
    assert bounded[0]["maximum"] == MAX_SEED


async def test_the_largest_seed_is_accepted_and_a_drawn_one_is_bounded(
    client: httpx.AsyncClient,
) -> None:
    largest = await client.post("/v1/twister/step", json={**STEP, "seed": MAX_SEED})
    assert largest.status_code == 200, largest.text
    assert largest.json()["seed"] == MAX_SEED
    drawn = await client.post("/v1/twister/step", json=STEP)
    assert drawn.status_code == 200, drawn.text
    assert 0 <= drawn.json()["seed"] <= MAX_SEED
