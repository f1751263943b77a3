"""Liveness: answers at once, even while plans run in the worker pool."""

from __future__ import annotations

from fastapi import APIRouter

from service import __version__
from service.deps import RegistryDep
from service.schemas import Health

router = APIRouter(tags=["health"])


@router.get("/health")
async def health(registry: RegistryDep) -> Health:
    """The service is up; counts of what it serves."""
    return Health(
        version=__version__,
        characters=len(registry.characters),
        scenes=len(registry.scene_ids()),
    )
