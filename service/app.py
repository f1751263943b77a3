"""The FastAPI application factory: ``uvicorn service.app:create_app --factory``."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI

from service import __version__
from service.errors import install_error_handlers
from service.registry import Registry
from service.routes import characters, health, scenes
from service.settings import Settings, get_settings

log = logging.getLogger("gecko")


def _character_ids(settings: Settings) -> list[str] | None:
    if settings.characters.strip() in ("", "auto"):
        return None
    return [part.strip() for part in settings.characters.split(",") if part.strip()]


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app; the registry (characters, offline data) loads in the lifespan."""
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.registry = Registry(
            cache_dir=settings.cache_path,
            scenes_dir=settings.scenes_path,
            character_ids=_character_ids(settings),
            build_missing_data=settings.build_missing_data,
            data_seed=settings.data_seed,
        )
        log.info("gecko ready: %d characters", len(app.state.registry.characters))
        yield

    app = FastAPI(
        title="Gecko",
        version=__version__,
        description="Multi-contact motion planning for legged characters.",
        lifespan=lifespan,
    )
    app.state.settings = settings
    install_error_handlers(app)
    app.include_router(health.router)
    app.include_router(characters.router)
    app.include_router(scenes.router)
    return app
