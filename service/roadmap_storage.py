"""The jump roadmaps' storage quota (``GECKO_ROADMAPS_QUOTA_BYTES``).

A build is refused before it starts when its estimated size (``ROADMAP_BYTES_PER_NODE`` per
node asked for) would take the stored roadmaps past the quota, and its files are admitted
into the store only if their real size still fits, checked under a lock on the roadmaps
directory shared by every process (two builds admitted together cannot both overflow it).
A DELETE of a finished roadmap frees its bytes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

from planner.ballistic.planner import RoadmapStore
from service.errors import INSUFFICIENT_STORAGE, ApiError
from service.quota import QuotaExceeded, directory_lock

STORE = "the stored roadmaps"

ROADMAP_BYTES_PER_NODE = 1200
"""Bytes a stored roadmap takes per node, at most, for the estimate made before a build:
measured 720 to 790 (.npz and .json) for the quadruped, the hexapod and the humanoid on the
gaps, at 300 and 1,500 nodes (about 19 edges a node), and 1.5 times that."""


def quota_exceeded(exc: QuotaExceeded, field: str = "nodes") -> ApiError:
    """A 507 naming the roadmaps' quota and how to make room."""
    return ApiError(
        INSUFFICIENT_STORAGE,
        "quota_exceeded",
        f"{exc} (GECKO_ROADMAPS_QUOTA_BYTES); DELETE /v1/roadmaps/{{id}} the roadmaps no "
        "longer needed to make room",
        field,
    )


def check_room(directory: Path, nodes: int, quota_bytes: int) -> None:
    """Raise :class:`QuotaExceeded` when a roadmap of ``nodes`` nodes, at its
    estimated size, would not fit beside the roadmaps stored in ``directory``."""
    used = RoadmapStore(directory).used_bytes()
    adding = nodes * ROADMAP_BYTES_PER_NODE
    if used + adding > quota_bytes:
        raise QuotaExceeded(store=STORE, used=used, adding=adding, quota=quota_bytes)


def admission(directory: Path, quota_bytes: int) -> Callable[[int], AbstractContextManager[None]]:
    """The ``admit`` of ``RoadmapStore.save`` for the quota: entered with the size of the
    files to store, it holds the directory's lock and raises
    :class:`QuotaExceeded` when they would not fit."""
    store = RoadmapStore(directory)

    @contextmanager
    def admit(size: int) -> Iterator[None]:
        with directory_lock(directory):
            used = store.used_bytes()
            if used + size > quota_bytes:
                raise QuotaExceeded(store=STORE, used=used, adding=size, quota=quota_bytes)
            yield

    return admit
