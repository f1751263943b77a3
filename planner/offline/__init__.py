"""Offline data of characters: reachable workspaces, sample databases, COM constraints.

Built by ``gecko-build-data`` (:mod:`planner.offline.cli`) and cached on disk.
"""

from planner.offline.build import OfflineParams
from planner.offline.data import (
    CODE_VERSION,
    ComConstraint,
    LimbOfflineData,
    OfflineData,
    build_offline_data,
    cache_key,
    default_cache_dir,
    load_offline_data,
)
from planner.offline.database import SampleDatabase

__all__ = [
    "CODE_VERSION",
    "ComConstraint",
    "LimbOfflineData",
    "OfflineData",
    "OfflineParams",
    "SampleDatabase",
    "build_offline_data",
    "cache_key",
    "default_cache_dir",
    "load_offline_data",
]
