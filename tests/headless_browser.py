"""Headless Chromium for the viewer's tests and benchmark: Debian's ``chromium`` driven by
``chromedriver`` through selenium, WebGL rendered in software (SwiftShader)."""

from __future__ import annotations

import shutil
from typing import Any

CHROMIUM_ARGUMENTS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-dev-shm-usage",
    "--window-size=1100,800",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-gpu-sandbox",
)


def chromium_paths() -> tuple[str, str] | None:
    """(chromium, chromedriver) executables, None when either is not installed."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    return None if chromium is None or driver is None else (chromium, driver)


def start_chromium(paths: tuple[str, str], *, console_log: bool = False) -> Any:
    """A selenium Chrome driver on headless Chromium; ``console_log`` keeps the page's
    console for ``get_log('browser')``."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium, driver_path = paths
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for argument in CHROMIUM_ARGUMENTS:
        options.add_argument(argument)
    if console_log:
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    driver.set_page_load_timeout(60)
    return driver
