"""The monitor's pages and the files they load from ``static/`` (HTML, CSS, the pages' ES modules),
for the monitor of one run and the overview of several alike."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import resources
from pathlib import PurePosixPath

from fastapi import APIRouter, HTTPException
from fastapi.responses import FileResponse

STATIC = resources.files("botstage.missions.monitor") / "static"
# A browser runs a module script only when it is served as JavaScript: the types are pinned here
# rather than left to the platform's table (Windows' registry can map .js to text/plain).
MEDIA_TYPES = {".html": "text/html", ".css": "text/css", ".js": "text/javascript"}


def static_file(name: str) -> FileResponse:
    media_type = MEDIA_TYPES.get(PurePosixPath(name).suffix)
    return FileResponse(str(STATIC / name), media_type=media_type, headers={"Cache-Control": "no-cache"})


def pages_router(pages: Mapping[str, str]) -> APIRouter:
    """Each page of ``pages`` (route: file name) and ``/static/{name}``, the files they load."""
    router = APIRouter(include_in_schema=False)
    for route, name in pages.items():
        router.add_api_route(route, _page(name), methods=["GET"])

    @router.get("/static/{name}")
    def static(name: str) -> FileResponse:
        if name not in {entry.name for entry in STATIC.iterdir()}:  # only the files we ship
            raise HTTPException(404, f"no file {name!r}")
        return static_file(name)

    return router


def _page(name: str) -> Callable[[], FileResponse]:
    def page() -> FileResponse:
        return static_file(name)

    return page
