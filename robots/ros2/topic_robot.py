"""A robot on a ROS 2 graph through its topics, as the ``ros2`` backend opens it.

Opening joins the graph and waits up to ``ready_timeout`` seconds for a first message on every
topic the robot publishes, and fails naming each silent topic. From then on the devices are
proxies (robots/ros2/proxies.py): readings stamped on the run's clock, stale ones refused with the
topic and their age, commands published. ``step`` does nothing (the robot moves itself);
``close`` publishes zero velocity and leaves the graph.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from botstage.robots.backend import Fault, OpenRequest
from botstage.robots.clock import Clock
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import CameraInfo, Pose2D
from botstage.robots.profile import Device, Profile
from botstage.robots.ros2 import botstage_messages as own
from botstage.robots.ros2 import readings
from botstage.robots.ros2.names import fully_qualified_name
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.proxies import (
    AudioBuffer,
    BatteryProxy,
    CameraProxy,
    ClockRef,
    DisplayProxy,
    DriveProxy,
    ImuProxy,
    LaserProxy,
    Latest,
    MicrophoneProxy,
    OdometryProxy,
    PanProxy,
    PeopleProxy,
    SonarProxy,
    SpeakerProxy,
)
from botstage.robots.ros2.topics import Direction, Route, routes

if TYPE_CHECKING:
    from botstage.robots.ros2.backend import Ros2Options

log = logging.getLogger(__name__)

STALE_PERIODS = 3  # a reading is stale after this many periods of its channel's rate, at the least


class Ros2Backend:
    """A robot on a ROS 2 graph, through one node: sensor proxies fed by subscriptions, command proxies publishing."""

    def __init__(self, request: OpenRequest, options: Ros2Options, node: Ros2Node) -> None:
        self.profile: Profile = request.profile
        self.grid: GridMap | None = request.grid
        self.options = options
        self.node = node
        self.clock = ClockRef(request.clock)
        self.devices: dict[str, Any] = {}
        self.latest: dict[str, Latest] = {}
        self.audio = AudioBuffer()
        self._routes = {route.key: route for route in routes(self.profile)}
        for route in self._routes.values():
            if route.channel.direction is Direction.READING:
                self.latest[route.key] = self._subscribe(route)
        for interface in self.profile.interfaces:
            device = self._device(interface, request.start)
            if device is not None:
                self.devices[interface] = device
        self.not_on_graph = [name for name in self.profile.interfaces if name not in self.devices]

    @classmethod
    def open(cls, request: OpenRequest, options: Ros2Options) -> Ros2Backend:
        """Join the graph and wait for the robot's topics; a ``ConnectionError`` names the silent ones."""
        node = Ros2Node(
            options.node_name,
            options.namespace,
            domain_id=options.domain_id,
            listen=options.listen,
            connect=options.connect,
        )
        try:
            backend = cls(request, options, node)
            backend.wait_ready(options.ready_timeout)
        except BaseException:
            node.close()
            raise
        return backend

    # -- wiring --------------------------------------------------------------------------------------

    def _topic(self, key: str) -> str:
        return self._routes[key].topic

    def _subscribe(self, route: Route) -> Latest:
        convert = {
            "odometry": readings.odometry_of,
            "imu": readings.imu_of,
            "laser": readings.scan_of,
            "sonar": readings.sonar_of,
            "battery": readings.battery_of,
            "camera": _read_only_frame,
            "people": own.people_of,
            "microphone": lambda message: self.audio.heard(own.audio_of(message)),
            "speaking": lambda message: bool(message.data),
            "pan_state": lambda message: readings.joint_position_of(message, self._joint_name()),
        }[route.key]
        period = route.period or 0.0
        bound = max(self.options.stale_after, STALE_PERIODS * period)
        channel = route.channel
        what = channel.interface if channel.key == channel.interface else f"{channel.interface} ({channel.key})"
        topic = fully_qualified_name(route.topic, self.node.namespace, self.node.name)
        latest = Latest(what, topic, convert, self.clock, bound)
        self.node.subscription(route.topic, channel.type_name, latest.on_message, channel.qos)
        return latest

    def _publisher(self, key: str) -> Any:
        route = self._routes[key]
        return self.node.publisher(route.topic, route.channel.type_name, route.channel.qos)

    def _device(self, interface: str, start: Pose2D) -> Any | None:
        """The proxy for ``interface``, or None for an interface ROS 2 has no topic for here."""
        latest, spec, base = self.latest, self.profile.interfaces[interface], self.profile.base
        if interface == "drive":
            return DriveProxy(self._publisher("drive"), base.max_linear, base.max_angular)
        if interface == "odometry":
            return OdometryProxy(latest["odometry"], start)
        if interface in ("imu", "sonar", "battery"):
            return {"imu": ImuProxy, "sonar": SonarProxy, "battery": BatteryProxy}[interface](latest[interface])
        if interface == "laser":
            return LaserProxy(latest["laser"])
        if interface == "people":
            return PeopleProxy(latest["people"], spec.range_min or 0.8, spec.range_max or 4.0)
        if interface == "camera":
            info = CameraInfo(spec.width or 640, spec.height or 480, spec.field_of_view or 1.0)
            return CameraProxy(latest["camera"], info)
        if interface == "microphone":
            return MicrophoneProxy(latest["microphone"], self.audio)
        if interface == "speaker":
            return SpeakerProxy(
                self._publisher("speaker"), latest["speaking"], self.clock, latest["speaking"].stale_after
            )
        if interface == "display":
            return DisplayProxy(self._publisher("display"), self.clock)
        if interface == "pan":
            low, high = joint_limits(spec)
            return PanProxy(self._publisher("pan"), latest["pan_state"], low, high)
        return None

    def _joint_name(self) -> str:
        joint = self.profile.interfaces["pan"].joint
        return joint.name if joint is not None else "pan_joint"

    def wait_ready(self, timeout: float) -> None:
        """Until every subscribed topic has had a message, or ``ConnectionError`` naming those that had none."""
        deadline = time.monotonic() + timeout  # the transport's own deadline: the run's clock starts later
        for latest in self.latest.values():
            latest.ready.wait(max(0.0, deadline - time.monotonic()))
        silent = [latest for latest in self.latest.values() if not latest.ready.is_set()]
        if silent:
            names = ", ".join(f"{latest.topic} ({latest.what})" for latest in silent)
            where = ", ".join(self.options.connect) or "nothing (no connect endpoints)"
            raise ConnectionError(
                f"ros2 backend: no message within {timeout:g} s on {names}; connected to {where}, "
                f"domain {self.options.domain_id}: is the robot up and publishing (botstage serve robot, "
                "or the robot's ROS 2 driver), and its profile's ros2: topics its names?"
            )

    # -- the Backend protocol --------------------------------------------------------------------

    @property
    def faults(self) -> Mapping[str, Fault]:
        """None: a real robot's faults are its own."""
        return MappingProxyType({})

    def step(self) -> None:
        """Nothing: the robot moves itself; readings arrive on their own."""

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with the run's clock from now on; those held keep their instant of arrival."""
        old = self.clock.clock
        for latest in self.latest.values():
            latest.rebase(old, clock)
        self.clock.clock = clock

    def true_pose(self) -> Pose2D | None:
        return None

    def close(self) -> None:
        """Zero velocity, then leave the graph (the node's tokens and the session)."""
        try:
            drive = self.devices.get("drive")
            if drive is not None and not self.node.closed:
                drive.stop()
        finally:
            self.node.close()

    def summary(self) -> dict[str, Any]:
        """The node, and per topic what arrived, what was dropped, and how often a read found it stale."""
        topics = {
            latest.topic: {"received": latest.received, "rejected": latest.rejected, "stale_reads": latest.stale_reads}
            for latest in self.latest.values()
        }
        drive = self.devices.get("drive")
        return {
            "node": self.node.fqn,
            "domain_id": self.options.domain_id,
            "topics": topics,
            "velocity_commands": drive.sent if drive is not None else 0,
            "not_on_graph": self.not_on_graph,
        }

    def write_results(self, folder: Path) -> None:
        """Nothing to leave: what the robot did is in its own logs."""


def joint_limits(spec: Device) -> tuple[float, float]:
    """A pan's limits in rad from its profile joint (the AX-12A's units: 300 deg over 1024)."""
    from botstage.robots.ax12 import raw_to_angle

    joint = spec.joint
    if joint is None:
        raise ValueError("a pan needs its joint in the profile")
    flipped = joint.min > joint.max
    ends = sorted(raw_to_angle(limit, joint.init, flipped) for limit in (joint.min, joint.max))
    return ends[0], ends[1]


def _read_only_frame(message: Any) -> Any:
    frame = readings.frame_of(message)
    frame.setflags(write=False)
    return frame
