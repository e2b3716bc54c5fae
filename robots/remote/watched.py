"""A service client that knows when its server's process is gone.

Remote devices and remote skills both call one service of another process and must tell a lost
process (its liveliness tokens left the graph) from a slow one: ``WatchedClient.call`` returns
the response or raises ``RemoteLost`` saying ``remote 'NAME' lost`` as soon as the loss is seen.
"""

from __future__ import annotations

import threading
from typing import Any

import zenoh

from botstage.robots.remote.devices import RemoteLost
from botstage.robots.ros2.service import (
    ServiceCancelled,
    ServiceClient,
    ServiceError,
    ServiceTimeout,
    ServiceUnavailable,
)

# A process killed mid-call ends the query (no server answered) a few ms before its tokens leave
# the graph: wait that long for the liveliness to say whether it is gone.
LOSS_GRACE_S = 0.5


class WatchedClient:
    """Calls one service of process ``remote``, watching its servers' liveliness."""

    def __init__(self, client: ServiceClient, remote: str, timeout: float) -> None:
        self.client, self.remote, self.timeout = client, remote, timeout
        self._lock = threading.Lock()
        self._lost = threading.Event()
        self._waiting: set[zenoh.CancellationToken] = set()
        client.servers.listen(self._on_change)

    def _on_change(self, zid: str, alive: bool) -> None:
        """Zenoh's thread: the last server left, so end the calls waiting on it."""
        if alive or self.client.servers.zids():
            return
        with self._lock:
            self._lost.set()
            waiting = list(self._waiting)
        if waiting:  # cancelling may wait for Zenoh's threads: not on one of them
            threading.Thread(target=lambda: [token.cancel() for token in waiting], daemon=True).start()

    def wait_for_service(self, timeout: float | None = None) -> bool:
        return self.client.wait_for_service(timeout)

    def call(self, request: Any) -> Any:
        """The response, or ``RemoteLost`` when the process is gone or silent past the timeout."""
        lost_message = f"remote {self.remote!r} lost"
        token = zenoh.CancellationToken()
        with self._lock:  # watched from now on: a loss after this cancels the token
            self._lost.clear()
            self._waiting.add(token)
        try:
            if not self.client.servers.serving():
                raise RemoteLost(lost_message)
            return self.client.call(request, self.timeout, cancel=token)
        except ServiceCancelled:
            raise RemoteLost(lost_message) from None
        except ServiceTimeout:
            raise RemoteLost(f"{lost_message}: no answer within {self.timeout:g} s") from None
        except ServiceUnavailable as error:
            if self._lost.wait(LOSS_GRACE_S):
                raise RemoteLost(lost_message) from None
            raise RemoteLost(f"{lost_message}: {error}") from None
        except ServiceError as error:
            raise RemoteLost(f"{lost_message}: {error}") from None
        finally:
            with self._lock:
                self._waiting.discard(token)

    def close(self) -> None:
        self.client.close()
