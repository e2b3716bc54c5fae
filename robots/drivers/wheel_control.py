"""From a velocity command to motor outputs: the book's twist_to_motors and pid_velocity nodes.

``wheel_targets`` turns (v, ω) into the two wheels' speeds for the base's wheel separation,
within the profile's limits (the driver enforces them; callers are not trusted).
``WheelController`` closes the loop per wheel (gains: the profile's ``control.pid``): the motor
output (PWM) that makes the wheel's measured speed (from the encoders) follow its target. Unlike
the book's node it has a feedforward term (the output the target needs on a free wheel), so the
integral only makes up for load and friction, and anti-windup: the integral accumulates only
near the target (``integral_zone``: not while the wheel is still accelerating towards a new
speed), never further in the direction of a saturated output, and its share of the output is
bounded by the output limit, so a stalled wheel does not wind it up to a lurch when it frees.
"""

from __future__ import annotations

import math
from collections import deque

from botstage.robots.profile import Base, WheelPid


def wheel_targets(v: float, w: float, base: Base) -> tuple[float, float]:
    """(v, ω) to (left, right) wheel speeds in m/s, clamped to the profile's limits; when a
    wheel would pass the top speed both are scaled down together, keeping the turn's shape."""
    if not (math.isfinite(v) and math.isfinite(w)):
        raise ValueError(f"a velocity command must be finite, got ({v}, {w})")
    v = max(-base.max_linear, min(base.max_linear, v))
    w = max(-base.max_angular, min(base.max_angular, w))
    half = base.wheel_separation / 2
    left, right = v - w * half, v + w * half
    top = base.wheel_top_speed
    scale = max(abs(left), abs(right), top) / top
    return left / scale, right / scale


class WheelSpeed:
    """A wheel's measured speed: encoder steps over their time, averaged over a few samples."""

    def __init__(self, ticks_per_metre: float, samples: int = 2) -> None:
        self.ticks_per_metre = ticks_per_metre
        self._samples: deque[float] = deque(maxlen=samples)
        self.value = 0.0

    def add(self, ticks: int, dt: float) -> float:
        if dt > 0:
            self._samples.append(ticks / self.ticks_per_metre / dt)
            self.value = sum(self._samples) / len(self._samples)
        return self.value

    def reset(self) -> None:
        self._samples.clear()
        self.value = 0.0


class WheelController:
    """One wheel's PID speed loop with feedforward and anti-windup; see the module."""

    def __init__(self, gains: WheelPid, top_speed: float) -> None:
        self.gains = gains
        self.kf = gains.kf if gains.kf is not None else gains.output_limit / top_speed
        self.limit = gains.output_limit
        self.integral = 0.0  # m of accumulated error
        self._previous_error: float | None = None
        self.output = 0.0
        self.saturated = False

    def reset(self) -> None:
        self.integral = 0.0
        self._previous_error = None
        self.output = 0.0
        self.saturated = False

    def step(self, target: float, measured: float, dt: float) -> float:
        """The motor output for this control step; a wheel told to stop gets zero (the motor
        driver brakes) and forgets its integral, so it does not creep."""
        if target == 0.0:
            self.reset()
            return 0.0
        g = self.gains
        error = target - measured
        derivative = 0.0
        if g.kd and self._previous_error is not None and dt > 0:
            derivative = (error - self._previous_error) / dt
        self._previous_error = error
        fixed = self.kf * target + g.kp * error + g.kd * derivative
        if g.ki and abs(error) < g.integral_zone:
            integral = self.integral + error * max(dt, 0.0)
            unclamped = fixed + g.ki * integral
            # integrate only when that does not push a saturated output further out
            if abs(unclamped) <= self.limit or unclamped * error < 0:
                bound = 2 * self.limit / g.ki
                self.integral = max(-bound, min(bound, integral))
        raw = fixed + g.ki * self.integral
        self.output = max(-self.limit, min(self.limit, raw))
        self.saturated = abs(raw) > self.limit
        return self.output
