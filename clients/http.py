"""A small typed wrapper over Gecko's HTTP API, taking an injected ``httpx.AsyncClient``."""

from __future__ import annotations

from typing import Any

import httpx


class GeckoError(Exception):
    """An error answer from the service: HTTP status plus the JSON error envelope."""

    def __init__(self, status: int, code: str, message: str, field: str | None) -> None:
        super().__init__(f"{status} {code}: {message}" + (f" (field {field})" if field else ""))
        self.status = status
        self.code = code
        self.message = message
        self.field = field


def _checked(response: httpx.Response) -> Any:
    if response.status_code >= 400:
        try:
            error = response.json()["error"]
            raise GeckoError(
                response.status_code, error["code"], error["message"], error.get("field")
            )
        except (ValueError, KeyError, TypeError):
            raise GeckoError(response.status_code, "http_error", response.text, None) from None
    return response.json()


def _checked_bytes(response: httpx.Response) -> bytes:
    if response.status_code >= 400:
        _checked(response)
    return response.content


RESULT_PATHS = {"plan": "/v1/plans", "step": "/v1/twister/steps", "jump": "/v1/jumps"}


class GeckoClient:
    """Calls the service; every method returns the decoded JSON answer or raises GeckoError."""

    def __init__(self, http: httpx.AsyncClient) -> None:
        self.http = http

    async def health(self) -> dict[str, Any]:
        return dict(_checked(await self.http.get("/health")))

    async def characters(self) -> list[dict[str, Any]]:
        return list(_checked(await self.http.get("/v1/characters")))

    async def character(self, character_id: str) -> dict[str, Any]:
        return dict(_checked(await self.http.get(f"/v1/characters/{character_id}")))

    async def scenes(self) -> list[dict[str, Any]]:
        return list(_checked(await self.http.get("/v1/scenes")))

    async def scene(self, scene_id: str) -> dict[str, Any]:
        return dict(_checked(await self.http.get(f"/v1/scenes/{scene_id}")))

    async def upload_scene(self, mesh: bytes, fmt: str, name: str = "") -> dict[str, Any]:
        params = {"format": fmt, "name": name}
        return dict(_checked(await self.http.post("/v1/scenes", params=params, content=mesh)))

    async def plan(self, request: dict[str, Any], timeout: float = 120.0) -> dict[str, Any]:
        """``POST /v1/plans``."""
        return dict(_checked(await self.http.post("/v1/plans", json=request, timeout=timeout)))

    async def twister_step(self, request: dict[str, Any], timeout: float = 120.0) -> dict[str, Any]:
        """``POST /v1/twister/step``."""
        response = await self.http.post("/v1/twister/step", json=request, timeout=timeout)
        return dict(_checked(response))

    async def jumps(self, request: dict[str, Any], timeout: float = 120.0) -> dict[str, Any]:
        """``POST /v1/jumps``."""
        return dict(_checked(await self.http.post("/v1/jumps", json=request, timeout=timeout)))

    async def build_roadmap(self, request: dict[str, Any]) -> dict[str, Any]:
        """``POST /v1/roadmaps``: starts (or finds) a build; returns its status."""
        return dict(_checked(await self.http.post("/v1/roadmaps", json=request)))

    async def roadmap(self, roadmap_id: str) -> dict[str, Any]:
        """``GET /v1/roadmaps/{id}``."""
        return dict(_checked(await self.http.get(f"/v1/roadmaps/{roadmap_id}")))

    async def result(self, kind: str, result_id: str) -> dict[str, Any]:
        """A stored answer by id: ``kind`` is ``plan``, ``step`` or ``jump``."""
        return dict(_checked(await self.http.get(f"{RESULT_PATHS[kind]}/{result_id}")))

    async def result_glb(
        self, kind: str, result_id: str, *, scene: bool = False, overlays: bool = False
    ) -> bytes:
        """A stored answer as GLB (glTF 2.0, y up, metres): the character's node tree and
        its animation; ``scene`` adds the scene mesh, ``overlays`` the COM curve and contacts."""
        params = {"scene": str(scene).lower(), "overlays": str(overlays).lower()}
        url = f"{RESULT_PATHS[kind]}/{result_id}.glb"
        return _checked_bytes(await self.http.get(url, params=params, timeout=120.0))

    async def results(self, limit: int = 100) -> list[dict[str, Any]]:
        """``GET /v1/results``: stored answers, most recently used first."""
        return list(_checked(await self.http.get("/v1/results", params={"limit": limit})))

    async def scene_mesh(self, scene_id: str, fmt: str = "glb") -> bytes:
        """``GET /v1/scenes/{id}/mesh``: GLB (y up) or STL (z up)."""
        url = f"/v1/scenes/{scene_id}/mesh"
        return _checked_bytes(await self.http.get(url, params={"format": fmt}))
