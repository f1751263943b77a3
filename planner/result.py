"""Planner outcomes: a status enum and a generic result carrying a value and statistics."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Generic, TypeVar

T = TypeVar("T")


class PlanStatus(enum.Enum):
    """How a planner ended. Only SOLVED and APPROXIMATE carry a usable value."""

    SOLVED = "SOLVED"
    APPROXIMATE = "APPROXIMATE"
    INVALID_START = "INVALID_START"
    INVALID_GOAL = "INVALID_GOAL"
    TIMEOUT = "TIMEOUT"
    INFEASIBLE = "INFEASIBLE"

    def __bool__(self) -> bool:
        return self in (PlanStatus.SOLVED, PlanStatus.APPROXIMATE)


@dataclass(frozen=True, slots=True)
class PlanResult(Generic[T]):
    """A planner's answer: status, the value (possibly partial), free-form statistics."""

    status: PlanStatus
    value: T | None
    stats: dict[str, float | int | str] = field(default_factory=dict)
    message: str = ""
