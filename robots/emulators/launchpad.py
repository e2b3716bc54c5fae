"""The Chefbot's Tiva C Launchpad firmware on a pseudo-terminal, driving the simulated Chefbot.

The emulator is a ``PtyBoard`` (``pty_board.py``): a pty whose slave has a stable path, a
symlink in a private folder (as udev's ``/dev/serial/by-id`` names a USB board), which the
driver opens with pyserial like ``/dev/ttyACM0``. Its own thread plays the firmware's
``loop()`` at ``loop_hz`` (decision: 50 Hz; the chapter gives no rate): it reads ``s``/``r``
commands as they come (the Messenger library), sets the simulated wheels to the commanded
motor outputs, **steps the World by the wall-clock time since its last loop** (the emulator's
thread is the only one that moves the world, so the robot moves in real time, whatever the
mission's tick rate), and prints the firmware's lines in its loop order: ``t`` and ``e`` and
``s`` every loop, ``u`` at the sonar's rate, ``i`` at the IMU's (the profile's ``rate_hz``,
else 10 and 20 Hz) and ``b`` once a second (decision), about 3 KB/s of the line's 11.5 KB/s.

Like the book's firmware, the board keeps the last motor outputs it was given until told
otherwise: it has no watchdog (the driver has). A motor output becomes a wheel speed through
``MotorModel`` (the PWM share of the wheels' top speed, with a deadband), which the driver's PID
loop has to close. Encoder counters are C ``long`` (32-bit, wrapping; ``counter_start`` puts
them near the wrap for tests), ``micros()`` is unsigned 32-bit, the IMU's yaw starts at 0 at
boot (the MPU-6050's DMP knows no heading), printed with ``imu_decimals`` decimals (decision:
4; Energia's ``Serial.print(float)`` prints 2, a 1.1° step).

Faults on request: from ``PtyBoard``, ``inject_garbage``, ``drop_lines`` and
``unplug``/``replug``/``disconnect`` (the pty goes away; the path comes back with a new pty,
and the board, powered by the robot, carries on as it was); here, ``stall`` (a wheel that does
not turn whatever its motor gets) and ``board_reset`` (as ``r``: "Reset Done", a boot pause,
counters and clock from zero, motors off). Their arguments are bounded (``ValueError`` beyond,
``MAX_GARBAGE``, ``MAX_DROP`` and ``MAX_UNPLUG_S`` re-exported here): a fault never asks for more
memory or time than a test could want.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from botstage.robots.drivers.launchpad_protocol import PWM_LIMIT, CommandDecoder
from botstage.robots.emulators.pty_board import MAX_DROP, MAX_GARBAGE, MAX_UNPLUG_S, PtyBoard
from botstage.robots.sim.world import World

__all__ = ["MAX_DROP", "MAX_GARBAGE", "MAX_UNPLUG_S", "SONAR_RAYS", "WHEELS", "LaunchpadEmulator", "MotorModel"]

SONAR_RAYS = 7
WHEELS = ("left", "right")


@dataclass(frozen=True)
class MotorModel:
    """A motor output (PWM) to a wheel speed: linear above a deadband, full output at the top speed."""

    deadband: int = 10
    gain: float = 1.0

    def speed(self, pwm: float, top_speed: float) -> float:
        magnitude = min(abs(pwm), PWM_LIMIT)
        if magnitude <= self.deadband:
            return 0.0
        return math.copysign(self.gain * top_speed * (magnitude - self.deadband) / (PWM_LIMIT - self.deadband), pwm)


def _int32(value: int) -> int:
    return (value + 2**31) % 2**32 - 2**31


class LaunchpadEmulator(PtyBoard):
    """The board; see the module. ``start()`` (or a ``with`` block) opens the pty and runs it."""

    def __init__(
        self,
        world: World,
        *,
        world_lock: threading.Lock | None = None,
        loop_hz: float = 50.0,
        imu_hz: float | None = None,
        sonar_hz: float | None = None,
        battery_hz: float = 1.0,
        counter_start: int = 0,
        imu_decimals: int = 4,
        motor: MotorModel | None = None,
        boot_s: float = 0.3,
        link_dir: Path | None = None,
        extra_steps: list[Callable[[float], None]] | None = None,
        seed: int = 0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(
            name="launchpad",
            link_name="ttyLaunchpad",
            loop_hz=loop_hz,
            link_dir=link_dir,
            seed=seed,
            monotonic=monotonic,
        )
        self.world = world
        self.lock = world_lock or threading.Lock()
        interfaces = world.profile.interfaces
        imu, sonar = interfaces.get("imu"), interfaces.get("sonar")
        self.imu_period = 1.0 / (imu_hz or (imu.rate_hz if imu and imu.rate_hz else 20.0))
        self.sonar_period = 1.0 / (sonar_hz or (sonar.rate_hz if sonar and sonar.rate_hz else 10.0))
        self.battery_period = 1.0 / battery_hz
        self.sonar_device = (
            sonar.model_copy(update={"beams": SONAR_RAYS, "field_of_view": sonar.field_of_view or 0.26})
            if sonar is not None
            else None
        )
        self.counter_start = counter_start
        self.imu_decimals = imu_decimals
        self.motor = motor or MotorModel()
        self.boot_s = boot_s
        self.extra_steps = list(extra_steps or [])
        # the first speed command heard on each link (the first plug and every replug)
        self.first_speeds: list[tuple[int, int]] = []
        self.commands = CommandDecoder()
        self.speeds = (0, 0)  # motor outputs applied (PWM)
        self.stalled: set[str] = set()
        self._boot(monotonic())

    # -- faults -------------------------------------------------------------------------------

    def stall(self, wheel: str | None) -> None:
        """``left`` or ``right`` stops turning whatever its motor gets; None frees both."""
        if wheel is not None and wheel not in WHEELS:
            raise ValueError(f"no wheel {wheel!r}: left or right")
        with self._fault_lock:
            self.stalled = set() if wheel is None else {*self.stalled, wheel}

    def board_reset(self) -> None:
        """What ``r`` does: "Reset Done", then the board reboots."""
        self._write(b"Reset Done\r\n")
        self._boot(self.monotonic() + self.boot_s)
        self.counters["resets"] += 1

    # -- the firmware -------------------------------------------------------------------------

    def _boot(self, at: float) -> None:
        with self.lock:
            body = self.world.body
            self._tick_base = (body.left.ticks, body.right.ticks)
            self._imu_zero = self.world.imu_yaw
        self.speeds = (0, 0)
        self._booted_at = at
        self._booting_until = at
        self._last_loop = at
        self._next = {"imu": at, "sonar": at, "battery": at}
        self._last_micros = 0

    def _received(self, data: bytes) -> None:
        if self.monotonic() < self._booting_until:
            return  # a rebooting board hears nothing
        for command in self.commands.feed(data):
            self.counters[f"command_{command.kind}"] += 1
            if command.kind == "s":
                if self._fresh_link:  # what a driver says first on a new link (it must be zero)
                    self._fresh_link = False
                    self.first_speeds.append((command.left, command.right))
                self.speeds = (
                    max(-PWM_LIMIT, min(PWM_LIMIT, command.left)),
                    max(-PWM_LIMIT, min(PWM_LIMIT, command.right)),
                )
            else:
                self.board_reset()

    def _loop(self, now: float, dt: float) -> None:
        """One pass of the firmware's loop(): move the world, then print the readings."""
        world, base = self.world, self.world.profile.base
        top = base.wheel_top_speed
        left, right = (
            0.0 if wheel in self.stalled else self.motor.speed(pwm, top)
            for wheel, pwm in zip(("left", "right"), self.speeds, strict=True)
        )
        booting = now < self._booting_until
        lines = []
        with self.lock:
            world.cmd_vel((left + right) / 2, (right - left) / base.wheel_separation)
            if dt > 0:
                world.step(dt)
                for step in self.extra_steps:
                    step(dt)
            if booting:
                return
            body = world.body
            ticks = (
                _int32(body.left.ticks - self._tick_base[0] + self.counter_start),
                _int32(body.right.ticks - self._tick_base[1] + self.counter_start),
            )
            micros = int((now - self._booted_at) * 1e6) % 2**32
            since = ((micros - self._last_micros) % 2**32) / 1e6
            self._last_micros = micros
            lines.append(b"t\t%d\t%.6f\n" % (micros, since))
            lines.append(b"e\t%d\t%d\n" % ticks)
            if self.sonar_device is not None and now >= self._next["sonar"]:
                self._next["sonar"] = max(self._next["sonar"] + self.sonar_period, now)
                nearest = float(np.min(world.laser(self.sonar_device)))
                cm = int(nearest * 100) if math.isfinite(nearest) else 0  # no echo: pulseIn gives 0
                lines.append(b"u\t%d\n" % cm)
            lines.append(b"s\t%d\t%d\n" % self.speeds)
            if now >= self._next["imu"]:
                self._next["imu"] = max(self._next["imu"] + self.imu_period, now)
                yaw = math.remainder(world.imu_yaw - self._imu_zero, 2 * math.pi)
                d = self.imu_decimals
                quaternion = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
                lines.append(b"i\t" + b"\t".join(b"%.*f" % (d, q) for q in quaternion) + b"\n")
            if now >= self._next["battery"]:
                self._next["battery"] = max(self._next["battery"] + self.battery_period, now)
                lines.append(b"b\t%.2f\n" % world.battery_voltage)
        self._send_lines(lines)
