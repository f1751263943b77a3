"""Gecko served by a real ``uvicorn`` command in its own process group, as an operator runs
it (``--workers N``), and its process tree read through psutil: the uvicorn workers and the
lanes' compute processes below them."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import httpx
import psutil

from tests.live_server import free_port
from tests.paths import REPO_ROOT, gecko_cache_dir

START_TIMEOUT_S = 180.0
STOP_TIMEOUT_S = 90.0


def _is_spawned(process: psutil.Process) -> bool:
    """A multiprocessing "spawn" child (a uvicorn worker or a lane's process), not the
    resource tracker multiprocessing starts beside them."""
    try:
        return "spawn_main" in " ".join(process.cmdline())
    except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
        return False


def _alive(process: psutil.Process) -> bool:
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


@dataclass
class ServerProcess:
    """A running ``uvicorn service.app:create_app`` command."""

    popen: subprocess.Popen[bytes]
    url: str
    workers: int
    log_path: Path

    @property
    def pid(self) -> int:
        return self.popen.pid

    def tree(self) -> list[psutil.Process]:
        """Every live process below the uvicorn command (workers, lanes, trackers)."""
        try:
            return [p for p in psutil.Process(self.pid).children(recursive=True) if _alive(p)]
        except psutil.NoSuchProcess:
            return []

    def uvicorn_workers(self) -> list[int]:
        """Pids of the service workers: the command itself with ``--workers 1``."""
        if self.workers == 1:
            return [self.pid]
        try:
            children = psutil.Process(self.pid).children()
        except psutil.NoSuchProcess:
            return []
        return [p.pid for p in children if _alive(p) and _is_spawned(p)]

    def compute_processes(self) -> dict[int, list[int]]:
        """Service worker pid -> pids of its lanes' live processes."""
        out: dict[int, list[int]] = {}
        for worker in self.uvicorn_workers():
            try:
                children = psutil.Process(worker).children()
            except psutil.NoSuchProcess:
                continue
            out[worker] = sorted(p.pid for p in children if _alive(p) and _is_spawned(p))
        return out

    def log(self) -> str:
        """What the server wrote on stdout and stderr so far."""
        return self.log_path.read_text(errors="replace")

    def terminate(self, timeout_s: float = STOP_TIMEOUT_S) -> int:
        """SIGTERM to the uvicorn command (not its group) and wait; its exit code."""
        self.popen.send_signal(signal.SIGTERM)
        return self.popen.wait(timeout=timeout_s)


def _env(home: Path, extra: dict[str, str]) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("GECKO_")}
    env |= {
        "GECKO_HOME": str(home),
        "GECKO_CACHE_DIR": str(gecko_cache_dir()),
        "GECKO_CHARACTERS": "humanoid,quadruped",
        "GECKO_LOG_LEVEL": "warning",
        "PYTHONUNBUFFERED": "1",
    }
    return env | extra


@contextmanager
def server_process(
    home: Path,
    *,
    workers: int = 1,
    env: dict[str, str] | None = None,
    grace_s: int = 5,
    healthcheck_s: int = 30,
) -> Iterator[ServerProcess]:
    """Run uvicorn on a free port with ``GECKO_HOME=home`` until the block ends (then SIGTERM,
    and SIGKILL to the whole group if anything is left, so a failing test leaks nothing)."""
    port = free_port()
    log_path = home / f"uvicorn-{port}.log"
    home.mkdir(parents=True, exist_ok=True)
    command = [
        sys.executable, "-m", "uvicorn", "service.app:create_app", "--factory",
        "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers),
        "--no-access-log", "--timeout-graceful-shutdown", str(grace_s),
        "--timeout-worker-healthcheck", str(healthcheck_s),
    ]  # fmt: skip
    with log_path.open("wb") as log:
        popen = subprocess.Popen(
            command,
            cwd=REPO_ROOT,
            env=_env(home, env or {}),
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,  # its own process group: cleaned up whole below
        )
    server = ServerProcess(popen, f"http://127.0.0.1:{port}", workers, log_path)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            if popen.poll() is not None:
                raise RuntimeError(f"uvicorn exited with {popen.returncode}:\n{server.log()}")
            try:
                if httpx.get(f"{server.url}/health", timeout=5).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"uvicorn did not answer within {START_TIMEOUT_S} s")
            time.sleep(0.2)
        # Every worker started serving (they share the socket: one alone answers /health).
        while server.log().count("Application startup complete") < workers:
            assert time.monotonic() < deadline, f"the workers did not all start:\n{server.log()}"
            time.sleep(0.2)
        yield server
    finally:
        if popen.poll() is None:
            popen.send_signal(signal.SIGTERM)
            with suppress(subprocess.TimeoutExpired):
                popen.wait(timeout=STOP_TIMEOUT_S)
        with suppress(ProcessLookupError):
            os.killpg(popen.pid, signal.SIGKILL)  # anything left of the group
        popen.wait(timeout=30)
