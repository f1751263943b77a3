"""FastAPI dependencies: the registry and the settings, taken from the app state."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.registry import Registry
from service.settings import Settings


def get_registry(request: Request) -> Registry:
    registry: Registry = request.app.state.registry
    return registry


def get_app_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


RegistryDep = Annotated[Registry, Depends(get_registry)]
SettingsDep = Annotated[Settings, Depends(get_app_settings)]
