"""Upload benchmark: answer time of uploads refused by their counts and of accepted ones, with
/health polled throughout, and the listing and details after a restart.

Usage: ``python bench/uploads.py``. A real server (uvicorn on a local port, default limits:
2 million triangles, 50 MiB bodies) in a temporary home; the meshes are the issue's cases: a
GLB whose one 20,480-triangle mesh 95 (accepted) or 105 (refused) nodes instance, and
grid PLYs of 500,000 (accepted) and 2.5 million (refused) triangles. The first upload of a
run also starts the uploads lane's process. Targets: refusals in well under a second; /health
p99 under 50 ms and never over 100 ms while uploads are parsed and built; after a restart the
listing and details in milliseconds (no scene loaded). Prints, asserts nothing.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import httpx
import trimesh

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from service.settings import Settings  # noqa: E402
from tests.live_server import live_server  # noqa: E402
from tests.mesh_files import grid_ply, instanced_glb  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402
from tests.service.test_uploads import HealthProbe  # noqa: E402

LISTINGS = 5  # GET /v1/scenes repeated after the restart (median printed)


def _cases() -> list[tuple[str, str, bytes]]:
    box = trimesh.creation.box().export(file_type="stl")
    assert isinstance(box, bytes)
    return [
        ("box (starts the uploads process)", "stl", box),
        ("GLB 105 x 20,480 = 2.15 M triangles", "glb", instanced_glb(105, subdivisions=5)),
        ("PLY 2.5 M triangles", "ply", grid_ply(2_500_000)),
        ("GLB 95 x 20,480 = 1.95 M triangles", "glb", instanced_glb(95, subdivisions=5)),
        ("PLY 500 k triangles", "ply", grid_ply(500_000)),
    ]


def main() -> None:
    home = Path(tempfile.mkdtemp(prefix="gecko-bench-uploads-"))
    settings = Settings(
        home=home,
        cache_dir=gecko_cache_dir(),
        scenes_dir=home / "scenes",
        characters="humanoid",
        log_level="warning",
    )
    print(f"{'upload':38} {'MB':>6} {'status':>6} {'s':>7} {'health p50':>10} {'max ms':>7}")
    with live_server(settings) as url, httpx.Client(base_url=url, timeout=600) as http:
        for label, fmt, body in _cases():
            with HealthProbe(url) as probe:
                started = time.perf_counter()
                answer = http.post("/v1/scenes", params={"format": fmt}, content=body)
                seconds = time.perf_counter() - started
                time.sleep(0.1)
            latencies = [1000 * s for s in probe.latencies]
            print(
                f"{label:38} {len(body) / 1e6:6.2f} {answer.status_code:6d} {seconds:7.2f} "
                f"{statistics.median(latencies):10.1f} {max(latencies):7.1f}"
            )
    stored = sum(p.stat().st_size for p in (home / "scenes").iterdir()) / 1e6
    print(f"stored: {stored:.1f} MB")
    with live_server(settings) as url, httpx.Client(base_url=url, timeout=600) as http:
        times = []
        for _ in range(LISTINGS):
            started = time.perf_counter()
            listing = http.get("/v1/scenes").json()
            times.append(1000 * (time.perf_counter() - started))
        print(
            f"after a restart: GET /v1/scenes ({len(listing)} scenes) first {times[0]:.1f} ms, "
            f"median {statistics.median(times):.1f} ms"
        )
        for scene in listing:
            if scene["builtin"]:
                continue
            started = time.perf_counter()
            detail = http.get(f"/v1/scenes/{scene['id']}")
            ms = 1000 * (time.perf_counter() - started)
            print(
                f"after a restart: GET /v1/scenes/{scene['id'][:8]} "
                f"({scene['triangle_count']} triangles, {len(detail.content) / 1e3:.0f} kB) "
                f"{ms:.1f} ms"
            )


if __name__ == "__main__":
    main()
