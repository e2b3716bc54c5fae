"""Serving a FastAPI app with uvicorn on a thread of this process (the gallery, the live monitor).

The listening socket is bound before uvicorn starts (port 0: the kernel picks a free one, with no
window for another process to take it), so the URL is known at once; ``stop()`` shuts the server
down and frees the port.
"""

from __future__ import annotations

import ipaddress
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import uvicorn


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


def url_of(host: str, port: int) -> str:
    return f"http://[{host}]:{port}" if ":" in host else f"http://{host}:{port}"


@dataclass
class ServerThread:
    """A uvicorn server running on a daemon thread over a socket bound beforehand."""

    host: str
    port: int
    server: uvicorn.Server = field(repr=False)
    thread: threading.Thread = field(repr=False)
    sock: socket.socket = field(repr=False)

    @property
    def url(self) -> str:
        return url_of(self.host, self.port)

    def stop(self, timeout: float = 10.0) -> None:
        """Shut down and free the port (bounded: a stuck connection does not hang the caller)."""
        self.server.should_exit = True
        self.thread.join(timeout)
        if self.thread.is_alive():
            self.server.force_exit = True
            self.thread.join(timeout)
        self.sock.close()


def start_server(config: uvicorn.Config, sock: socket.socket, name: str, timeout: float = 10.0) -> ServerThread:
    """Run ``config`` on a thread over ``sock`` and return once it accepts connections."""
    host, port = sock.getsockname()[:2]
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, name=f"{name}-{port}", daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout
    while not server.started:  # a bounded wait for the server to come up, never a timing assumption
        if not thread.is_alive() or time.monotonic() > deadline:
            server.should_exit = True
            thread.join(timeout)
            sock.close()
            raise RuntimeError(f"the {name} did not start on {host}:{port} within {timeout:g} s")
        time.sleep(0.005)
    return ServerThread(host, port, server, thread, sock)


def app_config(app: Any, host: str, port: int, *, access_log: bool = False) -> uvicorn.Config:
    return uvicorn.Config(
        app,
        host=host,
        port=port,
        log_level="info" if access_log else "warning",
        access_log=access_log,
        lifespan="off",
        timeout_graceful_shutdown=2,
        server_header=False,
    )
