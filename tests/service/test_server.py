"""The real server: uvicorn in a subprocess, as `make serve` runs it, answers /health."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time

import httpx

from tests.paths import REPO_ROOT, gecko_cache_dir


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_uvicorn_serves_health(tmp_path: object) -> None:
    port = _free_port()
    env = {
        **os.environ,
        "GECKO_HOME": str(tmp_path),
        "GECKO_CACHE_DIR": str(gecko_cache_dir()),
        "GECKO_CHARACTERS": "humanoid,quadruped,hexapod",
    }
    command = [
        sys.executable, "-m", "uvicorn", "service.app:create_app", "--factory",
        "--host", "127.0.0.1", "--port", str(port),
    ]  # fmt: skip
    server = subprocess.Popen(
        command, cwd=REPO_ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                response = httpx.get(f"http://127.0.0.1:{port}/health", timeout=2)
                break
            except httpx.TransportError:
                assert server.poll() is None, server.stdout.read().decode() if server.stdout else ""
                assert time.monotonic() < deadline, "server did not answer within 60 s"
                time.sleep(0.2)
        assert response.status_code == 200
        assert response.json()["status"] == "ok"
        assert response.json()["characters"] == 3
    finally:
        server.terminate()
        server.wait(timeout=20)
