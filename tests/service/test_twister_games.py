"""Twister games as a client plays them: each move passes the last answer's state back, and
the service must accept every state it answered (its contacts are placed again from the
configuration). In-process planning worker; the clock decides nothing here."""

from __future__ import annotations

import json
import random
import time
from typing import Any

import pytest

from service import compute
from tests.live_fixtures import LIVE_STEP

FAR_CAP_S = 600.0  # s: a cap no step reaches
MOVES = 8

# (character, game seed): the seed draws each move's request seed, as clients.load_test and
# bench/step.py do. The hexapod's game 317 reached, at its sixth move, a state whose feet had
# turned about their points while held: placed again from its configuration, the COM lay
# 4.6 mm outside the feet's kinematic polytopes, and its seventh move was refused with 422.
GAMES = [("hexapod", 317), ("hexapod", 3), ("quadruped", 11), ("humanoid", 5)]


def _step(request: dict[str, Any]) -> dict[str, Any]:
    body: dict[str, Any] = compute.run_twister_step(
        json.dumps(request), int(request["seed"]), deadline=time.monotonic() + FAR_CAP_S
    )
    return body


@pytest.mark.usefixtures("in_process_worker")
@pytest.mark.parametrize(("character", "game"), GAMES)
def test_every_state_answered_is_accepted_back(character: str, game: int) -> None:
    draw = random.Random(game)
    first = {**LIVE_STEP, "character": character, "action": {"kind": "auto"}}
    state = None
    solved = 0
    for _ in range(MOVES):
        request = dict(first)
        if state is not None:
            del request["stand_at"]
            request |= {"state": state}
        request["seed"] = draw.randrange(2**31)
        request["time_budget_s"] = 60  # the most: the clock never cuts a move's attempts
        answer = _step(request)  # a state answered before and refused now raises (422)
        if answer["status"] != "SOLVED":
            assert answer["failure"]["reason"], answer
            continue
        solved += 1
        state = answer["state"]
    assert solved >= MOVES // 2, f"{solved} of {MOVES} moves solved"
