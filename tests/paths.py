"""Where the repository and the shared offline-data cache are, for tests."""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent


def gecko_cache_dir() -> Path:
    """The offline-data cache that `make data` fills (shared by tests to avoid rebuilding)."""
    home = Path(os.environ.get("GECKO_HOME", REPO_ROOT / ".gecko"))
    return Path(os.environ.get("GECKO_CACHE_DIR", home / "cache"))
