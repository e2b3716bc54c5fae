"""Which ROS 2 topic carries each robot interface: its name, message type, direction and rate.

One table for both sides of the wire. A robot process (``botstage serve robot``) publishes what
its devices read and subscribes to the commands; the ``ros2`` backend subscribes to the readings
of a robot already on a ROS 2 graph and publishes the commands. Names are ROS's defaults
(``cmd_vel``, ``odom``, ``scan``, ...) and relative, so a node's namespace puts a robot's topics
under it (``/robot1/cmd_vel``); a profile's ``ros2:`` section renames them and sets the rates at
which a robot process publishes (``ros2: {topics: {laser: base_scan}, rates_hz: {camera: 15}}``).

A channel is one topic of an interface; the speaker has two: ``speaker`` (text to say, in) and
``speaking`` (whether it is talking, out). The display takes ``std_msgs/String`` holding JSON,
``{"layout": "Layout_1", "content": {"title": "..."}}``: a layout and its text fields have no
standard message.

The pan (the face tracker's servo) has two channels: ``pan`` (in) takes the joint's goal angle
as ``std_msgs/Float64`` on ``pan_controller/command``, the topic and type of the book's chapter 2
(dynamixel_controllers' JointPositionController; a ROS 2 port of its controller publishes there
unchanged), and ``pan_state`` (out) says where the joint is as ``sensor_msgs/JointState`` on
``joint_states``, one joint named as the profile's ``joint.name`` (``pan_joint``), position only,
as ros2_control's joint_state_broadcaster publishes it (decision: the chapter's own state message,
dynamixel_msgs/JointState, is not a standard type; the joint limits are the profile's, so a
mission reads them from there). The state at 20 Hz, the chapter's manager's update_rate.

Sensor streams use ROS's sensor-data QoS (best effort, depth 5), as ROS drivers publish them;
commands, odometry, battery, audio and the speaking state are reliable (audio must not have
holes, a command must arrive). ``/clock`` is absolute and best effort with depth 1 (rclcpp's
ClockQoS).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

from botstage.robots.ros2.names import validate_topic_name
from botstage.robots.ros2.qos import QoS, Reliability

if TYPE_CHECKING:
    from botstage.robots.profile import Profile


class Direction(Enum):
    READING = "reading"  # the robot publishes it
    COMMAND = "command"  # the robot subscribes to it


RELIABLE = QoS()  # ROS 2's default profile: reliable, volatile, keep last 10
SENSOR_DATA = QoS(reliability=Reliability.BEST_EFFORT, depth=5)  # rmw_qos_profile_sensor_data
CLOCK_QOS = QoS(reliability=Reliability.BEST_EFFORT, depth=1)  # rclcpp::ClockQoS

CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"


@dataclass(frozen=True, slots=True)
class Channel:
    """One topic of one interface, with ROS's default name and botstage's default rate."""

    key: str  # its name in a profile's ros2: section
    interface: str
    topic: str
    type_name: str
    direction: Direction
    rate_hz: float | None = None  # readings only: how often a robot process publishes it
    qos: QoS = RELIABLE


CHANNELS: dict[str, Channel] = {
    channel.key: channel
    for channel in (
        Channel("drive", "drive", "cmd_vel", "geometry_msgs/msg/Twist", Direction.COMMAND),
        Channel("odometry", "odometry", "odom", "nav_msgs/msg/Odometry", Direction.READING, 20.0),
        Channel("imu", "imu", "imu", "sensor_msgs/msg/Imu", Direction.READING, 50.0, SENSOR_DATA),
        Channel("laser", "laser", "scan", "sensor_msgs/msg/LaserScan", Direction.READING, 10.0, SENSOR_DATA),
        Channel("sonar", "sonar", "range", "sensor_msgs/msg/Range", Direction.READING, 10.0, SENSOR_DATA),
        Channel("battery", "battery", "battery_state", "sensor_msgs/msg/BatteryState", Direction.READING, 1.0),
        # a 640x480 frame costs the simulator ~30 ms to draw: 5 Hz by default, more when asked
        Channel("camera", "camera", "image_raw", "sensor_msgs/msg/Image", Direction.READING, 5.0, SENSOR_DATA),
        Channel("people", "people", "people", "botstage_msgs/msg/PeopleTracks", Direction.READING, 10.0, SENSOR_DATA),
        Channel("microphone", "microphone", "audio", "botstage_msgs/msg/AudioChunk", Direction.READING, 10.0),
        Channel("speaker", "speaker", "say", "std_msgs/msg/String", Direction.COMMAND),
        Channel("speaking", "speaker", "speaking", "std_msgs/msg/Bool", Direction.READING, 5.0),
        Channel("display", "display", "display", "std_msgs/msg/String", Direction.COMMAND),
        Channel("pan", "pan", "pan_controller/command", "std_msgs/msg/Float64", Direction.COMMAND),
        Channel("pan_state", "pan", "joint_states", "sensor_msgs/msg/JointState", Direction.READING, 20.0),
    )
}


@dataclass(frozen=True, slots=True)
class Route:
    """A channel as one robot uses it: the topic name and rate its profile gives (or ROS's defaults)."""

    channel: Channel
    topic: str
    rate_hz: float | None

    @property
    def key(self) -> str:
        return self.channel.key

    @property
    def period(self) -> float | None:
        return 1.0 / self.rate_hz if self.rate_hz else None


def channels_of(interface: str) -> list[Channel]:
    """The channels of one interface (none for an interface ROS has no topic for)."""
    return [channel for channel in CHANNELS.values() if channel.interface == interface]


def routes(profile: Profile) -> list[Route]:
    """Every channel of every interface the profile lists, named and paced as its ``ros2:`` says."""
    section = profile.ros2
    found = []
    for interface in profile.interfaces:
        for channel in channels_of(interface):
            rate = (
                section.rates_hz.get(channel.key, channel.rate_hz) if channel.direction is Direction.READING else None
            )
            found.append(Route(channel, section.topics.get(channel.key, channel.topic), rate))
    return found


def check_section(
    topics: dict[str, str], rates_hz: dict[str, float], interfaces: list[str]
) -> list[tuple[tuple[str, str], str, str]]:
    """Problems with a profile's ``ros2:`` section: (where, message, hint) for each one."""
    problems = []
    for part, entries in (("topics", topics), ("rates_hz", rates_hz)):
        for key in entries:
            channel = CHANNELS.get(key)
            if channel is None:
                close = difflib.get_close_matches(key, list(CHANNELS), n=1)
                hint = f"did you mean {close[0]!r}?" if close else f"channels: {', '.join(CHANNELS)}"
                problems.append(((part, key), f"unknown channel {key!r}", hint))
            elif channel.interface not in interfaces:
                problems.append(
                    ((part, key), f"the robot has no {channel.interface!r} interface", "list it under interfaces:")
                )
            elif part == "rates_hz" and channel.direction is Direction.COMMAND:
                problems.append(((part, key), f"{key!r} is a command: its rate is its sender's", ""))
    for key, name in topics.items():
        try:
            validate_topic_name(name)
        except ValueError as error:
            problems.append((("topics", key), str(error), ""))
    return problems
