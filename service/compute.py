"""Planning work run inside worker processes: request JSON in, response JSON out.

Each function takes the validated request as a JSON string (cheap to pickle), resolves the
character and scene in the worker's registry, calls the planner and converts the answer.
Errors the client can fix are raised as :class:`~service.errors.ApiError` (picklable).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

from planner.scene import Scene
from service.errors import ApiError, not_found
from service.registry import CharacterEntry
from service.workers import worker_registry


def character_entry(character_id: str) -> CharacterEntry:
    """The served character, or a 404 naming the ``character`` field."""
    entry = worker_registry().get_character(character_id)
    if entry is None:
        raise not_found("character", character_id, "character")
    return entry


def scene_by_id(scene_id: str) -> Scene:
    """The scene, or a 404 naming the ``scene`` field."""
    scene = worker_registry().get_scene(scene_id)
    if scene is None:
        raise not_found("scene", scene_id, "scene")
    return scene


class Stopwatch:
    """Wall-clock seconds per named stage, for the ``timings`` of a response."""

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - start


def invalid(message: str, field: str) -> ApiError:
    """A 422 the client can fix."""
    return ApiError(422, "invalid_request", message, field)
