"""Serve the gallery with uvicorn: in the foreground (`botstage gallery`) or on a thread in-process.

In-process, the listening socket is bound before uvicorn starts (port 0: the kernel picks a free
one, with no window for another process to take it), so the URL is known at once; ``stop()``
shuts the server down and frees the port, and a gallery started again on the same port (with
``SO_REUSEADDR``) serves the same folder: what tests use to take a gallery down and bring it back.
"""

from __future__ import annotations

import logging
import sqlite3
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import uvicorn

from botstage.missions.gallery.app import DEFAULT_MAX_BYTES, create_app
from botstage.missions.gallery.images import DEFAULT_MAX_PIXELS
from botstage.missions.serving import ServerThread, app_config, bind, start_server

_log = logging.getLogger("botstage.gallery")
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


class GalleryError(Exception):
    """The gallery cannot open its folder (not a folder, not writable, a damaged index)."""


def _config(
    folder: Path, host: str, port: int, token: str | None, limits: tuple[int, int], access_log: bool
) -> uvicorn.Config:
    max_bytes, max_pixels = limits
    app = create_app(folder, token=token, max_bytes=max_bytes, max_pixels=max_pixels)
    return app_config(app, host, port, access_log=access_log)


def serve(
    folder: str | Path,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    *,
    token: str | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    bound: Callable[[int], None] = lambda port: None,
) -> None:
    """Serve until interrupted (Ctrl-C or SIGTERM); a port in use is an ``OSError`` here, not an exit,
    and a folder the gallery cannot keep its photos in a ``GalleryError``.

    ``bound`` hears the port listened on once it is (port 0: the one the kernel picked)."""
    sock = bind(host, port)
    try:
        port = sock.getsockname()[1]
        try:
            config = _config(Path(folder), host, port, token, (max_bytes, max_pixels), access_log=True)
        except (OSError, sqlite3.Error) as exc:
            raise GalleryError(f"cannot open the gallery in {folder}: {exc}") from exc
        bound(port)
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        sock.close()


@dataclass
class RunningGallery:
    """A gallery serving on a thread of this process."""

    folder: Path
    host: str
    port: int
    running: ServerThread = field(repr=False)

    @property
    def url(self) -> str:
        return self.running.url

    @property
    def upload_url(self) -> str:
        return f"{self.url}/photos"

    @property
    def server(self) -> uvicorn.Server:
        return self.running.server

    def stop(self, timeout: float = 10.0) -> None:
        """Shut down and free the port (bounded: a stuck connection does not hang the caller)."""
        self.running.stop(timeout)
        self.running.server.config.app.state.store.close()

    def __enter__(self) -> RunningGallery:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_gallery(
    folder: str | Path,
    *,
    host: str = DEFAULT_HOST,
    port: int = 0,
    token: str | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    timeout: float = 10.0,
) -> RunningGallery:
    """Start a gallery on a thread and return once it accepts connections (port 0: a free one)."""
    folder = Path(folder)
    sock = bind(host, port)
    port = sock.getsockname()[1]
    config = _config(folder, host, port, token, (max_bytes, max_pixels), access_log=False)
    running = start_server(config, sock, "gallery", timeout)
    _log.info("gallery serving %s at %s", folder, running.url)
    return RunningGallery(folder, host, port, running)
