"""The gesture controller of the book's chapter 5: a hand's IMU steers a robot, made to drive any robot.

The chapter's converter (``gesture_teleop.py`` in qboticslabs/ros_robotics_projects, with its
``teleop_config.yaml``): on each orientation from the IMU (``imu_data``, yaw/pitch/roll in
degrees, 2.5 Hz), the change of pitch since the last one moves the speed by ``step_size`` per
degree and the change of yaw moves the turn the same way; speed stays within
``low_speed``..``high_speed`` (±4), turn within ``low_turn``..``high_turn`` (±2); with the hand
level (|pitch| under 2°) and not turning, the robot stops. Its quirks, fixed here:

- **Clamps by if/elif**: its ``if speed > high ... elif turn > high`` never clamps the turn
  while the speed is clamped. Here each is clamped on its own.
- **int() truncation**: it truncates the changes and the pitch to whole degrees, so slow
  motions (under a degree per sample) do nothing at all, and rounding toward zero makes the
  dead band lopsided (-2.9° counts as level, as 2.9° does; -3.0° does not). Here the changes are
  used as they are, and the home band is a stated width (``home_pitch_deg``; the yaw counts as
  still under ``still_yaw_deg`` a sample).
- **The yaw's wrap**: the DMP's yaw jumps from 180 to -180; the chapter's change of yaw is then
  -360°, a full turn the other way. Here the change is taken the short way round.
- **The robot's limits**: its ±4 m/s and ±2 rad/s are a simulated TurtleBot's ranges; here the
  converter's range maps onto the driven robot's ``max_linear`` and ``max_angular`` (the
  chapter's full tilt is the robot's top speed), so the same hand drives Chefbot and Bittle.
- **A hand that goes quiet** (the IMU unplugged, the link lost): with no orientation for
  ``stale_s`` the command is zero, as a robot's velocity watchdog would do, and the converter
  starts afresh from the next one (the hand may have moved meanwhile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


class GestureConfig(BaseModel):
    """The chapter's ``teleop_config.yaml`` keys, and this converter's own (with defaults)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    imu_topic: str = Field(default="/imu_data", description="the rosserial topic of the IMU's yaw/pitch/roll")
    low_speed: float = -4.0
    high_speed: float = 4.0
    low_turn: float = -2.0
    high_turn: float = 2.0
    step_size: float = Field(default=0.02, gt=0, description="speed (turn) per degree of pitch (yaw) change")
    home_pitch_deg: float = Field(default=2.0, ge=0, description="a hand this level (±) is at home")
    still_yaw_deg: float = Field(default=0.5, ge=0, description="a yaw change this small per sample is no turn")
    stale_s: float = Field(default=1.0, gt=0, description="s without an orientation before the robot stops")

    @model_validator(mode="after")
    def _ranges(self) -> GestureConfig:
        if not (self.low_speed < 0 < self.high_speed and self.low_turn < 0 < self.high_turn):
            raise ValueError("low_speed < 0 < high_speed and low_turn < 0 < high_turn")
        return self


def load_config(path: str | Path) -> GestureConfig:
    """A ``teleop_config.yaml`` (the chapter's keys; unknown ones are errors); ValueError with the reason."""
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
        return GestureConfig.model_validate(data)
    except ValidationError as error:
        problems = [
            f"{'.'.join(map(str, e['loc'])) or 'the file'}: "
            + ("unknown key" if e["type"] == "extra_forbidden" else e["msg"].removeprefix("Value error, "))
            for e in error.errors()
        ]
        raise ValueError(f"{path}: {'; '.join(problems)}") from None
    except (OSError, yaml.YAMLError) as error:
        raise ValueError(f"{path}: {error}") from None


def _clamp(value: float, low: float, high: float) -> float:
    return max(low, min(high, value))


@dataclass
class GestureConverter:
    """Orientation samples in, the chapter's (speed, turn) out; see the module."""

    config: GestureConfig = field(default_factory=GestureConfig)
    speed: float = 0.0
    turn: float = 0.0
    _last: tuple[float, float] | None = None  # the previous sample's yaw and pitch

    def update(self, yaw: float, pitch: float) -> tuple[float, float]:
        """One IMU sample (degrees); the new (speed, turn) in the chapter's units."""
        config = self.config
        if self._last is None:
            self._last = (yaw, pitch)  # the first sample only sets where the hand is
        d_yaw = math.remainder(yaw - self._last[0], 360.0)
        d_pitch = pitch - self._last[1]
        self._last = (yaw, pitch)
        if abs(pitch) < config.home_pitch_deg and abs(d_yaw) < config.still_yaw_deg:
            self.speed = self.turn = 0.0
        else:
            self.speed = _clamp(self.speed + config.step_size * d_pitch, config.low_speed, config.high_speed)
            self.turn = _clamp(self.turn + config.step_size * d_yaw, config.low_turn, config.high_turn)
        return self.speed, self.turn

    def reset(self) -> None:
        """Start afresh (the hand was lost): stopped, and the next sample is a new reference."""
        self.speed = self.turn = 0.0
        self._last = None

    def command(self, max_linear: float, max_angular: float) -> tuple[float, float]:
        """(v, w) for a robot with these limits: the converter's range mapped onto them."""
        config = self.config
        v = self.speed / (config.high_speed if self.speed >= 0 else -config.low_speed) * max_linear
        w = self.turn / (config.high_turn if self.turn >= 0 else -config.low_turn) * max_angular
        return v, w


class OrientationSource(Protocol):
    """Where orientations come from (the rosserial driver's ``orientation()``)."""

    def orientation(self) -> Any: ...  # an object with yaw, pitch, roll (degrees) and received (monotonic s)


class GestureCommands:
    """The teleop loop's commands from a hand: each tick, the newest sample through the converter.

    ``monotonic`` is the clock the samples' ``received`` times are on (the driver's).
    """

    def __init__(
        self,
        source: OrientationSource,
        max_linear: float,
        max_angular: float,
        config: GestureConfig | None = None,
        monotonic: Any = None,
    ) -> None:
        import time

        self.source = source
        self.limits = (max_linear, max_angular)
        self.converter = GestureConverter(config or GestureConfig())
        self.monotonic = monotonic or time.monotonic
        self._seen: float | None = None  # the received time of the last sample taken
        self.samples = 0
        self.stale = False

    def __call__(self) -> tuple[float, float]:
        sample = self.source.orientation()
        now = self.monotonic()
        if sample is None or now - sample.received > self.converter.config.stale_s:
            if not self.stale:
                self.converter.reset()
            self.stale = True
            return 0.0, 0.0
        self.stale = False
        if sample.received != self._seen:
            self._seen = sample.received
            self.samples += 1
            self.converter.update(sample.yaw, sample.pitch)
        return self.converter.command(*self.limits)
