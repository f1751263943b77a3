"""glTF export benchmark: export time and GLB size against the JSON answer, per reference
plan, and the viewer's first paint in headless Chromium.

Usage: ``python bench/export.py [--scenario NAME ...] [--repeats 20] [--no-browser]``.
Plans come from ``tests/scenarios/plans/`` (default: a few on the built-in characters),
computed by a real server (uvicorn on a local port, as the tests run it) and stored; the
export is then timed in this process on the stored answer (median of ``--repeats``): the
character with its animation, and with the scene and overlays added (what the viewer loads).
Targets: export < 50 ms; for a 30 s motion the GLB no larger than the JSON. First paint:
from the page's request to its first frame with the motion loaded (Chromium, SwiftShader).
Prints, asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from service.export import result_glb  # noqa: E402
from service.results import StoredResult  # noqa: E402
from service.settings import Settings  # noqa: E402
from service.workers import registry_for  # noqa: E402
from tests.headless_browser import chromium_paths, start_chromium  # noqa: E402
from tests.live_server import live_server  # noqa: E402
from tests.paths import gecko_cache_dir  # noqa: E402

PLANS = ROOT / "tests" / "scenarios" / "plans"
DEFAULT = ("flat_short_humanoid", "flat_walk_humanoid", "flat_walk_quadruped", "stairs_humanoid")
TARGETS = "targets: export < 50 ms; a 30 s motion's GLB no larger than its JSON"
PLAN_FIELDS = ("character", "scene", "start", "goal", "options", "seed", "time_budget_s")


def _median_ms(function: Any, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def first_paint_ms(url: str, rid: str, runs: int = 3) -> tuple[float, float] | None:
    """Median (page request -> first frame with the motion, GLB load -> that frame), ms."""
    paths = chromium_paths()
    if paths is None:
        print("viewer first paint: chromium/chromedriver not installed, skipped")
        return None
    driver = start_chromium(paths)
    totals, loads = [], []
    try:
        for _ in range(runs):
            driver.get("about:blank")
            driver.get(f"{url}/viewer?plan={rid}")
            deadline = time.monotonic() + 120
            while driver.execute_script("return document.body.dataset.painted") != "true":
                if time.monotonic() > deadline:
                    raise RuntimeError("the viewer did not paint within 120 s")
                time.sleep(0.01)
            loads.append(float(driver.execute_script("return window.gecko.firstPaintMs")))
            # performance.now() counts from the navigation's start (the page request)
            totals.append(float(driver.execute_script("return window.gecko.paintedAt")))
    finally:
        driver.quit()
    return statistics.median(totals), statistics.median(loads)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", nargs="*", default=list(DEFAULT))
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--no-browser", action="store_true")
    args = parser.parse_args()

    home = Path(tempfile.mkdtemp(prefix="gecko-bench-export-"))
    settings = Settings(home=home, cache_dir=gecko_cache_dir(), scenes_dir=home / "scenes")
    registry = registry_for(settings)
    print(TARGETS)
    header = (
        f"{'scenario':24s} {'motion s':>8s} {'frames':>6s} {'JSON kB':>8s} {'GLB kB':>7s} "
        f"{'GLB/JSON':>8s} {'export ms':>9s} {'+scene+overlays':>15s} {'kB':>6s}"
    )
    print(header)
    first_id = None
    with live_server(settings) as url:
        for name in args.scenario:
            scenario = json.loads((PLANS / f"{name}.json").read_text())
            request = {k: scenario[k] for k in PLAN_FIELDS if k in scenario}
            response = httpx.post(f"{url}/v1/plans", json=request, timeout=300)
            answer = response.json()
            if response.status_code != 200 or not answer.get("keyframes"):
                print(f"{name:24s} no motion ({response.status_code}, {answer.get('status')})")
                continue
            json_bytes = len(httpx.get(f"{url}/v1/plans/{answer['id']}", timeout=60).content)
            stored = StoredResult("plan", answer["id"], {**request, "seed": answer["seed"]}, answer)

            def plain(stored: StoredResult = stored) -> bytes:
                return result_glb(registry, stored, with_scene=False, with_overlays=False)

            def full(stored: StoredResult = stored) -> bytes:
                return result_glb(registry, stored, with_scene=True, with_overlays=True)

            plain(), full()  # warm: character meshes and scene loaded once
            plain_ms, full_ms = _median_ms(plain, args.repeats), _median_ms(full, args.repeats)
            plain_size, full_size = len(plain()), len(full())
            duration = answer["keyframes"][-1]["t"] - answer["keyframes"][0]["t"]
            print(
                f"{name:24s} {duration:8.1f} {len(answer['keyframes']):6d} "
                f"{json_bytes / 1e3:8.0f} {plain_size / 1e3:7.0f} "
                f"{plain_size / json_bytes:8.2f} {plain_ms:9.1f} {full_ms:15.1f} "
                f"{full_size / 1e3:6.0f}"
            )
            first_id = first_id or answer["id"]
        if first_id and not args.no_browser:
            paint = first_paint_ms(url, first_id)
            if paint is not None:
                print(
                    f"viewer first paint (headless Chromium, SwiftShader, median of 3): "
                    f"{paint[0]:.0f} ms from the page request, {paint[1]:.0f} ms of it "
                    "from opening the GLB"
                )
    shutil.rmtree(home, ignore_errors=True)


if __name__ == "__main__":
    main()
