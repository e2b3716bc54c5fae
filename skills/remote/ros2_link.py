"""Remote skills over ROS 2 services: ``/<process>/skill_tick`` of type ``botstage_msgs/srv/SkillTick``.

The host's process serves the service (``serve_skill_host``); the mission holds one
``SkillTickLink`` per process. A tick is one service call; the link also watches the service's
servers in the graph (their liveliness tokens), so a process that dies or is cut off ends the
call in flight at once with ``remote 'NAME' lost`` rather than after a timeout, and a process
that comes back (a new session) is called again by the next tick.
"""

from __future__ import annotations

import threading
from concurrent.futures import FIRST_COMPLETED, Future, wait
from typing import Any

from robots.remote import values
from robots.ros2 import types
from robots.ros2.node import Ros2Node
from robots.ros2.service import ServiceError, ServiceUnavailable
from skills.remote.host import SkillHost
from skills.remote.protocol import (
    State,
    TickReply,
    TickRequest,
    reply_fields,
    reply_of,
    request_fields,
    request_of,
)
from skills.remote.proxy import RemoteLost

SERVICE_TYPE = "botstage_msgs/srv/SkillTick"
TICK_TIMEOUT_S = 120.0  # a step that waits for a recogniser on a loaded machine; loss is seen sooner
# A process killed mid-call ends the query (no server answered) a few ms before its tokens leave
# the graph: wait that long for the liveliness to say whether it is gone.
LOSS_GRACE_S = 0.5


def service_name(process: str) -> str:
    """The service a process's skill host answers on (absolute: one per process in the domain)."""
    return f"/{process}/skill_tick"


def serve_skill_host(node: Ros2Node, host: SkillHost, process: str | None = None) -> Any:
    """Answer ``/<process>/skill_tick`` with ``host`` (the node's name by default); the server."""
    response_type = types.message_class(f"{SERVICE_TYPE}_Response")

    def handle(request: Any) -> Any:
        try:
            reply = host.handle(request_of(request))
        except values.ValueCodecError as error:
            reply = TickReply(State.ENDED, "failure", f"the host could not read the request: {error}")
        return response_type(**reply_fields(reply))

    return node.service(service_name(process or node.name), SERVICE_TYPE, handle)


class SkillTickLink:
    """The mission's link to one process's skill host."""

    def __init__(self, node: Ros2Node, process: str, timeout: float = TICK_TIMEOUT_S) -> None:
        self.remote = process
        self.timeout = timeout
        self._client = node.client(service_name(process), SERVICE_TYPE)
        self._request_type = types.message_class(f"{SERVICE_TYPE}_Request")
        self._lock = threading.Lock()
        self._lost: Future[str] = Future()
        self._client.servers.listen(self._on_change)

    def _on_change(self, zid: str, alive: bool) -> None:
        if not alive and not self._client.servers.zids():
            with self._lock:
                lost = self._lost
            if not lost.done():
                lost.set_result(zid)

    def wait_for_remote(self, timeout: float | None = None) -> bool:
        """Whether the process serves its skills, waiting up to ``timeout`` s."""
        return self._client.wait_for_service(timeout)

    def tick(self, request: TickRequest) -> TickReply:
        lost_message = f"remote {self.remote!r} lost"
        if not self._client.servers.zids():
            raise RemoteLost(lost_message)
        with self._lock:
            if self._lost.done():
                self._lost = Future()  # it came back since: watch afresh
            lost = self._lost
        call = self._client.call_async(self._request_type(**request_fields(request)))
        done, _ = wait([call, lost], timeout=self.timeout, return_when=FIRST_COMPLETED)
        if call not in done:
            call.cancel()
            raise RemoteLost(lost_message if lost in done else f"{lost_message}: no answer within {self.timeout:g} s")
        try:
            return reply_of(call.result())
        except ServiceUnavailable as error:
            if lost in wait([lost], timeout=LOSS_GRACE_S).done:
                raise RemoteLost(lost_message) from None
            raise RemoteLost(f"{lost_message}: {error}") from None
        except ServiceError as error:
            raise RemoteLost(f"{lost_message}: {error}") from None
        except values.ValueCodecError as error:
            raise RemoteLost(f"remote {self.remote!r} sent a reply that cannot be read: {error}") from None

    def close(self) -> None:
        self._client.close()
