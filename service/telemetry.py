"""Request ids, JSON log lines and request metrics: one ASGI middleware around the app.

Every request gets an id: the client's ``X-Request-ID`` when it is sane (1 to 128 letters,
digits and ``._:-``), else a fresh one; the answer carries it back in ``X-Request-ID``. When
the answer is complete, one JSON line is logged (logger ``gecko.request``: id, method,
route template, path, status, duration) with whatever the handler added through
:func:`service.context.annotate` (a plan's seed, the status of the answer, its stage
timings, the error code).
Every other log line of the service's ``gecko.*`` loggers written while serving a request
carries its ``request_id`` too.
"""

from __future__ import annotations

import json
import logging
import re
import sys
import time
import uuid
from typing import Any, TextIO

from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.context import RequestContext, current_request_id, enter, leave
from service.errors import error_body
from service.metrics import UNMATCHED_ROUTE, Metrics

REQUEST_ID_HEADER = "X-Request-ID"
_SANE_REQUEST_ID = re.compile(r"[A-Za-z0-9._:\-]{1,128}")
_HANDLER_NAME = "gecko-json"
# Attributes every LogRecord has; anything else on a record came from ``extra=``.
_RECORD_FIELDS = frozenset(vars(logging.makeLogRecord({}))) | {"message", "asctime"}

log = logging.getLogger("gecko.request")


def request_id_from(value: str | None) -> str:
    """The client's request id when it is sane, else a new random one (32 hex digits)."""
    if value is not None and _SANE_REQUEST_ID.fullmatch(value):
        return value
    return uuid.uuid4().hex


class JsonFormatter(logging.Formatter):
    """One JSON object per line: time (Unix s), level, logger, message, request id, extras."""

    def format(self, record: logging.LogRecord) -> str:
        line: dict[str, Any] = {
            "time": round(record.created, 6),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        request_id = getattr(record, "request_id", None) or current_request_id()
        if request_id is not None:
            line["request_id"] = request_id
        for key, value in vars(record).items():
            if key not in _RECORD_FIELDS and key not in line:
                line[key] = value
        if record.exc_info:
            line["exception"] = self.formatException(record.exc_info)
        return json.dumps(line, default=str, separators=(",", ":"))


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """Writes to whatever ``sys.stderr`` is at the time of each record (so that a test's
    capture, or a redirect made after start-up, sees the lines)."""

    def __init__(self) -> None:
        super().__init__()

    @property
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, _: TextIO) -> None:  # StreamHandler.__init__ assigns it
        pass


def configure_logging(level: str) -> None:
    """Send the ``gecko`` loggers' records to stderr as JSON lines at ``level`` (idempotent)."""
    logger = logging.getLogger("gecko")
    logger.setLevel(level.upper())
    logger.propagate = False
    if not any(handler.get_name() == _HANDLER_NAME for handler in logger.handlers):
        handler = _StderrHandler()
        handler.set_name(_HANDLER_NAME)
        handler.setFormatter(JsonFormatter())
        logger.addHandler(handler)


def route_template(scope: Scope) -> str:
    """The path template of the route that served ``scope`` (``/v1/plans/{plan_id}``), or a
    single placeholder for paths no route serves (so metric labels stay bounded)."""
    route = scope.get("route")
    path = getattr(route, "path", None)
    return path if isinstance(path, str) else UNMATCHED_ROUTE


class Telemetry:
    """ASGI middleware: request id, one JSON log line and the request metrics per request."""

    def __init__(self, app: ASGIApp, metrics: Metrics) -> None:
        self.app = app
        self.metrics = metrics

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        incoming = None
        for name, value in scope.get("headers", []):
            if name == b"x-request-id":
                incoming = value.decode("latin-1")
        context = RequestContext(request_id_from(incoming))
        token = enter(context)
        status = 500
        response_started = False

        async def send_with_id(message: Message) -> None:
            nonlocal status, response_started
            if message["type"] == "http.response.start":
                status = int(message["status"])
                response_started = True
                MutableHeaders(scope=message).append(REQUEST_ID_HEADER, context.request_id)
            await send(message)

        self.metrics.in_progress.inc()
        try:
            await self.app(scope, receive, send_with_id)
        except Exception as exc:
            status = 500
            log.exception("unexpected %s", type(exc).__name__)
            if response_started:
                raise
            await self._internal_error(send, context.request_id, exc)
        finally:
            seconds = time.perf_counter() - started
            self.metrics.in_progress.dec()
            route = route_template(scope)
            method = str(scope.get("method", ""))
            self.metrics.observe_request(method, route, status, seconds)
            log.info(
                "%s %s %d",
                method,
                scope.get("path", ""),
                status,
                extra={
                    "method": method,
                    "route": route,
                    "path": scope.get("path", ""),
                    "status": status,
                    "duration_s": round(seconds, 6),
                    **{k: v for k, v in context.fields.items() if k not in _RECORD_FIELDS},
                },
            )
            leave(token)

    @staticmethod
    async def _internal_error(send: Send, request_id: str, exc: Exception) -> None:
        body = json.dumps(
            error_body("internal_error", f"unexpected {type(exc).__name__}", None)
        ).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 500,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (REQUEST_ID_HEADER.lower().encode(), request_id.encode()),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})
