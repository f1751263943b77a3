"""Work budgets: how much search and keyframe work a request's ``time_budget_s`` buys.

Every tuning value of it is here, named and explained. A plan is decided by counted work,
never by the clock, so the same request and seed give the same answer on a quiet machine and
on a loaded one: ``time_budget_s`` buys ``UNITS_PER_SECOND`` work units per second, each
stage charges a fixed number of units per step it counts (an RRT iteration, a
contact-sequence cycle and the states it checked, a keyframe), and a stage stops when the
units are spent. The wall-clock budget stays as a hard cap that only binds on a machine much
slower (or busier) than the reference one; the plan's stats then say ``clock_cap_hit`` and
its message says a replay may differ.

A work unit is about one millisecond of the reference machine (2 cores, nothing else
running). Costs were measured on it (shared with other work at times, so if anything slower
than a quiet one) over the reference plans of ``tests/scenarios/plans``, rounded up.
"""

from __future__ import annotations

from planner.character import Character
from planner.termination import Deadline, WorkBudget

UNITS_PER_SECOND = 600.0
"""Work units one second of ``time_budget_s`` buys. The reference machine does about 1000 a
second (0.6 ms a unit for the quadruped to 1.3 for Talos on platforms), so the work of a
budget takes about 60 % of it there: plans stopped by their work budget measured 40 to 76 %
of their clock cap (rubble 4 s, the hexapod's wall 15 s, flat walks 1 and 2 s, Talos's
platforms 2 s, the handrail 5 s), so the cap binds only on a machine (or under a load) 1.3
to 2.5 times slower. Enough for every reference plan at its budget (the heaviest, the
hexapod's climbing wall, spends about 29 000 of the 36 000 units its 60 s buy)."""

SEARCH_SHARE = 0.8
"""The search (endpoints, root path, contacts) stops once it has used this share of the
units (and of the clock cap); the COM trajectory and the keyframes get every unit it left."""

STANDING_ATTEMPT_UNITS = 10.0
"""A root pose tried for a standing state (IK of every ground limb, a state check): about
10 ms."""

ROOT_PATH_ITERATION_UNITS = 2.0
"""An RRT-Connect iteration of the root path (a sample steered, the other tree connecting),
and a shortcut or waypoint-skipping try of its smoothing: 1.3 to 1.8 ms (more as the trees
grow)."""

SEQUENCE_CYCLE_UNITS_PER_LIMB = 5.0
"""A contact-sequence cycle (the body advanced, the footholds ahead found), per walking limb,
on top of the states it checks (``STATE_CHECK_UNITS``)."""

STATE_CHECK_UNITS = 5.0
"""A candidate contact state checked (``ContactContext.work``), with the IK that placed it:
a cycle that fails and tries again pays for every try. Fitted with the cycle cost over the
reference plans: a cycle took 25 to 67 ms (rubble, flat ground, the humanoid climbing with
hands and feet, the hexapod, HyQ, Talos on platforms), about 0.5 to 1.2 ms a unit."""

KEYFRAME_UNITS_PER_SHAPE = 0.2
"""A keyframe tracked (two QP control steps, a collision check, its share of the COM
trajectory), per collision shape of the character: the checks dominate. Measured 3 ms for
the humanoid (15 shapes) and the quadruped (17), 5 ms for the hexapod (25) and Talos (30).
A swing tracked again with a higher arc pays again."""


COM_STATE_UNITS = 16.0
"""A contact state's share of the COM trajectory (2PAC's sliding window, Eq. 1 checks),
computed before any keyframe and never cut: 7 (Talos) to 16 ms (the hexapod, the humanoid)
a state. Charged to the keyframes' units so that they stay close to the time they take."""


def keyframe_units(character: Character) -> float:
    """Work units of one keyframe of ``character``."""
    return KEYFRAME_UNITS_PER_SHAPE * len(character.geometry.geometryObjects)


def plan_budget(time_budget_s: float, cap_s: float | None = None) -> WorkBudget:
    """The work budget of a plan asked for ``time_budget_s`` seconds: its units come from
    ``time_budget_s`` alone (so a request replays however long it waited in a queue); its
    wall-clock cap is ``cap_s`` seconds from now (default ``time_budget_s``)."""
    cap = time_budget_s if cap_s is None else cap_s
    return WorkBudget(UNITS_PER_SECOND * time_budget_s, Deadline(cap))
