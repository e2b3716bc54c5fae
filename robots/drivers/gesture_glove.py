"""The ``gesture`` interface of a run: the book's IMU glove, as the gesture_drive skill reads it.

On a simulated clock the hand is a script (``HandScript``, the emulated Arduino's default unless
given) sampled at the sketch's 2.5 Hz on the mission clock, so a run is the same every time and
as fast as the simulator. On a wall clock the orientations come over rosserial from the port in
``BOTSTAGE_IMU_PORT``, or from the emulated Arduino on a pty when none is set; the driver opens
when a skill first asks, so a mission that never gestures opens nothing. Either way
``orientation()`` gives yaw, pitch, roll in degrees and ``received``, the mission time it arrived.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from dataclasses import dataclass
from typing import Any

from botstage.robots.clock import Clock
from botstage.robots.emulators.imu_arduino import PUBLISH_HZ, HandScript

PORT_VARIABLE = "BOTSTAGE_IMU_PORT"


@dataclass(frozen=True, slots=True)
class HandSample:
    yaw: float
    pitch: float
    roll: float
    received: float  # mission time


class ScriptedGlove:
    """A hand played from a script on the mission clock, sampled as the sketch publishes."""

    def __init__(self, clock: Clock, script: HandScript | None = None, rate_hz: float = PUBLISH_HZ) -> None:
        self.clock = clock
        self.script = script or HandScript.default()
        self.period = 1.0 / rate_hz

    def orientation(self) -> HandSample:
        at = math.floor(self.clock.now() / self.period + 1e-9) * self.period  # the last publication
        yaw, pitch, roll = self.script.at(at)
        return HandSample(yaw, pitch, roll, at)


class RosserialGlove:
    """The glove over rosserial (a port, or the emulated Arduino), opened on the first read."""

    def __init__(self, clock: Clock, port: str | None = None) -> None:
        self.clock = clock
        self.port = port
        self._stack = contextlib.ExitStack()
        self._driver: Any = None
        self._last: tuple[float, HandSample] | None = None  # the driver's last sample, as given out

    def _open(self) -> Any:
        from botstage.robots.drivers.rosserial import RosserialDriver
        from botstage.robots.emulators.imu_arduino import ImuArduino

        port = self.port
        if port is None:
            port = self._stack.enter_context(ImuArduino()).path
        self._driver = self._stack.enter_context(RosserialDriver(port))
        return self._driver

    def orientation(self) -> HandSample | None:
        driver = self._driver or self._open()
        sample = driver.orientation()
        if sample is None:
            return None
        if self._last is not None and self._last[0] == sample.received:
            return self._last[1]  # the same sample, at the same mission time: a reader counts it once
        age = time.monotonic() - sample.received  # the driver stamps arrivals on the monotonic clock
        given = HandSample(sample.yaw, sample.pitch, sample.roll, self.clock.now() - age)
        self._last = (sample.received, given)
        return given

    def close(self) -> None:
        self._stack.close()


def glove_for(clock: Clock) -> ScriptedGlove | RosserialGlove:
    """The run's glove: scripted on a simulated clock, rosserial on a wall clock."""
    if clock.simulated:
        return ScriptedGlove(clock)
    return RosserialGlove(clock, os.environ.get(PORT_VARIABLE) or None)
