"""Temporary files of atomic writes: how to recognise them, and removing those a crash left.

Every store of the service (uploaded scenes, results, roadmaps) writes to a temporary file in
its own directory and renames it into place. A process killed between the two leaves the
temporary file behind; listings skip such files and start-up removes them.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

log = logging.getLogger("gecko.files")

TEMPORARY_PREFIXES = (".tmp-", ".bvh-")
TEMPORARY_SUFFIXES = (".tmp",)


def is_temporary(name: str) -> bool:
    """True for the name of a temporary file of an atomic write (``.tmp-*``, ``*.tmp``)."""
    return name.startswith(TEMPORARY_PREFIXES) or name.endswith(TEMPORARY_SUFFIXES)


def remove_leftovers(directory: Path, *, older_than_s: float) -> list[Path]:
    """Remove the temporary files in ``directory`` (not below it) last modified more than
    ``older_than_s`` seconds ago; returns the paths removed.

    The age guard spares a write in progress in another service worker sharing the directory.
    """
    if not directory.is_dir():
        return []
    now = time.time()
    removed = []
    for path in directory.iterdir():
        if not is_temporary(path.name):
            continue
        try:
            if not path.is_file() or now - path.stat().st_mtime < older_than_s:
                continue
            path.unlink()
        except OSError as exc:  # gone meanwhile, or not ours to remove
            log.debug("leftover %s not removed: %s", path, exc)
            continue
        removed.append(path)
    if removed:
        log.warning("removed %d leftover temporary files in %s", len(removed), directory)
    return removed
