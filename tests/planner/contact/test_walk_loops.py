"""A walk that comes back to the contacts it held, without getting further along its guide,
stops there (``SequenceParams.loop_visits``) instead of going round again: the climbing
humanoid's first walk, along the straight guide up the wall, does so at 1.39 m."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from planner.character import get_character
from planner.contact import planner as contact_planner
from planner.contact.planner import plan_contact_motion
from planner.contact.sequence import LOOP_CONTACT_TOLERANCE, SequenceParams
from planner.offline import load_offline_data
from planner.result import PlanStatus
from tests.paths import gecko_cache_dir
from tests.scenarios.plans.test_plans import (
    SPECS,
    scenario_endpoint,
    scenario_options,
    scenario_scene,
)


def _same(a: Any, b: Any) -> bool:
    held = {c.limb: c.position for c in b.contacts}
    return held.keys() == set(a.limbs) and all(
        float(np.linalg.norm(c.position - held[c.limb])) <= LOOP_CONTACT_TOLERANCE
        for c in a.contacts
    )


def test_a_walk_stops_when_it_comes_back_to_its_contacts(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each walk of the climbing humanoid's plan is recorded as the planner makes it. One
    stops on a loop: its last state holds the contacts of one state before it, and of no
    other (it stopped at the first return). The plan still solves, with a later walk."""
    walks: list[Any] = []
    real = contact_planner.contact_sequence

    def recorded(*args: Any, **kwargs: Any) -> Any:
        result = real(*args, **kwargs)
        walks.append(result)
        return result

    monkeypatch.setattr(contact_planner, "contact_sequence", recorded)
    spec = SPECS["climbing_wall_humanoid"]
    spec = json.loads(json.dumps(spec))
    character = get_character(spec["character"])
    plan = plan_contact_motion(
        scenario_scene(spec),
        character,
        load_offline_data(character, gecko_cache_dir()),
        scenario_endpoint(spec["start"]),
        scenario_endpoint(spec["goal"]),
        rng=np.random.default_rng(int(spec["seed"])),
        time_budget_s=float(spec["time_budget_s"]),
        options=scenario_options(spec),
    )
    assert plan.status is PlanStatus.SOLVED, plan.message
    looped = [w for w in walks if w.stats.get("loops")]
    assert looped, [w.message for w in walks]
    walk = looped[0]
    assert walk.status is PlanStatus.APPROXIMATE
    assert f"the same contacts {SequenceParams().loop_visits} times" in walk.message
    states = walk.value
    # it stopped at the first return: the last state's contacts were held once before
    assert sum(_same(states[-1], s) for s in states) == SequenceParams().loop_visits == 2
