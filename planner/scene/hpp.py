"""The multi-contact scene meshes of the optional ``hpp-environments`` package."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path


def hpp_environment_meshes() -> dict[str, Path]:
    """Scene name (file stem) -> path of each installed ``meshes/multicontact/*.stl``.

    Empty when hpp-environments is not installed.
    """
    try:
        files = importlib.metadata.files("hpp-environments") or []
    except importlib.metadata.PackageNotFoundError:
        return {}
    found: dict[str, Path] = {}
    for entry in files:
        text = str(entry).replace("\\", "/")
        if "hpp_environments/meshes/multicontact/" in text and text.lower().endswith(".stl"):
            path = Path(str(entry.locate()))
            if path.is_file():
                found[path.stem] = path
    return dict(sorted(found.items()))
