"""A process pool for planning work, so the event loop (and /health) never waits on the CPU.

Each worker process keeps its own :class:`~service.registry.Registry`, built once from the
service settings, so characters and scenes load once per process (from the on-disk caches).
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from service.errors import ApiError
from service.metrics import Metrics
from service.registry import Registry
from service.settings import Settings

T = TypeVar("T")
log = logging.getLogger("gecko.workers")

_WORKER_REGISTRY: Registry | None = None
_WORKER_SETTINGS: Settings | None = None


def _init_worker(settings_json: str) -> None:
    global _WORKER_REGISTRY, _WORKER_SETTINGS
    settings = Settings.model_validate_json(settings_json)
    _WORKER_SETTINGS = settings
    _WORKER_REGISTRY = registry_for(settings)


def registry_for(settings: Settings) -> Registry:
    """A registry over the settings' directories (characters load lazily)."""
    ids = None
    if settings.characters.strip() not in ("", "auto"):
        ids = [part.strip() for part in settings.characters.split(",") if part.strip()]
    return Registry(
        cache_dir=settings.cache_path,
        scenes_dir=settings.scenes_path,
        character_ids=ids,
        build_missing_data=settings.build_missing_data,
        data_seed=settings.data_seed,
    )


def worker_registry() -> Registry:
    """The registry of the current worker process."""
    if _WORKER_REGISTRY is None:
        raise RuntimeError("worker_registry() called outside a worker process")
    return _WORKER_REGISTRY


def worker_settings() -> Settings:
    """The settings the current worker process was started with."""
    if _WORKER_SETTINGS is None:
        raise RuntimeError("worker_settings() called outside a worker process")
    return _WORKER_SETTINGS


def _ping() -> int:
    return 1


class WorkerPool:
    """Runs picklable functions in worker processes; recreated if a worker dies."""

    def __init__(self, settings: Settings, metrics: Metrics | None = None) -> None:
        # One BLAS thread per worker: the matrices are small, and workers share the cores.
        for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(variable, "1")
        self._settings = settings
        self._metrics = metrics or Metrics()
        self._metrics.worker_processes.set(settings.worker_processes)
        self._executor = self._new_executor()

    def _new_executor(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self._settings.worker_processes,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(self._settings.model_dump_json(),),
        )

    async def warm_up(self) -> None:
        """Start every worker process now rather than on the first request."""
        loop = asyncio.get_running_loop()
        jobs = [
            loop.run_in_executor(self._executor, _ping)
            for _ in range(self._settings.worker_processes)
        ]
        await asyncio.gather(*jobs)

    async def run(self, function: Callable[..., T], *args: Any, timeout_s: float) -> T:
        """Run ``function(*args)`` in a worker; 503 if the pool broke, 504 past ``timeout_s``."""
        loop = asyncio.get_running_loop()
        executor = self._executor
        self._metrics.worker_tasks.inc()
        try:
            future = loop.run_in_executor(executor, function, *args)
            return await asyncio.wait_for(future, timeout=timeout_s)
        except BrokenProcessPool as exc:
            log.error("a planning worker died: %r", exc)
            self._replace(executor)
            raise ApiError(503, "worker_lost", "a planning worker died; retry", None) from exc
        except TimeoutError as exc:
            raise ApiError(504, "timeout", f"no answer within {timeout_s:.1f} s", None) from exc
        finally:
            self._metrics.worker_tasks.dec()

    def _replace(self, broken: ProcessPoolExecutor) -> None:
        """A new pool in place of ``broken``, once (every task of a broken pool fails)."""
        if broken is not self._executor:
            return
        broken.shutdown(wait=False, cancel_futures=True)
        self._executor = self._new_executor()
        self._metrics.worker_restarts.inc()

    def submit(self, function: Callable[..., T], *args: Any) -> Future[T]:
        """Start background work (e.g. a roadmap build); it records its own result."""
        executor = self._executor
        try:
            return executor.submit(function, *args)
        except BrokenProcessPool:
            log.error("the planning pool was broken; starting a new one")
            self._replace(executor)
            return self._executor.submit(function, *args)

    def shutdown(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
