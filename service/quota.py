"""Storage quotas of the service's stores on disk (uploaded scenes, jump roadmaps): the
refusal, and the lock that serialises the quota checks of every process on a directory."""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

LOCK_FILE = ".lock"  # in a store's directory: serialises its quota checks across processes


class QuotaExceeded(Exception):
    """Storing ``adding`` bytes would take a store (``store``: what it holds, for the
    message) past its quota; ``used`` bytes are stored already."""

    def __init__(self, *, store: str, used: int, adding: int, quota: int) -> None:
        super().__init__(store, used, adding, quota)
        self.store, self.used, self.adding, self.quota = store, used, adding, quota

    def __str__(self) -> str:
        return (
            f"{self.store} take {self.used} bytes; {self.adding} more would go past the "
            f"quota of {self.quota}"
        )


@contextmanager
def directory_lock(directory: Path) -> Iterator[None]:
    """Exclusive use of ``directory``'s quota across processes (an advisory lock on its
    ``LOCK_FILE``), for a check and the renames it admits."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / LOCK_FILE, "a+b") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
