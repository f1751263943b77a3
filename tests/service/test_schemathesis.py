"""Schemathesis against the live OpenAPI document of a real server (uvicorn on a port): every
answer conforms to the document (status, content type, headers, body schema) and none is a
5xx. A short, derandomized run: a few generated requests per operation, positive and
negative, plus explicit requests that reach the planners (a Twister game of two moves, short
plans with each kind of endpoint, jumps on a small roadmap, an asynchronous plan).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis.errors import Unsatisfiable
from schemathesis.config import SchemathesisConfig
from schemathesis.generation import GenerationMode
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    positive_data_acceptance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)
from schemathesis.specs.openapi.schemas import OpenApiSchema

from service.settings import Settings
from tests.live_server import live_server
from tests.paths import gecko_cache_dir

GENERATED_PER_OPERATION = 5
# Every answer is checked for these (and never to be a server error).
CONFORMANCE = [
    status_code_conformance,
    content_type_conformance,
    positive_data_acceptance,
    response_headers_conformance,
    response_schema_conformance,
]
SMALL_BUDGET_S = 4.0


@pytest.fixture(scope="module")
def fuzz_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A server of its own (the run deletes and uploads): two planning processes."""
    home: Path = tmp_path_factory.mktemp("gecko-fuzz")
    server_settings = Settings(
        home=home,
        cache_dir=gecko_cache_dir(),
        scenes_dir=home / "scenes",
        characters="humanoid,quadruped",
        worker_processes=2,
        max_upload_bytes=200_000,
        log_level="warning",
    )
    with live_server(server_settings) as url:
        yield url


@pytest.fixture(scope="module")
def api_schema(fuzz_url: str) -> OpenApiSchema:
    config = SchemathesisConfig.from_dict(
        {
            "seed": 1,
            "phases": {
                "examples": {"enabled": False},  # the planning examples are run below, cheaper
                "coverage": {"enabled": False},
                "stateful": {"enabled": False},
                "fuzzing": {"enabled": True},
            },
            "generation": {"mode": "all", "deterministic": True, "database": "none"},
            "request-timeout": 120,
        }
    )
    return schemathesis.openapi.from_url(f"{fuzz_url}/openapi.json", config=config)


def _run_generated(operation: Any, mode: GenerationMode) -> str | None:
    """A few generated requests of one operation in one mode, each checked (every default
    check: no 5xx, conformance, negative data refused); the first failure, as text."""
    excluded = []
    if operation.label == "POST /v1/scenes":
        # Any bytes are a schema-valid mesh body; most are no mesh at all: 422 is the answer.
        excluded.append(positive_data_acceptance)

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(
        max_examples=GENERATED_PER_OPERATION,
        derandomize=True,
        deadline=None,
        database=None,
        phases=[Phase.explicit, Phase.generate],  # no shrinking: report, do not minimise
        suppress_health_check=list(HealthCheck),
    )
    def check(case: Any) -> None:
        response = case.call(timeout=120)
        case.validate_response(response, excluded_checks=excluded)

    try:
        check()
    except Unsatisfiable:  # nothing of the operation can be made invalid (no parameters)
        assert mode is GenerationMode.NEGATIVE, operation.label
    except (Exception, BaseExceptionGroup) as exc:  # one report for every operation, below
        return f"{operation.label} [{mode}]: {exc!s:.3000}"
    return None


def test_generated_requests_conform(api_schema: OpenApiSchema) -> None:
    failures: list[str] = []
    operations = 0
    for result in api_schema.get_all_operations():
        operation = result.ok()
        operations += 1
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            failure = _run_generated(operation, mode)
            if failure is not None:
                failures.append(failure)
    assert operations >= 20
    assert not failures, "\n\n".join(failures)


def _example(spec: dict[str, Any], name: str) -> dict[str, Any]:
    examples = spec["components"]["schemas"][name]["examples"]
    return dict(examples[0])


def _call(api_schema: OpenApiSchema, method: str, path: str, **kwargs: Any) -> Any:
    """One explicit request, validated like the generated ones; the response."""
    case = api_schema[path][method].Case(**kwargs)
    response = case.call(timeout=120)
    case.validate_response(response, checks=CONFORMANCE)
    assert response.status_code < 500, response.text
    return response


def test_explicit_requests_reach_the_planners(api_schema: OpenApiSchema, fuzz_url: str) -> None:
    spec = httpx.get(f"{fuzz_url}/openapi.json", timeout=30).json()
    answers: dict[str, str] = {}

    # The documented Twister example, then a move from the state it answered.
    first = _example(spec, "TwisterStepRequest") | {"time_budget_s": SMALL_BUDGET_S}
    step = _call(api_schema, "POST", "/v1/twister/step", body=first)
    assert step.status_code == 200
    answers["step"] = step.json()["status"]
    state = step.json()["state"]
    following = {k: v for k, v in first.items() if k != "stand_at"} | {
        "state": state,
        "action": {"kind": "auto"},
    }
    assert _call(api_schema, "POST", "/v1/twister/step", body=following).status_code == 200

    # The documented plan (shorter, on a small budget), and one between root poses.
    plan = _example(spec, "PlanRequest") | {"time_budget_s": SMALL_BUDGET_S}
    plan["goal"] = {"stand_at": [0.5, 0.0, 0.0]}
    answered = _call(api_schema, "POST", "/v1/plans", body=plan)
    assert answered.status_code == 200
    answers["plan"] = answered.json()["status"]
    poses = plan | {"start": {"position": [0.0, 0.0, 0.9]}, "goal": {"position": [0.4, 0, 0.9]}}
    assert _call(api_schema, "POST", "/v1/plans", body=poses).status_code == 200
    plan_id = answered.json()["id"]
    _call(api_schema, "GET", "/v1/plans/{plan_id}", path_parameters={"plan_id": plan_id})

    # An asynchronous plan: 202, then its job.
    queued = _call(api_schema, "POST", "/v1/plans", body=plan | {"async": True, "seed": 9})
    assert queued.status_code == 202
    job_path = {"job_id": queued.json()["id"]}
    deadline = time.monotonic() + 120
    while _call(api_schema, "GET", "/v1/jobs/{job_id}", path_parameters=job_path).json()[
        "status"
    ] in ("queued", "running"):
        assert time.monotonic() < deadline, "the asynchronous plan never finished"
        time.sleep(0.2)

    # A small roadmap, then the documented jump on it.
    roadmap = {"character": "quadruped", "scene": "gaps", "nodes": 60, "seed": 3}
    built = _call(api_schema, "POST", "/v1/roadmaps", body=roadmap)
    assert built.status_code in (200, 202)
    rid = {"roadmap_id": built.json()["id"]}
    while (
        status := _call(api_schema, "GET", "/v1/roadmaps/{roadmap_id}", path_parameters=rid)
    ).json()["status"] != "done":
        assert status.json()["status"] in ("queued", "running"), status.text
        assert time.monotonic() < deadline, "the roadmap was never built"
        time.sleep(0.2)
    jump = _example(spec, "JumpRequest") | {
        "roadmap": rid["roadmap_id"],
        "time_budget_s": SMALL_BUDGET_S,
    }
    jumped = _call(api_schema, "POST", "/v1/jumps", body=jump)
    assert jumped.status_code == 200
    answers["jump"] = jumped.json()["status"]
    print(f"planners reached: {answers}")
    assert set(answers) == {"step", "plan", "jump"}
