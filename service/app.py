"""The FastAPI application factory: ``uvicorn service.app:create_app --factory``."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from starlette.middleware.cors import CORSMiddleware
from starlette.middleware.gzip import GZipMiddleware

from planner.ballistic.planner import RoadmapStore
from service import __version__, openapi
from service.errors import install_error_handlers
from service.files import remove_leftovers
from service.job_runner import JobRunner
from service.jobs import SqliteJobStore
from service.lanes import Lanes
from service.metrics import LIVE_REFRESH_S, Metrics, multiprocess_dir
from service.results import ResultStore, code_version
from service.routes import (
    characters,
    health,
    jobs,
    jumps,
    metrics,
    plans,
    results,
    scenes,
    twister,
    viewer,
)
from service.settings import Settings, get_settings
from service.telemetry import REQUEST_ID_HEADER, Telemetry, configure_logging
from service.workers import registry_for

log = logging.getLogger("gecko")


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app; the registry (characters, offline data) loads in the lifespan."""
    settings = settings or get_settings()
    configure_logging(settings.log_level)
    # several uvicorn workers: one set of figures for all of them (prometheus multiprocess)
    app_metrics = Metrics(multiprocess_dir(settings.home))

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # The cache directory holds the offline data and BVH caches, written the same way.
        stores = (settings.scenes_path, settings.results_path, settings.roadmaps_path)
        for directory in (*stores, settings.cache_path):
            remove_leftovers(directory, older_than_s=settings.leftover_min_age_s)
        registry = registry_for(settings)
        registry.preload()
        app.state.registry = registry
        app_metrics.watch_scenes(registry.uploaded_bytes, settings.scenes_quota_bytes)
        settings.roadmaps_path.mkdir(parents=True, exist_ok=True)
        roadmaps = RoadmapStore(settings.roadmaps_path)
        app_metrics.watch_roadmaps(roadmaps.used_bytes, settings.roadmaps_quota_bytes)
        lanes = Lanes(settings, app_metrics)
        app.state.lanes = lanes
        job_store = SqliteJobStore(settings.jobs_db_path)
        app_metrics.watch_jobs(job_store.counts)
        app.state.jobs = JobRunner(job_store, lanes.jobs)
        await app.state.jobs.open()
        log.info("code version %s", code_version())  # hashed once, before any request
        app.state.results = ResultStore(
            settings.results_path,
            max_count=settings.results_max_count,
            max_bytes=settings.results_max_bytes,
        )
        log.info("gecko ready: %d characters", len(registry.characters))
        live = asyncio.create_task(_refresh_live(app_metrics)) if app_metrics.multiprocess else None
        try:
            yield
        finally:
            if live is not None:
                live.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await live
            await app.state.jobs.close()
            lanes.shutdown()
            app_metrics.close()

    app = FastAPI(
        title="Gecko",
        version=__version__,
        description="Multi-contact motion planning for legged characters.",
        lifespan=lifespan,
        docs_url=None,  # served by service.openapi from local assets, not a CDN
        redoc_url=None,
    )
    app.state.settings = settings
    app.state.metrics = app_metrics
    install_error_handlers(app)
    app.include_router(health.router)
    app.include_router(metrics.router)
    app.include_router(characters.router)
    app.include_router(scenes.router)
    app.include_router(plans.router)
    app.include_router(twister.router)
    app.include_router(jumps.router)
    app.include_router(jobs.router)
    app.include_router(results.router)
    viewer.install(app)
    openapi.install(app)
    # Outermost last: telemetry sees the final status and times everything, CORS headers go
    # on every answer (errors too), gzip compresses what the routes answer.
    app.add_middleware(
        GZipMiddleware, minimum_size=settings.gzip_minimum_bytes, compresslevel=settings.gzip_level
    )
    if settings.cors_origins:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["content-type", REQUEST_ID_HEADER.lower()],
            expose_headers=[REQUEST_ID_HEADER, "Location", "Retry-After", "Content-Disposition"],
            max_age=600,
        )
    app.add_middleware(Telemetry, metrics=app_metrics)
    return app


async def _refresh_live(app_metrics: Metrics) -> None:
    """Multiprocess metrics: this worker's lane and memory gauges, kept current."""
    while True:
        await asyncio.sleep(LIVE_REFRESH_S)
        try:
            app_metrics.refresh_live()
        except OSError as exc:  # the metrics directory removed under us: say so, go on
            log.warning("could not refresh the metrics: %s", exc)
