"""Zenoh endpoints as a user gives them (``--listen``, ``--connect``, backend options), checked
before a session opens, so a typo is a clear error rather than Zenoh's."""

from __future__ import annotations

import re
from collections.abc import Iterable

# robots/ros2/node.py's, named here too so that checking options loads no Zenoh
DEFAULT_LISTEN = "tcp/127.0.0.1:0"  # loopback, a port the system picks
ROUTER_LISTEN = "tcp/127.0.0.1:7447"  # where rmw_zenoh's nodes look for rmw_zenohd by default

_ENDPOINT = re.compile(r"(tcp|udp|tls|quic)/(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(\d{1,5})\Z")


def check_endpoint(endpoint: str) -> str:
    """``endpoint`` if it reads ``proto/host:port`` (tcp, udp, tls or quic; port 0-65535), else a ValueError."""
    match = _ENDPOINT.match(endpoint.strip()) if isinstance(endpoint, str) else None
    if match is None or int(match.group(3)) > 65535:
        raise ValueError(f"{endpoint!r} is not a Zenoh endpoint (like {ROUTER_LISTEN})")
    return endpoint.strip()


def endpoints(value: str | Iterable[str]) -> list[str]:
    """Endpoints from a list or from one comma-separated string (as ``--backend-opt`` gives them), checked."""
    items = value.split(",") if isinstance(value, str) else list(value)
    return [check_endpoint(item) for item in items if str(item).strip()]
