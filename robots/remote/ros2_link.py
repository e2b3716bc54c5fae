"""Remote devices over ROS 2 services: ``/<robot>/device_call`` and ``/<robot>/describe_devices``.

The robot's process serves both over its backend's devices (``serve_devices``); a process that
uses them builds proxies from the description (``open_remote_devices``). Each device call is one
service call. A robot process that dies or is cut off ends the call in flight at once with
``RemoteLost`` (its servers leave the graph), which the skill holding the device reports.
"""

from __future__ import annotations

from typing import Any

from botstage.robots.remote.devices import (
    DeviceHost,
    RemoteDevice,
    RemoteLost,
    members_json,
    members_of,
    remote_devices,
)
from botstage.robots.remote.watched import WatchedClient
from botstage.robots.ros2 import types
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.service import ServiceError

CALL_TYPE = "botstage_msgs/srv/DeviceCall"
DESCRIBE_TYPE = "botstage_msgs/srv/DescribeDevices"
CALL_TIMEOUT_S = 60.0


def call_service(robot: str) -> str:
    return f"/{robot}/device_call"


def describe_service(robot: str) -> str:
    return f"/{robot}/describe_devices"


def serve_devices(node: Ros2Node, host: DeviceHost, robot: str | None = None) -> list[Any]:
    """Answer device calls and descriptions for ``host``'s devices; the two servers."""
    robot = robot or node.name
    call_response = types.message_class(f"{CALL_TYPE}_Response")
    describe_response = types.message_class(f"{DESCRIBE_TYPE}_Response")
    description = members_json(host.members)

    def call(request: Any) -> Any:
        result, kind, message = host.answer(request.interface, request.member, request.args_json)
        return call_response(result_json=result, error_type=kind, error=message)

    return [
        node.service(call_service(robot), CALL_TYPE, call),
        node.service(describe_service(robot), DESCRIBE_TYPE, lambda _request: describe_response(description)),
    ]


class DeviceCallLink:
    """One process's link to a robot process's devices."""

    def __init__(self, node: Ros2Node, robot: str, timeout: float = CALL_TIMEOUT_S) -> None:
        self.remote = robot
        self._call = WatchedClient(node.client(call_service(robot), CALL_TYPE), robot, timeout)
        self._describe = node.client(describe_service(robot), DESCRIBE_TYPE)
        self._request = types.message_class(f"{CALL_TYPE}_Request")

    def describe(self, timeout: float) -> dict[str, Any]:
        """The robot's devices and members, waiting up to ``timeout`` s for the robot to serve them."""
        if not self._describe.wait_for_service(timeout):
            raise RemoteLost(f"robot process {self.remote!r} does not serve its devices (waited {timeout:g} s)")
        request = types.message_class(f"{DESCRIBE_TYPE}_Request")()
        try:
            return members_of(self._describe.call(request, timeout).devices_json)
        except ServiceError as error:
            raise RemoteLost(f"robot process {self.remote!r}: {error}") from None

    def call(self, interface: str, member: str, args_json: str) -> tuple[str, str, str]:
        response = self._call.call(self._request(interface=interface, member=member, args_json=args_json))
        return response.result_json, response.error_type, response.error

    def close(self) -> None:
        self._call.close()
        self._describe.close()


def open_remote_devices(node: Ros2Node, robot: str, timeout: float) -> tuple[DeviceCallLink, dict[str, RemoteDevice]]:
    """Proxies of every device ``robot`` serves, and the link they share."""
    link = DeviceCallLink(node, robot)
    try:
        return link, remote_devices(link, link.describe(timeout))
    except Exception:
        link.close()
        raise
