"""The browser viewer: ``/viewer`` (an HTML page) and its static files under ``/static``
(the page's script and style, and three.js vendored from its npm release)."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
router = APIRouter(tags=["viewer"])


@router.get("/viewer", include_in_schema=False)
async def viewer_page() -> FileResponse:
    """The viewer; ``/viewer?plan=<id>`` (or ``step=``, ``jump=``) opens a result directly."""
    return FileResponse(STATIC_DIR / "viewer" / "index.html", media_type="text/html")


def install(app: FastAPI) -> None:
    """Serve the viewer page and its static files."""
    app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
