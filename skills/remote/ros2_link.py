"""Remote skills over ROS 2 services: ``/<process>/skill_tick`` of type ``botstage_msgs/srv/SkillTick``.

The host's process serves the service (``serve_skill_host``); the mission holds one
``SkillTickLink`` per process. A tick is one service call; the link also watches the service's
servers in the graph (their liveliness tokens), so a process that dies or is cut off ends the
call in flight at once with ``remote 'NAME' lost`` rather than after a timeout, and a process
that comes back (a new session) is called again by the next tick.
"""

from __future__ import annotations

from typing import Any

from botstage.robots.remote import values
from botstage.robots.remote.watched import WatchedClient
from botstage.robots.ros2 import types
from botstage.robots.ros2.node import Ros2Node
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import (
    State,
    TickReply,
    TickRequest,
    reply_fields,
    reply_of,
    request_fields,
    request_of,
)
from botstage.skills.remote.proxy import RemoteLost

SERVICE_TYPE = "botstage_msgs/srv/SkillTick"
TICK_TIMEOUT_S = 120.0  # a step that waits for a recogniser on a loaded machine; loss is seen sooner


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
        self._client = WatchedClient(node.client(service_name(process), SERVICE_TYPE), process, timeout)
        self._request_type = types.message_class(f"{SERVICE_TYPE}_Request")
        self.work_given = 0  # replies that said the process has after-tick work (lockstep steps it then)

    def wait_for_remote(self, timeout: float | None = None) -> bool:
        """Whether the process serves its skills, waiting up to ``timeout`` s."""
        return self._client.wait_for_service(timeout)

    def tick(self, request: TickRequest) -> TickReply:
        response = self._client.call(self._request_type(**request_fields(request)))
        try:
            reply = reply_of(response)
        except values.ValueCodecError as error:
            raise RemoteLost(f"remote {self.remote!r} sent a reply that cannot be read: {error}") from None
        if reply.pending_after_tick:
            self.work_given += 1
        return reply

    def close(self) -> None:
        self._client.close()
