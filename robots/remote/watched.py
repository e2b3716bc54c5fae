"""A service client that knows when its server's process is gone.

Remote devices and remote skills both call one service of another process and must tell a lost
process (its liveliness tokens left the graph) from a slow one: ``WatchedClient.call`` returns
the response or raises ``RemoteLost`` saying ``remote 'NAME' lost`` as soon as the loss is seen.
"""

from __future__ import annotations

import threading
from concurrent.futures import FIRST_COMPLETED, Future, wait
from typing import Any

from robots.remote.devices import RemoteLost
from robots.ros2.service import ServiceClient, ServiceError, ServiceUnavailable

# A process killed mid-call ends the query (no server answered) a few ms before its tokens leave
# the graph: wait that long for the liveliness to say whether it is gone.
LOSS_GRACE_S = 0.5


class WatchedClient:
    """Calls one service of process ``remote``, watching its servers' liveliness."""

    def __init__(self, client: ServiceClient, remote: str, timeout: float) -> None:
        self.client, self.remote, self.timeout = client, remote, timeout
        self._lock = threading.Lock()
        self._lost: Future[str] = Future()
        client.servers.listen(self._on_change)

    def _on_change(self, zid: str, alive: bool) -> None:
        if not alive and not self.client.servers.zids():
            with self._lock:
                lost = self._lost
            if not lost.done():
                lost.set_result(zid)

    def wait_for_service(self, timeout: float | None = None) -> bool:
        return self.client.wait_for_service(timeout)

    def call(self, request: Any) -> Any:
        """The response, or ``RemoteLost`` when the process is gone or silent past the timeout."""
        lost_message = f"remote {self.remote!r} lost"
        if not self.client.servers.zids():
            raise RemoteLost(lost_message)
        with self._lock:
            if self._lost.done():
                self._lost = Future()  # it came back since: watch afresh
            lost = self._lost
        pending = self.client.call_async(request)
        done, _ = wait([pending, lost], timeout=self.timeout, return_when=FIRST_COMPLETED)
        if pending not in done:
            pending.cancel()
            raise RemoteLost(lost_message if lost in done else f"{lost_message}: no answer within {self.timeout:g} s")
        try:
            return pending.result()
        except ServiceUnavailable as error:
            if lost in wait([lost], timeout=LOSS_GRACE_S).done:
                raise RemoteLost(lost_message) from None
            raise RemoteLost(f"{lost_message}: {error}") from None
        except ServiceError as error:
            raise RemoteLost(f"{lost_message}: {error}") from None

    def close(self) -> None:
        self.client.close()
