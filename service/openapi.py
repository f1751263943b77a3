"""The OpenAPI document as the service answers, and the API docs page served without a CDN.

FastAPI documents a 422 with its own ``HTTPValidationError`` body on every operation with
parameters; Gecko answers every error with :class:`~service.schemas.ErrorBody` instead, and
a route whose only parameters are free-text path ids never answers 422. A JSON body that does
not decode (not UTF-8) is a 400, which FastAPI does not document. The document is rewritten
accordingly. ``/docs`` is Swagger UI from ``service/static/vendor/swagger-ui`` (vendored
from its npm release, like three.js for the viewer); ReDoc is not served.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.openapi.utils import get_openapi
from fastapi.responses import HTMLResponse

SWAGGER_UI = "/static/vendor/swagger-ui"
_FASTAPI_422 = "#/components/schemas/HTTPValidationError"
_ERROR_BODY = "#/components/schemas/ErrorBody"
_INVALID = "invalid input: the message names the field and the limit"
_NOT_JSON = "the body cannot be read as text (invalid_body: not UTF-8)"


def _can_fail_validation(operation: dict[str, Any]) -> bool:
    """True when some input of the operation can be refused: a body, or a parameter whose
    schema is more than a free string (a number, an enum, a bounded string, ...)."""
    if "requestBody" in operation:
        return True
    for parameter in operation.get("parameters", []):
        schema = parameter.get("schema", {})
        if set(schema) - {"type", "title", "description"} or schema.get("type") != "string":
            return True
    return False


def _takes_json(operation: dict[str, Any]) -> bool:
    """True when the operation's body is JSON (a body that does not parse is a 400)."""
    return "application/json" in operation.get("requestBody", {}).get("content", {})


def _rewrite(spec: dict[str, Any]) -> dict[str, Any]:
    for path_item in spec.get("paths", {}).values():
        for operation in path_item.values():
            responses = operation.get("responses", {})
            if _takes_json(operation) and "400" not in responses:
                responses["400"] = {
                    "description": _NOT_JSON,
                    "content": {"application/json": {"schema": {"$ref": _ERROR_BODY}}},
                }
            generated = responses.get("422", {})
            content = generated.get("content", {}).get("application/json", {})
            if content.get("schema", {}).get("$ref") != _FASTAPI_422:
                continue
            if _can_fail_validation(operation):
                content["schema"] = {"$ref": _ERROR_BODY}
                generated["description"] = _INVALID
            else:
                del responses["422"]
    schemas = spec.get("components", {}).get("schemas", {})
    for name in ("HTTPValidationError", "ValidationError"):
        schemas.pop(name, None)
    return spec


def install(app: FastAPI) -> None:
    """Serve ``/openapi.json`` as rewritten above and ``/docs`` from local assets."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            spec = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
                tags=app.openapi_tags,
            )
            app.openapi_schema = _rewrite(spec)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]

    @app.get("/docs", include_in_schema=False)
    async def docs(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "").rstrip("/")
        return get_swagger_ui_html(
            openapi_url=f"{root}{app.openapi_url}",
            title=f"{app.title} API",
            swagger_js_url=f"{root}{SWAGGER_UI}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{SWAGGER_UI}/swagger-ui.css",
            swagger_favicon_url=f"{root}{SWAGGER_UI}/favicon-32x32.png",
            swagger_ui_parameters={"validatorUrl": None},
        )
