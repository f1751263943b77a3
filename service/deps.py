"""FastAPI dependencies: the registry and the settings, taken from the app state.

They are ``async`` on purpose: FastAPI runs a plain ``def`` dependency in its thread pool,
so every request naming one (``/health`` included) would wait for a free thread and for the
GIL, and hop back to the event loop, only to read an attribute."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.registry import Registry
from service.settings import Settings


async def get_registry(request: Request) -> Registry:
    """The app's registry (characters, scenes), read on the event loop thread."""
    registry: Registry = request.app.state.registry
    return registry


async def get_app_settings(request: Request) -> Settings:
    """The app's settings, read on the event loop thread."""
    settings: Settings = request.app.state.settings
    return settings


RegistryDep = Annotated[Registry, Depends(get_registry)]
SettingsDep = Annotated[Settings, Depends(get_app_settings)]
