"""The Khronos glTF validator (npm ``gltf-validator``, installed by ``make setup`` from
tools/package-lock.json), run with Node on GLB files."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from tests.paths import REPO_ROOT

SCRIPT = REPO_ROOT / "tools" / "gltf_validate.js"
PACKAGE = REPO_ROOT / "tools" / "node_modules" / "gltf-validator"


def validate(paths: list[Path]) -> list[dict[str, Any]]:
    """One validation report per file (the validator's JSON); skips the test when Node or
    the validator is missing."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("Node is not installed: `make setup` installs it (apt-get, as root)")
    if not PACKAGE.is_dir():
        pytest.skip("gltf-validator is not installed: run `npm ci --prefix tools`")
    done = subprocess.run(
        [node, str(SCRIPT), *map(str, paths)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    reports: list[dict[str, Any]] = json.loads(done.stdout)
    return reports


def errors_of(report: dict[str, Any]) -> list[str]:
    """The report's errors (severity 0) as 'CODE at pointer: message' lines."""
    return [
        f"{m['code']} at {m.get('pointer', '')}: {m['message']}"
        for m in report["issues"]["messages"]
        if m["severity"] == 0
    ]
