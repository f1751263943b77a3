"""The one exception the scene layer raises for unusable input."""

from __future__ import annotations


class SceneError(ValueError):
    """A mesh or scene request that cannot be used.

    message : what is wrong, for a human; field : which input it concerns (e.g. ``"mesh"``,
    ``"format"``, ``"vertices"``), so the service can report it as ``error.field``.
    """

    def __init__(self, message: str, field: str = "mesh") -> None:
        super().__init__(message)
        self.message = message
        self.field = field

    def __str__(self) -> str:
        return f"{self.field}: {self.message}"
