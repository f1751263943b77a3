"""Service settings, read from ``GECKO_*`` environment variables."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

REPO_ROOT = Path(__file__).resolve().parent.parent


class Settings(BaseSettings):
    """Where Gecko keeps its files and how much work one request may ask for."""

    model_config = SettingsConfigDict(env_prefix="GECKO_")

    home: Path = Field(default=REPO_ROOT / ".gecko", description="root of caches and uploads")
    cache_dir: Path | None = Field(
        default=None, description="offline data and collision caches (default: <home>/cache)"
    )
    scenes_dir: Path | None = Field(
        default=None, description="uploaded scenes (default: <home>/scenes)"
    )
    build_missing_data: bool = Field(
        default=True, description="build a character's offline data at start-up if not cached"
    )
    characters: str = Field(
        default="auto",
        description="comma-separated character ids to serve, or 'auto' for the built-in ones "
        "plus the real robots whose data package is installed",
    )
    max_upload_bytes: int = Field(default=50 * 1024 * 1024, gt=0)
    max_triangles: int = Field(default=2_000_000, gt=0)
    worker_processes: int = Field(
        default=2, ge=1, le=64, description="planning processes per service worker"
    )
    data_seed: int = Field(default=0, ge=0)
    results_max_count: int = Field(
        default=500, ge=1, le=1_000_000, description="stored results kept (least recently used go)"
    )
    results_max_bytes: int = Field(
        default=512 * 1024 * 1024,
        ge=1024 * 1024,
        le=1024**4,
        description="bytes of stored results kept (least recently used go)",
    )

    leftover_min_age_s: float = Field(
        default=60.0,
        ge=0,
        le=86_400,
        description="s; temporary files of interrupted writes older than this are removed at "
        "start-up (younger ones may be another service worker's write in progress)",
    )

    @property
    def cache_path(self) -> Path:
        """Offline data and collision caches."""
        return self.cache_dir or self.home / "cache"

    @property
    def roadmaps_path(self) -> Path:
        """Jump roadmaps and their build status files."""
        return self.home / "roadmaps"

    @property
    def results_path(self) -> Path:
        """Stored plan, Twister step and jump answers (``service.results``)."""
        return self.home / "results"

    @property
    def scenes_path(self) -> Path:
        """Uploaded scenes, one ``<id>.npz`` + ``<id>.json`` pair each."""
        return self.scenes_dir or self.home / "scenes"


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings (read once from the environment)."""
    return Settings()
