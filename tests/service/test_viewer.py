"""The viewer in a real headless browser (Debian's chromium + chromedriver, selenium) against
a real server: it loads stored results with no console errors, draws something, scrubbing
moves the character, and its timeline lists the plan's phases."""

from __future__ import annotations

import io
import time
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest

webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
Image = pytest.importorskip("PIL.Image", reason="pillow is not installed")

from tests.headless_browser import chromium_paths, start_chromium  # noqa: E402

READY_TIMEOUT_S = 90.0


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless Chromium driven by chromedriver, WebGL through SwiftShader."""
    paths = chromium_paths()
    if paths is None:
        pytest.skip(
            "chromium and chromium-driver are not installed: `make setup` installs them with "
            "apt-get when run as root (apt-get install chromium chromium-driver)"
        )
    driver = start_chromium(paths, console_log=True)
    try:
        yield driver
    finally:
        driver.quit()


def _open(browser: Any, url: str) -> None:
    browser.get_log("browser")  # drop what earlier pages logged
    browser.get(url)
    deadline = time.monotonic() + READY_TIMEOUT_S
    while True:
        state = browser.execute_script("return document.body.dataset.state")
        painted = browser.execute_script("return document.body.dataset.painted")
        if state == "error":
            message = browser.find_element("id", "message").text
            raise AssertionError(f"the viewer failed: {message}")
        if state == "ready" and painted == "true":
            return
        assert time.monotonic() < deadline, f"viewer not ready after {READY_TIMEOUT_S} s: {state}"
        time.sleep(0.1)


def _console_errors(browser: Any) -> list[str]:
    return [entry["message"] for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]


def _next_frames(browser: Any, count: int = 3) -> None:
    browser.execute_async_script(
        """
        const done = arguments[arguments.length - 1];
        let left = arguments[0];
        const step = () => (--left <= 0 ? done() : requestAnimationFrame(step));
        requestAnimationFrame(step);
        """,
        count,
    )


def _canvas_pixels(browser: Any) -> np.ndarray:
    png = browser.find_element("id", "view").screenshot_as_png
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float64)


def _scrub(browser: Any, t: float) -> None:
    """Move the time slider as a user would (value set, 'input' event fired)."""
    browser.execute_script(
        """
        const scrub = document.getElementById('scrub');
        scrub.value = String(arguments[0]);
        scrub.dispatchEvent(new Event('input', {bubbles: true}));
        """,
        t,
    )
    _next_frames(browser)


def test_viewer_plays_a_stored_plan(
    browser: Any, gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    plan = live_results["plan"]
    _open(browser, f"{gecko_url}/viewer?plan={plan['id']}")
    assert _console_errors(browser) == []
    browser.find_element("id", "follow").click()  # a fixed camera: only the body moves

    start = browser.execute_script("return window.gecko.start")
    end = browser.execute_script("return window.gecko.end")
    assert end > start
    _scrub(browser, start)
    first = _canvas_pixels(browser)
    assert first.shape[0] > 100 and first.shape[1] > 100
    background = np.median(first.reshape(-1, 3), axis=0)
    off_background = np.abs(first - background).max(axis=2) > 30
    assert first.std() > 10.0, "the canvas is flat"
    assert off_background.mean() > 0.01, "almost nothing drawn over the background"

    _scrub(browser, 0.5 * (start + end))
    assert browser.execute_script("return window.gecko.time") == pytest.approx(
        0.5 * (start + end), abs=1e-3
    )
    middle = _canvas_pixels(browser)
    changed = np.abs(middle - first).max(axis=2) > 40
    assert changed.sum() > 500, f"scrubbing to the middle changed {changed.sum()} pixels"
    assert _console_errors(browser) == []


def test_timeline_lists_the_plans_phases(
    browser: Any, gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    plan = live_results["plan"]
    _open(browser, f"{gecko_url}/viewer?plan={plan['id']}")
    blocks = browser.find_elements("css selector", "#phases .phase")
    assert len(blocks) == len(plan["phases"])
    for block, phase in zip(blocks, plan["phases"], strict=True):
        limbs = [c["limb"] for c in phase["contacts"]]
        assert block.get_attribute("data-limbs") == ",".join(limbs)
        assert float(block.get_attribute("data-t0")) == pytest.approx(phase["t0"])
    rows = browser.find_elements("css selector", "#limbs .limb")
    expected = {c["limb"] for phase in plan["phases"] for c in phase["contacts"]}
    assert {row.get_attribute("data-limb") for row in rows} == expected
    middle = 0.5 * (plan["phases"][0]["t0"] + plan["phases"][-1]["t1"])
    _scrub(browser, middle)
    current = int(browser.execute_script("return document.body.dataset.phase"))
    phase = plan["phases"][current]
    assert phase["t0"] - 1e-6 <= middle <= phase["t1"] + 1e-6
    assert _console_errors(browser) == []


def test_viewer_draws_the_current_phases_equilibrium_region(
    browser: Any, gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    """Mid-phase, the outline on screen is a horizontal convex loop around the phase's
    contact points (its static equilibrium region, the support polygon on flat ground), and
    around the COM's (x, y) too when the plan's COM is quasi-static (a dynamic COM leaves
    the support polygon in single support: its wrench, not its position, stays inside)."""
    plan = live_results["plan"]
    _open(browser, f"{gecko_url}/viewer?plan={plan['id']}")
    drawn = 0
    for index, phase in enumerate(plan["phases"]):
        middle = 0.5 * (phase["t0"] + phase["t1"])
        _scrub(browser, middle)
        assert int(browser.execute_script("return document.body.dataset.phase")) == index
        outline = np.asarray(browser.execute_script("return window.gecko.equilibrium"))
        if len(outline) == 0:
            continue
        drawn += 1
        # glTF (x, y, z) -> Gecko (x, -z, y): the loop is horizontal in Gecko's world.
        loop = np.column_stack([outline[:, 0], -outline[:, 2]])
        assert np.ptp(outline[:, 1]) < 1e-6
        edges = np.roll(loop, -1, axis=0) - loop
        points = np.array([p for c in phase["contacts"] for p in c["points"]])
        assert _inside(loop, points.mean(axis=0)), (index, loop, points)
        turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
        assert np.all(turns >= -1e-9) or np.all(turns <= 1e-9), (index, loop)  # convex
        com = _com_at(plan["com"], middle)
        if plan["report"]["phase_methods"][index] != "2pac+dynamic":
            assert _inside(loop, com), (index, loop, com)
    assert drawn >= len(plan["phases"]) // 2
    assert _console_errors(browser) == []


def _inside(loop: np.ndarray, point: np.ndarray) -> bool:
    """Whether (x, y) of ``point`` lies in the convex loop (k, 2), 1 mm tolerance."""
    edges = np.roll(loop, -1, axis=0) - loop
    cross = edges[:, 0] * (point[1] - loop[:, 1]) - edges[:, 1] * (point[0] - loop[:, 0])
    return bool(np.all(cross >= -1e-3) or np.all(cross <= 1e-3))


def _com_at(segments: list[dict[str, Any]], t: float) -> np.ndarray:
    """The COM (3,) at t on the plan's Bezier segments (de Casteljau, written here)."""
    for segment in segments:
        if segment["t0"] <= t <= segment["t1"]:
            points = np.asarray(segment["control_points"], dtype=np.float64)
            s = (t - segment["t0"]) / max(segment["t1"] - segment["t0"], 1e-12)
            while len(points) > 1:
                points = (1 - s) * points[:-1] + s * points[1:]
            return points[0]
    raise AssertionError(f"no COM segment covers t = {t}")


@pytest.mark.parametrize("kind", ["step", "jump"])
def test_viewer_opens_steps_and_jumps(
    browser: Any, gecko_url: str, live_results: dict[str, dict[str, Any]], kind: str
) -> None:
    _open(browser, f"{gecko_url}/viewer?{kind}={live_results[kind]['id']}")
    assert browser.execute_script("return window.gecko.phases.length") >= 1
    assert _console_errors(browser) == []


def test_viewer_lists_recent_results_and_reports_unknown_ids(
    browser: Any, gecko_url: str, live_results: dict[str, dict[str, Any]]
) -> None:
    browser.get(f"{gecko_url}/viewer")
    deadline = time.monotonic() + 30
    while len(browser.find_elements("css selector", "#recent option")) < 2:
        assert time.monotonic() < deadline, "no recent results listed"
        time.sleep(0.1)
    values = [
        o.get_attribute("value") for o in browser.find_elements("css selector", "#recent option")
    ]
    assert f"plan:{live_results['plan']['id']}" in values
    browser.get(f"{gecko_url}/viewer?plan={'0' * 32}")
    deadline = time.monotonic() + 30
    while browser.execute_script("return document.body.dataset.state") != "error":
        assert time.monotonic() < deadline, "an unknown id should show an error"
        time.sleep(0.1)
    assert "unknown plan" in browser.find_element("id", "message").text


def test_vendored_three_ships_with_its_licence(gecko_url: str) -> None:
    licence = httpx.get(f"{gecko_url}/static/vendor/three/LICENSE", timeout=10)
    assert licence.status_code == 200 and "MIT" in licence.text
    for path in (
        "build/three.module.js",
        "build/three.core.js",
        "examples/jsm/controls/OrbitControls.js",
        "examples/jsm/loaders/GLTFLoader.js",
    ):
        assert httpx.get(f"{gecko_url}/static/vendor/three/{path}", timeout=10).status_code == 200
