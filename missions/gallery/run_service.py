"""The web set's run service: it gives runs the function that starts the gallery server, for a run's
uploads when the mission names no endpoint (missions/session/uploads.py). Nothing starts here."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


class GalleryService:
    """gallery_server: ``start_gallery`` (FastAPI and uvicorn load when the first photo needs it)."""

    name = "gallery"

    def open(self, session: Any) -> Mapping[str, Any]:
        return {"gallery_server": _start_gallery}

    def close(self) -> None:
        """Nothing to release: the uploads service stops the gallery it started."""


def _start_gallery(*args: Any, **kwargs: Any) -> Any:
    from botstage.missions.gallery.server import start_gallery

    return start_gallery(*args, **kwargs)
