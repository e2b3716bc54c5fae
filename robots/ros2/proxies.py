"""Devices of a robot on a ROS 2 graph, as the ``ros2`` backend hands them to skills.

Each sensor proxy keeps the newest message of its topic, converted into the reading skills know
(robots/ros2/readings.py, botstage_messages.py) and stamped when it arrived, on the run's clock:
the robot's own stamps are on its clock (simulated, or the system's), which a mission cannot
compare with its own. Command proxies publish: the drive a Twist (``stop`` a zero one), the
speaker the text to say, the display its layout as JSON, a pan its goal angle (and reads where the
joint is from ``joint_states``).

A reading older than its bound is stale, and reading it raises ``StaleReadingError`` with the
topic and the age: a skill fails with that reason instead of acting on an old scan, and a
service that reads it ends the run with it. The bound is the backend's ``stale_after``, or three
periods of the channel's rate if that is longer (a battery at 1 Hz is not stale after 1 s).

Odometry is anchored: its first reading is where the mission put the robot, as a serial driver's
odometry starts at the mission's start (a ROS robot's ``odom`` frame starts wherever it was
switched on). Later poses are the robot's motion from there; the twist is in the robot's frame
and unchanged.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from botstage.robots.clock import Clock
from botstage.robots.interfaces import (
    AUDIO_BUFFER_S,
    AUDIO_RATE_HZ,
    CameraInfo,
    OdometryReading,
    Pose2D,
    TrackedPerson,
    Twist2D,
)
from botstage.robots.ros2 import botstage_messages as own
from botstage.robots.ros2 import readings
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.node import Publisher

log = logging.getLogger(__name__)


class StaleReadingError(RuntimeError):
    """A reading too old to act on: its topic stopped (the robot, its driver or the link)."""


class ClockRef:
    """The run's clock, which the run may replace once the robot is up (``use_clock``)."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock

    def now(self) -> float:
        return self.clock.now()


class Latest:
    """The newest reading of one topic and when it arrived (run clock), filled on Zenoh's threads."""

    def __init__(
        self, what: str, topic: str, convert: Callable[[Any], Any], clock: ClockRef, stale_after: float
    ) -> None:
        self.what, self.topic, self.stale_after = what, topic, stale_after
        self._convert, self._clock = convert, clock
        self._lock = threading.Lock()
        self._value: Any = None
        self._arrived: float | None = None
        self.received = 0
        self.rejected = 0
        self.stale_reads = 0
        self.ready = threading.Event()

    def on_message(self, message: Any, _: Attachment | None = None) -> None:
        """A message arrived: convert it (a message a reading cannot hold is counted and dropped)."""
        try:
            value = self._convert(message)
        except ValueError as error:
            with self._lock:
                self.rejected += 1
            log.warning("%s: dropped a message: %s", self.topic, error)
            return
        with self._lock:
            self._value, self._arrived = value, self._clock.now()
            self.received += 1
        self.ready.set()

    def get(self) -> tuple[Any, float]:
        """The newest reading and its arrival, or ``StaleReadingError`` if it is too old (or there is none)."""
        now = self._clock.now()
        with self._lock:
            value, arrived = self._value, self._arrived
            if arrived is None or now - arrived > self.stale_after:
                self.stale_reads += 1
        if arrived is None:
            raise StaleReadingError(f"{self.what}: nothing received on {self.topic} yet")
        age = now - arrived
        if age > self.stale_after:
            raise StaleReadingError(
                f"{self.what}: the latest message on {self.topic} is {age:.1f} s old (stale after "
                f"{self.stale_after:g} s): the robot stopped publishing it, or the link is down"
            )
        return value, arrived

    def rebase(self, old: Clock, new: Clock) -> None:
        """The run's clock changed: the arrival, as the same instant on the new clock (not before 0)."""
        with self._lock:
            if self._arrived is not None:
                self._arrived = max(0.0, new.now() - (old.now() - self._arrived))


# -- sensors ---------------------------------------------------------------------------------------


def _stamped(latest: Latest) -> Any:
    value, arrived = latest.get()
    return dataclasses.replace(value, stamp=arrived)


class OdometryProxy:
    def __init__(self, latest: Latest, start: Pose2D) -> None:
        self.latest, self.start = latest, start
        self._origin: Pose2D | None = None  # the robot's first odometry pose, in its odom frame

    def read(self) -> OdometryReading:
        reading = _stamped(self.latest)
        if self._origin is None:
            self._origin = reading.pose
        return anchored(reading, self._origin, self.start)


def anchored(reading: OdometryReading, origin: Pose2D, start: Pose2D) -> OdometryReading:
    """``reading`` moved so that ``origin`` (the robot's odom pose) falls on ``start`` (the mission's)."""
    turn = start.theta - origin.theta
    c, s = math.cos(turn), math.sin(turn)
    dx, dy = reading.pose.x - origin.x, reading.pose.y - origin.y
    theta = reading.pose.theta + turn
    pose = Pose2D(start.x + c * dx - s * dy, start.y + s * dx + c * dy, math.atan2(math.sin(theta), math.cos(theta)))
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    covariance = rotation @ np.asarray(reading.covariance) @ rotation.T
    return dataclasses.replace(reading, pose=pose, covariance=covariance)


class ImuProxy:
    def __init__(self, latest: Latest) -> None:
        self.latest = latest

    def read(self) -> Any:
        return _stamped(self.latest)


class LaserProxy:
    def __init__(self, latest: Latest) -> None:
        self.latest = latest

    def scan(self) -> Any:
        return _stamped(self.latest)


SonarProxy = ImuProxy  # read() of the newest reading, restamped
BatteryProxy = ImuProxy


class PeopleProxy:
    """The people of the newest PeopleTracks; the tracker's range is the robot's (from its messages)."""

    def __init__(self, latest: Latest, range_min: float, range_max: float) -> None:
        self.latest = latest
        self.range_min, self.range_max = range_min, range_max

    def people(self) -> list[TrackedPerson]:
        (people, self.range_min, self.range_max), _ = self.latest.get()
        return list(people)


class CameraProxy:
    """The newest frame (BGR, read-only: copy it to draw on it)."""

    def __init__(self, latest: Latest, info: CameraInfo) -> None:
        self.latest, self.info = latest, info

    def frame(self) -> np.ndarray:
        frame, _ = self.latest.get()
        return frame


class AudioBuffer:
    """Audio chunks kept from their arrival until the microphone is read (at most ``AUDIO_BUFFER_S``)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._chunks: deque[np.ndarray] = deque()
        self._buffered = 0
        self.dropped = 0  # samples lost because nobody read them in time

    def heard(self, samples: np.ndarray) -> np.ndarray:
        with self._lock:
            self._chunks.append(samples)
            self._buffered += samples.size
            while self._buffered > AUDIO_BUFFER_S * AUDIO_RATE_HZ and len(self._chunks) > 1:
                old = self._chunks.popleft()
                self._buffered -= old.size
                self.dropped += old.size
        return samples

    def take(self) -> np.ndarray:
        with self._lock:
            chunks, self._chunks, self._buffered = list(self._chunks), deque(), 0
        return np.concatenate(chunks) if chunks else np.zeros(0, np.int16)


class MicrophoneProxy:
    """Audio since the last read, joined from the chunks that arrived; stale when no chunk comes."""

    def __init__(self, latest: Latest, buffer: AudioBuffer) -> None:
        self.latest, self.buffer = latest, buffer

    def read(self) -> np.ndarray:
        self.latest.get()  # stale: the microphone stopped, and silence would be a lie
        return self.buffer.take()


# -- commands --------------------------------------------------------------------------------------


class DriveProxy:
    """Publishes a Twist per command, within the profile's limits (the robot enforces its own too)."""

    def __init__(self, publisher: Publisher, max_linear: float, max_angular: float) -> None:
        self.publisher = publisher
        self.max_linear, self.max_angular = max_linear, max_angular
        self.sent = 0

    def cmd_vel(self, v: float, w: float) -> None:
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"a velocity command must be finite, got ({v}, {w})")
        v = max(-self.max_linear, min(self.max_linear, v))
        w = max(-self.max_angular, min(self.max_angular, w))
        self.publisher.publish(readings.twist_message(Twist2D(v, w)))
        self.sent += 1

    def stop(self) -> None:
        self.cmd_vel(0.0, 0.0)


class SpeakerProxy:
    """Publishes the text to say; busy while the robot says it is speaking.

    Between ``say`` and the robot's first ``speaking: true`` the speaker counts as busy, for at
    most ``pending_s`` (a robot that says nothing of it is taken at its word after that).
    """

    def __init__(self, publisher: Publisher, speaking: Latest, clock: ClockRef, pending_s: float) -> None:
        self.publisher, self.speaking, self.clock = publisher, speaking, clock
        self.pending_s = pending_s
        self._pending_since: float | None = None
        self.said: list[tuple[float, str]] = []

    def say(self, text: str) -> None:
        self.publisher.publish(own.text_message(text))
        self._pending_since = self.clock.now()
        self.said.append((self._pending_since, text))

    def busy(self) -> bool:
        talking, arrived = self.speaking.get()
        if self._pending_since is not None:
            if talking and arrived >= self._pending_since:
                self._pending_since = None  # the robot took it
            elif self.clock.now() - self._pending_since <= self.pending_s:
                return True
            else:
                self._pending_since = None
        return bool(talking)


class DisplayProxy:
    def __init__(self, publisher: Publisher, clock: ClockRef) -> None:
        self.publisher, self.clock = publisher, clock
        self.shown: list[tuple[float, str, dict[str, str]]] = []

    def show(self, layout: str, **content: str) -> None:
        self.publisher.publish(own.display_message(layout, dict(content)))
        self.shown.append((self.clock.now(), layout, dict(content)))


class PanProxy:
    """A pan joint on the graph: goals published (clamped to the profile's limits, as the robot
    clamps them too), the position read from the newest joint state; None when that is stale, as
    a servo that cannot be read says."""

    def __init__(self, publisher: Publisher, state: Latest, min_angle: float, max_angle: float) -> None:
        self.publisher, self.state = publisher, state
        self._min, self._max = min_angle, max_angle
        self.sent = 0

    @property
    def min_angle(self) -> float:
        return self._min

    @property
    def max_angle(self) -> float:
        return self._max

    def move_to(self, angle: float) -> bool:
        if not math.isfinite(angle):
            raise ValueError(f"angle {angle}: a finite number of radians")
        self.publisher.publish(readings.command_message(min(max(angle, self._min), self._max)))
        self.sent += 1
        return True

    def position(self) -> float | None:
        try:
            value, _ = self.state.get()
        except StaleReadingError:
            return None
        return float(value)
