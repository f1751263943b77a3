"""Service settings, read from ``GECKO_*`` environment variables."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

REPO_ROOT = Path(__file__).resolve().parent.parent
# Upper bounds (s) of the request latency histogram's buckets: /health and listings take
# milliseconds, Twister steps tenths of a second, plans and jumps seconds (budget at most 60).
LATENCY_BUCKETS_S = (
    0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 20.0, 40.0, 80.0,
)  # fmt: skip
LogLevel = Literal["debug", "info", "warning", "error"]

# Admission control (service.lanes). Seconds a refused client is told to wait (Retry-After),
# per lane: interactive answers take about a second, uploads and background jobs longer.
RETRY_AFTER_S = {"interactive": 1, "jobs": 5, "uploads": 5}
SHORT_DEMAND_S = 10.0
"""s: while a Twister step arrived this recently, plans and jumps leave
``Settings.step_processes`` planning processes to steps: longer than a player's pause
between moves, and than a load-test client's wait on a jump or plan (up to 5 s under load).
"""
UPLOAD_CONCURRENCY = 1  # uploads parsed at once per service worker (the others wait in line)
# An uploaded mesh may have at most this many vertices per allowed triangle (counted before
# duplicates merge): more is a file padded with vertices no triangle needs.
VERTICES_PER_TRIANGLE = 3
# Jobs (service.jobs): how often (s) a service worker renews its heartbeat and looks for
# DELETEs of the jobs it runs, and how old (s) a heartbeat may be before the jobs of its
# service worker are reported interrupted (it died without saying so).
JOB_POLL_S = 0.5
JOB_OWNER_STALE_S = 15.0
JOBS_KEPT = 10_000  # finished jobs kept in the store; the oldest go first


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
    max_upload_bytes: int = Field(
        default=50 * 1024 * 1024, gt=0, le=1024**3, description="largest mesh upload body"
    )
    max_triangles: int = Field(
        default=2_000_000,
        gt=0,
        le=50_000_000,
        description="most triangles of an uploaded mesh, counted after instancing; at most "
        f"{VERTICES_PER_TRIANGLE} times as many vertices",
    )
    scenes_quota_bytes: int = Field(
        default=4 * 1024**3,
        ge=1024 * 1024,
        le=1024**4,
        description="bytes all uploaded scenes may take on disk: their mesh, metadata and "
        "details files in the scenes directory and their cached BVH (about 550 bytes a "
        "triangle) in the cache directory; an upload past it is refused with 507",
    )
    roadmaps_quota_bytes: int = Field(
        default=1024**3,
        ge=1024 * 1024,
        le=1024**4,
        description="bytes the stored jump roadmaps may take on disk (about 800 bytes a "
        "node); a build that would go past it is refused with 507 (before it starts, on "
        "1200 bytes a node), and DELETE /v1/roadmaps/{id} removes a finished one",
    )
    scenes_cached: int = Field(
        default=8,
        ge=1,
        le=1024,
        description="uploaded scenes kept loaded per process, least recently used unloaded "
        "first (they reload from disk on use)",
    )
    upload_timeout_s: float = Field(
        default=300.0,
        ge=1.0,
        le=3600.0,
        description="s; an upload's parse and build past this is stopped (504), its process killed",
    )
    worker_processes: int = Field(
        default=2, ge=1, le=64, description="planning processes per service worker"
    )
    worker_nice: int = Field(
        default=10,
        ge=0,
        le=19,
        description="niceness added to the planning, job and upload processes, so that the "
        "service process (its event loop, /health) gets a core at once when it needs one",
    )
    data_seed: int = Field(default=0, ge=0)
    interactive_queue: int = Field(
        default=16,
        ge=0,
        le=1024,
        description="plans and jumps that may wait for a planning process (beyond those "
        "running) per service worker; more get 503 with Retry-After",
    )
    step_queue: int = Field(
        default=2,
        ge=0,
        le=1024,
        description="Twister steps that may wait for a planning process per service worker "
        "(served before the plans and jumps waiting); more get 503 with Retry-After. Measured "
        "on 2 processes, steps alone at 16 and 64 clients: 49 per second either way, p99 "
        "118-154 ms with 2 waiting, 182-211 ms with 4",
    )
    step_processes: int = Field(
        default=1,
        ge=0,
        le=64,
        description="planning processes (of GECKO_WORKER_PROCESSES, at most all but one) "
        "that plans and jumps leave to Twister steps while steps keep coming (one arrived "
        "in the last 10 s): a step never waits behind seconds of planning",
    )
    job_processes: int = Field(
        default=1,
        ge=1,
        le=16,
        description="processes per service worker for background jobs (roadmap builds, "
        "asynchronous plans), apart from the planning processes",
    )
    job_queue: int = Field(
        default=16,
        ge=0,
        le=1024,
        description="background jobs that may wait for a job process per service worker; "
        "more get 503 with Retry-After",
    )
    upload_queue: int = Field(
        default=4,
        ge=0,
        le=64,
        description="scene uploads that may wait while another is parsed, per service "
        "worker; more get 503 with Retry-After",
    )
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

    log_level: LogLevel = Field(
        default="info", description="level of the service's JSON log lines (one per request)"
    )
    cors_origins: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="origins browsers may call the API from, comma-separated (e.g. "
        "'https://a.example,http://localhost:5173', or '*'); empty: no CORS headers",
    )
    gzip_minimum_bytes: int = Field(
        default=1024,
        ge=0,
        le=1024**3,
        description="answers of at least this many bytes are gzipped for clients that accept "
        "it (Accept-Encoding: gzip)",
    )
    gzip_level: int = Field(
        default=6, ge=1, le=9, description="gzip compression level (1 fastest, 9 smallest)"
    )

    @field_validator("cors_origins", mode="before")
    @classmethod
    def _split_origins(cls, value: object) -> object:
        if isinstance(value, str):
            return [part.strip() for part in value.split(",") if part.strip()]
        return value

    @field_validator("cors_origins")
    @classmethod
    def _check_origins(cls, value: list[str]) -> list[str]:
        for origin in value:
            if origin != "*" and not origin.startswith(("http://", "https://")):
                raise ValueError(f"CORS origin '{origin}' must be '*' or start with http(s)://")
        return [origin.rstrip("/") for origin in value]

    @property
    def max_vertices(self) -> int:
        """Most vertices of an uploaded mesh (counted after instancing, before merging)."""
        return VERTICES_PER_TRIANGLE * self.max_triangles

    @property
    def cache_path(self) -> Path:
        """Offline data and collision caches."""
        return self.cache_dir or self.home / "cache"

    @property
    def roadmaps_path(self) -> Path:
        """Jump roadmaps and their build status files."""
        return self.home / "roadmaps"

    @property
    def jobs_db_path(self) -> Path:
        """The SQLite file of the job store, shared by every service worker."""
        return self.home / "jobs.sqlite3"

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
