"""The planning processes' side: their registry and settings, and their task loop.

Planning work runs in worker processes (see :mod:`service.lanes`) so the event loop (and
/health) never waits on the CPU. Each worker process keeps its own
:class:`~service.registry.Registry`, built once from the service settings, so characters and
scenes load once per process (from the on-disk caches).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
from multiprocessing.connection import Connection
from typing import Any

from service.registry import Registry
from service.settings import Settings

_WORKER_REGISTRY: Registry | None = None
_WORKER_SETTINGS: Settings | None = None
MAX_NICENESS = 19  # the lowest priority Unix has


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
        max_loaded_scenes=settings.scenes_cached,
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


_PR_SET_PDEATHSIG = 1  # prctl(2) option: a signal for this process when its parent dies


def die_with_parent(parent_pid: int) -> bool:
    """Ask Linux to SIGKILL this process when the thread that started it exits (its service
    worker killed, even with ``kill -9``), so no planning process outlives its service
    worker; exits at once if that parent is already gone. False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)
    return True


def compute_niceness(nice: int) -> int:
    """The niceness of a compute process: this process's own plus ``nice`` (at most
    MAX_NICENESS; this process's own where Unix priorities are unknown)."""
    if not hasattr(os, "getpriority"):
        return 0
    own = os.getpriority(os.PRIO_PROCESS, 0)
    return min(MAX_NICENESS, own + max(0, nice))


def lower_priority(pid: int, niceness: int) -> bool:
    """Set process ``pid``'s niceness (0: this process) to ``niceness`` when that lowers its
    priority; never raises it. The compute processes keep every core busy under load, and
    the service process, which only answers and waits, must not queue behind them for one
    (a ``/health`` answers in milliseconds, not a time slice). False where not allowed."""
    if not hasattr(os, "setpriority"):
        return False
    try:
        if os.getpriority(os.PRIO_PROCESS, pid) < niceness:
            os.setpriority(os.PRIO_PROCESS, pid, niceness)
    except OSError:  # gone, or not allowed here: the same priority
        return False
    return True


def serve_tasks(
    connection: Connection,
    settings_json: str,
    parent_pid: int | None = None,
    niceness: int | None = None,
) -> None:
    """A planning process's loop: receive ``(function, args)``, send back ``("ok", value)``
    or ``("error", exception)``, until the service closes its end of the pipe (or dies).

    With ``parent_pid`` (the service worker's pid) the process dies with that worker. With
    ``niceness`` (:func:`compute_niceness`) it runs at that niceness before it does anything
    else: its start-up (imports, characters, scenes) costs a second of CPU, which must not
    compete with the service process either. The lane that starts it sets it too, at once
    (:meth:`service.lanes.Lane._spawn`), so that the interpreter's own imports run niced."""
    if niceness is not None:
        lower_priority(0, niceness)
    if parent_pid is not None:
        die_with_parent(parent_pid)
    _init_worker(settings_json)
    while True:
        try:
            function, args = connection.recv()
        except (EOFError, OSError):
            return  # the service is gone: nothing left to do
        try:
            outcome: tuple[str, Any] = ("ok", function(*args))
        except Exception as exc:  # reported to the request that sent the task
            outcome = ("error", exc)
        try:
            connection.send(outcome)
        except (BrokenPipeError, EOFError, OSError):
            return
        except Exception as exc:  # an answer or exception that cannot be pickled
            message = f"unpicklable {outcome[0]} from a worker: {type(exc).__name__}: {exc}"
            connection.send(("error", RuntimeError(message)))
