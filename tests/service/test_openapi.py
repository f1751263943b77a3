"""The OpenAPI document says what the service answers; /docs loads nothing from a CDN."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest
from pydantic import ValidationError

from planner.result import PlanStatus
from service.schemas import EndpointIn, StepActionIn, TwisterStepRequest

pytestmark = pytest.mark.anyio
ERROR_REF = "#/components/schemas/ErrorBody"


async def _spec(client: httpx.AsyncClient) -> dict[str, Any]:
    response = await client.get("/openapi.json")
    assert response.status_code == 200
    return dict(response.json())


def _operations(spec: dict[str, Any]) -> dict[tuple[str, str], dict[str, Any]]:
    return {
        (method.upper(), path): operation
        for path, item in spec["paths"].items()
        for method, operation in item.items()
    }


async def test_every_error_answer_is_the_error_envelope(client: httpx.AsyncClient) -> None:
    spec = await _spec(client)
    assert "HTTPValidationError" not in spec["components"]["schemas"]
    for key, operation in _operations(spec).items():
        for code, response in operation["responses"].items():
            if int(code) < 400:
                continue
            schema = response["content"]["application/json"]["schema"]
            assert schema == {"$ref": ERROR_REF}, (key, code)
            assert response["description"], (key, code)


async def test_routes_document_the_errors_they_give(client: httpx.AsyncClient) -> None:
    operations = _operations(await _spec(client))

    def codes(method: str, path: str) -> set[str]:
        return set(operations[(method, path)]["responses"])

    for path in ("/v1/plans", "/v1/twister/step", "/v1/jumps"):
        assert {"200", "404", "422", "503", "504"} <= codes("POST", path), path
    for path in ("/v1/plans/{plan_id}", "/v1/twister/steps/{step_id}", "/v1/jumps/{jump_id}"):
        assert {"200", "400", "404", "409", "410", "422"} <= codes("GET", path), path
    assert codes("POST", "/v1/roadmaps") >= {"200", "202", "404", "422"}
    assert codes("DELETE", "/v1/scenes/{scene_id}") == {"204", "403", "404"}
    assert codes("POST", "/v1/scenes") >= {"201", "413", "422"}
    # A free-text id in the path cannot be refused as invalid: no 422 is promised there.
    assert codes("GET", "/v1/characters/{character_id}") == {"200", "404"}
    # Job lookups wait for no writer, but a store locked past its timeout is a 503.
    assert codes("GET", "/v1/roadmaps/{roadmap_id}") == {"200", "404", "503"}
    assert codes("GET", "/v1/jobs/{job_id}") == {"200", "404", "503"}
    assert codes("GET", "/health") == {"200"}
    assert "/metrics" in {path for _, path in operations}


async def test_statuses_are_enums(client: httpx.AsyncClient) -> None:
    schemas = (await _spec(client))["components"]["schemas"]
    everything = {status.value for status in PlanStatus}
    assert set(schemas["PlanResponse"]["properties"]["status"]["enum"]) == everything
    assert set(schemas["JumpResponse"]["properties"]["status"]["enum"]) == everything
    assert set(schemas["TwisterStepResponse"]["properties"]["status"]["enum"]) == {
        "SOLVED",
        "INFEASIBLE",
    }
    job_states = {"queued", "running", "done", "failed", "cancelled", "interrupted"}
    assert set(schemas["RoadmapStatus"]["properties"]["status"]["enum"]) == job_states
    assert set(schemas["JobStatus"]["properties"]["status"]["enum"]) == job_states


def _one_of_accepts(schema: dict[str, Any], instance: dict[str, Any]) -> bool:
    """The schema's ``oneOf`` of ``required`` + ``not null`` branches, evaluated."""
    matching = 0
    for branch in schema["oneOf"]:
        (name,) = branch["required"]
        assert branch["properties"][name] == {"not": {"type": "null"}}
        matching += instance.get(name) is not None
    return matching == 1


@pytest.mark.parametrize(
    ("model", "schema_name", "first", "second"),
    [
        (EndpointIn, "EndpointIn", "position", "stand_at"),
        (TwisterStepRequest, "TwisterStepRequest", "state", "stand_at"),
    ],
)
async def test_exactly_one_of_is_in_the_schema_and_agrees_with_the_server(
    client: httpx.AsyncClient, model: Any, schema_name: str, first: str, second: str
) -> None:
    schema = (await _spec(client))["components"]["schemas"][schema_name]
    values = {
        "position": [0.0, 0.0, 0.9],
        "stand_at": [0.0, 0.0, 0.0],
        "state": {
            "configuration": {"root": {"position": [0, 0, 0.5]}, "joints": {}},
            "contacts": [],
        },
    }
    base = {"character": "quadruped", "scene": "flat", "action": {"kind": "auto"}}
    base = base if model is TwisterStepRequest else {}
    for instance in (
        {first: values[first]},
        {second: values[second]},
        {first: values[first], second: values[second]},
        {},
        {first: None, second: values[second]},
        {first: values[first], second: None},
    ):
        try:
            model.model_validate({**base, **instance})
            accepted = True
        except ValidationError:
            accepted = False
        assert _one_of_accepts(schema, instance) == accepted, instance
    assert "exactly one" in schema["description"]


async def test_json_bodies_that_do_not_parse_are_documented_400s(
    client: httpx.AsyncClient,
) -> None:
    operations = _operations(await _spec(client))
    for key, operation in operations.items():
        if "application/json" in operation.get("requestBody", {}).get("content", {}):
            assert "400" in operation["responses"], key
    json = {"content-type": "application/json"}
    answer = await client.post("/v1/jumps", content=b"S,\xff\xfe", headers=json)
    assert answer.status_code == 400
    assert answer.json()["error"]["code"] == "invalid_body"
    answer = await client.post("/v1/jumps", content=b"{not json", headers=json)
    assert answer.status_code == 422
    assert answer.json()["error"]["field"] == "body"
    assert "not valid JSON at character 1" in answer.json()["error"]["message"]


async def test_step_actions_and_orientations_say_what_the_server_accepts(
    client: httpx.AsyncClient,
) -> None:
    schemas = (await _spec(client))["components"]["schemas"]
    action = schemas["StepActionIn"]
    for instance, accepted in (
        ({"kind": "auto"}, True),
        ({"kind": "break", "limb": "lf_foot"}, True),
        ({"kind": "break"}, False),
        ({"kind": "create", "limb": None}, False),
    ):
        branches = action["anyOf"]
        auto = instance["kind"] == branches[0]["properties"]["kind"]["const"]
        named = isinstance(instance.get("limb"), str)
        assert auto or named == accepted, instance
        try:
            StepActionIn.model_validate(instance)
            assert accepted, instance
        except ValidationError:
            assert not accepted, instance
    orientation = schemas["EndpointIn"]["properties"]["orientation"]["anyOf"][0]
    assert orientation["not"] == {"prefixItems": [{"const": 0}] * 4}
    for value in ([0, 0, 0, 0], [0.0, -0.0, 0, 0]):
        with pytest.raises(ValidationError, match="non-zero quaternion"):
            EndpointIn.model_validate({"position": [0, 0, 1], "orientation": value})
    huge = EndpointIn.model_validate({"position": [0, 0, 1], "orientation": [1e300, 0, 0, 1e300]})
    assert huge.orientation == pytest.approx((2**-0.5, 0, 0, 2**-0.5))


async def test_requests_carry_examples(client: httpx.AsyncClient) -> None:
    schemas = (await _spec(client))["components"]["schemas"]
    for name in ("PlanRequest", "TwisterStepRequest", "JumpRequest"):
        assert schemas[name]["examples"], name


async def test_docs_load_nothing_from_outside(client: httpx.AsyncClient) -> None:
    page = await client.get("/docs")
    assert page.status_code == 200
    assets = re.findall(r"""(?:src|href)=["']([^"']+)["']""", page.text)
    assert assets
    assert all(asset.startswith("/") for asset in assets), assets
    assert "cdn" not in page.text.lower()
    assert "'/openapi.json'" in page.text or '"/openapi.json"' in page.text
    for asset in assets:
        response = await client.get(asset)
        assert response.status_code == 200, asset
        assert len(response.content) > 500, asset
    assert (await client.get("/redoc")).status_code == 404
