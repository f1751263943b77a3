"""Errors as JSON ``{"error": {"code", "message", "field"}}`` for every failure the API reports."""

from __future__ import annotations

import logging
import sqlite3
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from service.context import annotate

log = logging.getLogger("gecko.errors")


INSUFFICIENT_STORAGE = 507  # HTTP status of a refused store (a quota is full)


class ApiError(Exception):
    """An error with an HTTP status, a stable code, a message and the offending field."""

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        field: str | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.headers = headers

    def __reduce__(
        self,
    ) -> tuple[type[ApiError], tuple[int, str, str, str | None, dict[str, str] | None]]:
        # Raised in worker processes and re-raised in the server: keep it picklable.
        return (ApiError, (self.status, self.code, self.message, self.field, self.headers))


def not_found(kind: str, identifier: str, field: str) -> ApiError:
    """404 for an unknown id."""
    return ApiError(404, "not_found", f"unknown {kind} '{identifier}'", field)


def error_body(code: str, message: str, field: str | None) -> dict[str, Any]:
    """The JSON error envelope (its code and field also go to the request's log line)."""
    annotate(error_code=code, error_field=field)
    return {"error": {"code": code, "message": message, "field": field}}


def _field_path(location: Any) -> str:
    parts = [str(part) for part in location if part not in ("body", "query", "path")]
    return ".".join(parts) if parts else "body"


def install_error_handlers(app: FastAPI) -> None:
    """Route every error through the JSON envelope."""

    @app.exception_handler(ApiError)
    async def _api_error(_: Request, exc: ApiError) -> JSONResponse:
        return JSONResponse(
            error_body(exc.code, exc.message, exc.field),
            status_code=exc.status,
            headers=exc.headers,
        )

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
        errors = exc.errors()
        first = errors[0] if errors else {"loc": (), "msg": "invalid request"}
        if first.get("type") == "json_invalid":  # its location is a character position
            position = first.get("loc", ("body", "?"))[-1]
            message = f"body: not valid JSON at character {position} ({first.get('msg')})"
            return JSONResponse(error_body("invalid_request", message, "body"), status_code=422)
        field = _field_path(first.get("loc", ()))
        message = f"{field}: {first.get('msg', 'invalid value')}"
        if len(errors) > 1:
            message += f" (and {len(errors) - 1} more)"
        return JSONResponse(error_body("invalid_request", message, field), status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def _http(_: Request, exc: StarletteHTTPException) -> JSONResponse:
        codes = {400: "invalid_body", 404: "not_found", 405: "method_not_allowed"}
        code = codes.get(exc.status_code, "http_error")
        return JSONResponse(
            error_body(code, str(exc.detail), None),
            status_code=exc.status_code,
            headers=getattr(exc, "headers", None),
        )

    @app.exception_handler(sqlite3.OperationalError)
    async def _store_busy(_: Request, exc: sqlite3.OperationalError) -> JSONResponse:
        # The job store stayed locked by another process past its busy timeout (a process
        # stopped or stuck mid-write): a refusal to retry, not a server error.
        log.warning("job store unavailable: %s", exc)
        return JSONResponse(
            error_body("store_busy", f"the job store is busy ({exc}); retry in 1 s", None),
            status_code=503,
            headers={"Retry-After": "1"},
        )

    @app.exception_handler(Exception)
    async def _unexpected(_: Request, exc: Exception) -> JSONResponse:
        return JSONResponse(
            error_body("internal_error", f"unexpected {type(exc).__name__}", None),
            status_code=500,
        )
