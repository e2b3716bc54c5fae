"""Serve the gallery with uvicorn: in the foreground (`botstage gallery`) or on a thread in-process.

In-process, the listening socket is bound before uvicorn starts (port 0: the kernel picks a free
one, with no window for another process to take it), so the URL is known at once; ``stop()``
shuts the server down and frees the port, and a gallery started again on the same port (with
``SO_REUSEADDR``) serves the same folder: what tests use to take a gallery down and bring it back.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import uvicorn

from missions.gallery.app import DEFAULT_MAX_BYTES, create_app
from missions.gallery.images import DEFAULT_MAX_PIXELS

_log = logging.getLogger("botstage.gallery")
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


class GalleryError(Exception):
    """The gallery cannot open its folder (not a folder, not writable, a damaged index)."""


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    sock.setblocking(False)
    return sock


def _config(
    folder: Path, host: str, port: int, token: str | None, limits: tuple[int, int], access_log: bool
) -> uvicorn.Config:
    max_bytes, max_pixels = limits
    return uvicorn.Config(
        create_app(folder, token=token, max_bytes=max_bytes, max_pixels=max_pixels),
        host=host,
        port=port,
        log_level="info" if access_log else "warning",
        access_log=access_log,
        lifespan="off",
        timeout_graceful_shutdown=2,
        server_header=False,
    )


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
    server: uvicorn.Server = field(repr=False)
    thread: threading.Thread = field(repr=False)
    sock: socket.socket = field(repr=False)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    @property
    def upload_url(self) -> str:
        return f"{self.url}/photos"

    def stop(self, timeout: float = 10.0) -> None:
        """Shut down and free the port (bounded: a stuck connection does not hang the caller)."""
        self.server.should_exit = True
        self.thread.join(timeout)
        if self.thread.is_alive():
            self.server.force_exit = True
            self.thread.join(timeout)
        self.sock.close()
        self.server.config.app.state.store.close()

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
    server = uvicorn.Server(_config(folder, host, port, token, (max_bytes, max_pixels), access_log=False))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, name=f"gallery-{port}", daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout
    while not server.started:  # a bounded wait for the server to come up, never a timing assumption
        if not thread.is_alive() or time.monotonic() > deadline:
            server.should_exit = True
            thread.join(timeout)
            sock.close()
            raise RuntimeError(f"the gallery did not start on {host}:{port} within {timeout:g} s")
        time.sleep(0.005)
    _log.info("gallery serving %s at http://%s:%d", folder, host, port)
    return RunningGallery(folder, host, port, server, thread, sock)
