"""The request being served (a context variable): its id, and fields for its log line."""

from __future__ import annotations

import time
from contextvars import ContextVar, Token
from dataclasses import dataclass, field
from typing import Any


@dataclass(slots=True)
class RequestContext:
    """What is known about the request being served; handlers add ``fields`` to its log line."""

    request_id: str
    fields: dict[str, Any] = field(default_factory=dict)
    arrived: float = field(default_factory=time.monotonic)  # monotonic s, at the first byte


_current: ContextVar[RequestContext | None] = ContextVar("gecko_request", default=None)


def enter(context: RequestContext) -> Token[RequestContext | None]:
    """Make ``context`` the current request of this task; ``leave(token)`` undoes it."""
    return _current.set(context)


def leave(token: Token[RequestContext | None]) -> None:
    """Undo :func:`enter`."""
    _current.reset(token)


def annotate(**fields: Any) -> None:
    """Add fields (JSON-ready values) to the log line of the request being served, if any."""
    context = _current.get()
    if context is not None:
        context.fields.update(fields)


def current_request_id() -> str | None:
    """The id of the request being served in this task, if any."""
    context = _current.get()
    return context.request_id if context is not None else None


def arrival_time() -> float:
    """When the request being served arrived (:func:`time.monotonic` s); now outside one."""
    context = _current.get()
    return context.arrived if context is not None else time.monotonic()
