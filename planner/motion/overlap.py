"""Overlapping swings: a walker on four legs or more lifts its next leg before the leg in the
air has landed, as a quadruped walks at pace (diagonal legs in the air together).

The contact planner's sequences change one contact per state and balance every state
statically: break A, make A', break B, make B'. Where the legs left on the ground while
both A and B are free can carry the body dynamically (2PAC Eq. 1, checked by the dynamic
COM QP), the motion plays the same contacts in the order break A, break B, make A', make B':
one contact still changes per phase, and only the state between the two breaks is new (the
state before A' is made, without B). Offered on level ground only, where the two legs'
arcs cross nothing.

Units: metres, world frame z up.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

from planner.character import Character
from planner.kinematics import com_position
from planner.motion import tuning

if TYPE_CHECKING:  # annotations only: planner.contact imports planner.motion
    from planner.contact.state import ContactState

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Overlap:
    """The phases' contact states with swings overlapped: ``states`` (as many as given, the
    third of each pair replaced) and ``pairs``, per overlapped pair of swings, the index of
    its first phase (the first leg in the air alone, the ``OVERLAP_LEAD_S`` before the second
    lifts); the next phase has both legs in the air, the one after the second alone."""

    states: tuple[ContactState, ...]
    pairs: tuple[int, ...]


def _change(before: ContactState, after: ContactState) -> tuple[str, str] | None:
    """("break" or "make", limb) from ``before`` to ``after``; None unless exactly one limb
    changes."""
    lost = set(before.limbs) - set(after.limbs)
    gained = set(after.limbs) - set(before.limbs)
    if len(lost) + len(gained) != 1:
        return None
    return ("break", lost.pop()) if lost else ("make", gained.pop())


def _level(states: Sequence[ContactState]) -> bool:
    """Every contact of ``states`` faces up (``OVERLAP_MAX_NORMAL_TILT``) within
    ``OVERLAP_LEVEL`` of the same height."""
    heights = [float(c.placement[2, 3]) for s in states for c in s.contacts]
    upright = all(
        float(c.normal[2]) >= np.cos(tuning.OVERLAP_MAX_NORMAL_TILT)
        for s in states
        for c in s.contacts
    )
    return upright and max(heights) - min(heights) <= tuning.OVERLAP_LEVEL


def _support_distance(points: FloatArray, point: FloatArray) -> float:
    """m, horizontal distance from ``point`` (2,) to the hull of ``points`` (k, 2) (0
    inside; a segment's for two points)."""
    if len(points) == 2:
        a, b = points
        u = float(np.clip((point - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0, 1))
        return float(np.linalg.norm(a + u * (b - a) - point))
    try:
        hull = ConvexHull(points)
    except QhullError:  # points on a line
        return min(
            _support_distance(points[[i, j]], point)
            for i in range(len(points))
            for j in range(i + 1, len(points))
        )
    # facets as n . x + d <= 0 inside; outside by the largest positive offset at most
    offsets = hull.equations[:, :2] @ point + hull.equations[:, 2]
    return max(0.0, float(offsets.max()))


def overlap_swings(character: Character, states: Sequence[ContactState]) -> Overlap | None:
    """``states`` with consecutive swings overlapped where it may pay (module docstring):
    break A, make A', break B, make B' (A and B different limbs, the state before the break
    of A holding at least four contacts) on level ground, the contacts left while both are
    in the air (two at least) passing within ``OVERLAP_COM_REACH`` of the COM of the states
    balanced on one leg less (after the break of A and after the break of B). Pairs do not
    share phases. None unless the pairs hold at least ``OVERLAP_MIN_SHARE`` of the plan's
    swings (mostly level ground: a plan tries its overlapped swings whole or not at all, and
    the try costs a dynamic curve with more rounds)."""
    out = list(states)
    pairs: list[int] = []
    i = 0
    while i + 4 < len(states):
        changes = [_change(states[i + j], states[i + j + 1]) for j in range(4)]
        a = changes[0][1] if changes[0] is not None and changes[0][0] == "break" else None
        b = changes[2][1] if changes[2] is not None and changes[2][0] == "break" else None
        if (
            a is None
            or b is None
            or a == b
            or changes[1] != ("make", a)
            or changes[3] != ("make", b)
            or len(states[i].contacts) < 4
            or not _level(states[i : i + 5])
        ):
            i += 1
            continue
        both = states[i + 1].without(b)  # at least two contacts: four held, two up
        support = np.array([p[:2] for c in both.contacts for p in c.points])
        reach = max(
            _support_distance(support, com_position(character.model, states[j].q)[:2])
            for j in (i + 1, i + 3)
        )
        if reach > tuning.OVERLAP_COM_REACH:
            i += 1
            continue
        out[i + 2] = both
        pairs.append(i + 1)
        i += 4
    swings = sum(1 for a, b in itertools.pairwise(states) if set(b.limbs) - set(a.limbs))
    if not pairs or 2 * len(pairs) < tuning.OVERLAP_MIN_SHARE * swings:
        return None
    return Overlap(tuple(out), tuple(pairs))
