"""What skills may ask of a robot: small typed protocols, one per device.

The simulator, the serial drivers and remote peers all provide these, so a skill written
against them runs unchanged on each. Readings are immutable values stamped with the mission
clock's time; they check their own shape, so a faulty backend fails where the fault is.

Frames: the robot's base frame has x forward, y left, angles counter-clockwise in radians.
The people tracker reports in its sensor frame like the Kinect skeleton tracker of the
PeopleBot paper: x to the right (horizontal), z forward (depth), in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

AUDIO_RATE_HZ = 16_000
AUDIO_BUFFER_S = 30.0  # audio a microphone keeps between two reads; older samples are dropped


def _finite(name: str, *values: float) -> None:
    for value in values:
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value!r}")


@dataclass(frozen=True, slots=True)
class Pose2D:
    x: float
    y: float
    theta: float

    def __post_init__(self) -> None:
        _finite("a pose", self.x, self.y, self.theta)


@dataclass(frozen=True, slots=True)
class Twist2D:
    v: float  # m/s forward
    w: float  # rad/s counter-clockwise

    def __post_init__(self) -> None:
        _finite("a twist", self.v, self.w)


@dataclass(frozen=True, slots=True)
class OdometryReading:
    stamp: float
    pose: Pose2D
    twist: Twist2D
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # x, y, theta

    def __post_init__(self) -> None:
        if np.shape(self.covariance) != (3, 3):
            raise ValueError(f"odometry covariance must be 3x3, got shape {np.shape(self.covariance)}")


@dataclass(frozen=True, slots=True)
class ImuReading:
    stamp: float
    yaw: float  # rad, integrated orientation
    angular_velocity: float  # rad/s about z
    linear_acceleration: tuple[float, float]  # m/s², x and y in the base frame


@dataclass(frozen=True, slots=True)
class LaserScan:
    stamp: float
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray  # metres; inf where nothing was hit within range_max

    def __post_init__(self) -> None:
        if np.ndim(self.ranges) != 1 or len(self.ranges) == 0:
            raise ValueError("a laser scan has a non-empty 1-D array of ranges")
        if not 0 <= self.range_min < self.range_max:
            raise ValueError(f"need 0 <= range_min < range_max, got {self.range_min}, {self.range_max}")

    @property
    def angles(self) -> np.ndarray:
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def points(self) -> np.ndarray:
        """The hits as (x, y) points in the sensor frame; misses are left out."""
        hit = np.isfinite(self.ranges) & (self.ranges >= self.range_min)
        angles, ranges = self.angles[hit], self.ranges[hit]
        return np.column_stack((ranges * np.cos(angles), ranges * np.sin(angles)))


@dataclass(frozen=True, slots=True)
class SonarReading:
    stamp: float
    range: float  # metres; inf when nothing is within max_range
    field_of_view: float  # rad, full cone
    max_range: float


@dataclass(frozen=True, slots=True)
class BatteryState:
    stamp: float
    voltage: float
    percent: float  # 0..100
    current: float = 0.0  # A drawn, positive when discharging

    def __post_init__(self) -> None:
        if not 0 <= self.percent <= 100:
            raise ValueError(f"battery percent must be within 0..100, got {self.percent}")


@dataclass(frozen=True, slots=True)
class TrackedPerson:
    id: int
    x: float  # m, to the right of the sensor
    z: float  # m, in front of the sensor

    def __post_init__(self) -> None:
        _finite("a tracked person", self.x, self.z)


@dataclass(frozen=True, slots=True)
class CameraInfo:
    width: int
    height: int
    horizontal_fov: float  # rad

    @property
    def focal_px(self) -> float:
        """The pinhole focal length in pixels (for distances from box heights)."""
        return (self.width / 2) / math.tan(self.horizontal_fov / 2)


@runtime_checkable
class Drive(Protocol):
    def cmd_vel(self, v: float, w: float) -> None:
        """Command a forward speed (m/s) and turn rate (rad/s); limits are enforced by the backend."""

    def stop(self) -> None: ...


@runtime_checkable
class Odometry(Protocol):
    def read(self) -> OdometryReading: ...


@runtime_checkable
class Imu(Protocol):
    def read(self) -> ImuReading: ...


@runtime_checkable
class Laser(Protocol):
    def scan(self) -> LaserScan: ...


@runtime_checkable
class Sonar(Protocol):
    def read(self) -> SonarReading: ...


@runtime_checkable
class Battery(Protocol):
    def read(self) -> BatteryState: ...


@runtime_checkable
class PeopleTracker(Protocol):
    range_min: float
    range_max: float

    def people(self) -> list[TrackedPerson]: ...


@runtime_checkable
class Camera(Protocol):
    info: CameraInfo

    def frame(self) -> np.ndarray | None:
        """The latest BGR image (height x width x 3, uint8), or None before the first one."""


@runtime_checkable
class Microphone(Protocol):
    def read(self) -> np.ndarray:
        """Audio since the last read (at most the latest ``AUDIO_BUFFER_S``): 16 kHz mono int16, maybe empty."""


@runtime_checkable
class Speaker(Protocol):
    def say(self, text: str) -> None: ...

    def busy(self) -> bool:
        """True while speech or sound is still playing."""


@runtime_checkable
class AudioSpeaker(Speaker, Protocol):
    """A speaker that also plays sound made on the robot's side, such as synthesised speech.

    A plain ``Speaker`` only takes text (its own voice, or a display of it); the ``speak`` skill
    hands one of these the audio instead, when it could make some.
    """

    def play(self, samples: np.ndarray, rate_hz: int, text: str = "") -> None:
        """Play mono int16 ``samples`` at ``rate_hz``; ``text`` is what they say (for records)."""

    def stop(self) -> None:
        """Stop what is playing now (speech that was cancelled)."""


@runtime_checkable
class Display(Protocol):
    def show(self, layout: str, **content: str) -> None:
        """Show a named screen layout (e.g. the PeopleBot tablet's Layout_1) with its content."""


@runtime_checkable
class Pan(Protocol):
    """A camera's pan joint (the face tracker's AX-12A): angles in rad, positive turns the camera left
    (counter-clockwise seen from above), within ``min_angle``..``max_angle``."""

    @property
    def min_angle(self) -> float: ...

    @property
    def max_angle(self) -> float: ...

    def move_to(self, angle: float) -> bool:
        """Send the joint towards ``angle`` (clamped to its limits) at its own speed; False if not sent."""

    def position(self) -> float | None:
        """The joint's present angle, or None when it cannot be read (unplugged)."""


INTERFACES: dict[str, type] = {
    "drive": Drive,
    "odometry": Odometry,
    "imu": Imu,
    "laser": Laser,
    "sonar": Sonar,
    "battery": Battery,
    "people": PeopleTracker,
    "camera": Camera,
    "microphone": Microphone,
    "speaker": Speaker,
    "display": Display,
    "pan": Pan,
}


def check_interfaces(provided: dict[str, object]) -> list[str]:
    """Problems with a backend's interfaces: unknown names, objects that don't fit the protocol."""
    problems = []
    for name, device in provided.items():
        protocol = INTERFACES.get(name)
        if protocol is None:
            problems.append(f"unknown interface {name!r} (known: {', '.join(INTERFACES)})")
        elif not isinstance(device, protocol):
            problems.append(f"interface {name!r}: {type(device).__name__} does not provide {protocol.__name__}")
    return problems
