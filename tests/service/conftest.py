"""HTTP fixtures: the real app in process, lifespan run."""

from tests.app_fixtures import anyio_backend, client, in_process_worker, settings

__all__ = ["anyio_backend", "client", "in_process_worker", "settings"]
