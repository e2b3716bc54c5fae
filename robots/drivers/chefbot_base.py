"""Chefbot on its Launchpad: the book's controller chain behind the robot interfaces.

``cmd_vel`` → twist_to_motors (``wheel_targets``, within the profile's limits) → a PID speed
loop per wheel (``WheelController``) → ``s <left> <right>``. The loop runs on every encoder
line the board sends, and at once on every command, so a new speed (or a stop) goes out without
waiting for the board. Without fresh encoder lines (over ``STALE_S``) the integral holds: the
loop does not wind the motors up on news it does not have. The encoder steps also feed diff_tf odometry
(``DiffOdometry``); the IMU quaternion gives the yaw the localiser's EKF fuses; the ``u`` and
``b`` lines give the sonar and the battery.

Safety, enforced here whatever the caller does:

- **Watchdog**: with no velocity command for ``watchdog_s`` (profile ``control.watchdog_s``,
  0.5 s) the targets go to zero and ``s 0 0`` is sent; the next command moves the robot again.
- **Limits**: speeds and turn rates beyond the profile's are clamped, wheel speeds are kept
  under the wheels' top speed, outputs under the PID's ``output_limit`` (and the link clamps to
  ±255 again). Accelerations are left to the callers (navigation shapes its commands) and to
  the motors.
- **Board resets** (``micros()`` going backwards, or encoder counters jumping further than
  the wheels could turn) are counted and logged at a limited rate; odometry takes the new
  counters as its reference instead of a jump, the IMU's yaw is re-aligned so the heading
  stays continuous, and the PID starts afresh.

The board's counters are 32-bit (``launchpad_protocol``); their steps are taken modulo 2**32.
Time for velocity estimates comes from the board's ``micros()`` when its ``t`` line came with
the encoder line (as the firmware prints them), else from the host's monotonic clock.
Readings are stamped with the mission clock. Thread-safe: the reader thread updates, any
thread reads and commands.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

from botstage.robots.clock import Clock
from botstage.robots.drivers.diff_odometry import DiffOdometry
from botstage.robots.drivers.launchpad import LaunchpadDriver
from botstage.robots.drivers.launchpad_protocol import (
    ENCODER_BITS,
    BatteryVolts,
    BoardTime,
    Encoders,
    Message,
    MotorSpeeds,
    Quaternion,
    Ultrasonic,
    micros_delta,
    wrap_delta,
)
from botstage.robots.drivers.serial_link import RateLimitedLog
from botstage.robots.drivers.wheel_control import WheelController, WheelSpeed, wheel_targets
from botstage.robots.interfaces import BatteryState, ImuReading, OdometryReading, Pose2D, SonarReading
from botstage.robots.profile import Profile

log = logging.getLogger(__name__)

LAUNCHPAD = "launchpad"  # the driver name profiles give (interfaces: {drive: {hardware: launchpad}})
RESEND_S = 0.2  # an unchanged motor command is repeated this often (a lost command is not for ever)
STALE_S = 0.2  # encoder news older than this does not feed the PID's integral
WATCHDOG_POLL_S = 0.05


def _wrap(theta: float) -> float:
    return (theta + math.pi) % (2 * math.pi) - math.pi


class ChefbotBase:
    """The controller chain and the devices; see the module. ``open_chefbot`` builds one on a port."""

    def __init__(
        self,
        link: LaunchpadDriver,
        profile: Profile,
        clock: Clock,
        start: Pose2D | None = None,
        *,
        watchdog_s: float | None = None,
        encoder_bits: int = ENCODER_BITS,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        self.profile = profile
        self.base = profile.base
        self.clock = clock
        self.monotonic = monotonic
        self.watchdog_s = watchdog_s if watchdog_s is not None else profile.control.watchdog_s
        self.encoder_bits = encoder_bits
        self.start_pose = start or Pose2D(0.0, 0.0, 0.0)
        self.warn = RateLimitedLog(log, monotonic=monotonic)
        self.counters: Counter[str] = Counter()
        self._lock = threading.RLock()
        gains, top = profile.control.pid, self.base.wheel_top_speed
        self.controllers = (WheelController(gains, top), WheelController(gains, top))
        self.speeds = (
            WheelSpeed(self.base.ticks_per_metre, gains.smoothing),
            WheelSpeed(self.base.ticks_per_metre, gains.smoothing),
        )
        self.odometry = DiffOdometry(self.base.ticks_per_metre, self.base.wheel_separation, self.start_pose)
        self.targets = (0.0, 0.0)  # m/s per wheel, as commanded (within the limits)
        self.sent: tuple[int, int] | None = None
        self._sent_at = -math.inf
        self._last_command = -math.inf
        self._watchdog_tripped = True
        self._last_control = monotonic()
        self._encoders: tuple[int, int] | None = None  # the reference for the next step
        self._encoders_at = 0.0  # when the reference was received
        self._encoders_seen = -math.inf  # when the last encoder line was used (monotonic)
        self._encoders_micros: int | None = None
        self._micros: int | None = None
        self._micros_at = 0.0
        self._micros_fresh = False  # a t line came since the last e line
        self.yaw: float | None = None
        self.yaw_rate = 0.0
        self._yaw_offset: float | None = None
        self._yaw_at = 0.0
        self.sonar_m: float | None = None
        self.volts: float | None = None
        self.motor_speeds: tuple[float, float] | None = None  # what the board says it applies
        self._seen: set[type] = set()
        self._ready = threading.Event()
        self._is_ready = False
        self._handlers: dict[type, Callable[[Any, float], None]] = {
            Encoders: self._on_encoders,
            BoardTime: self._on_time,
            Quaternion: self._on_imu,
            Ultrasonic: self._on_sonar,
            BatteryVolts: self._on_battery,
            MotorSpeeds: self._on_speeds,
        }
        self._closing = threading.Event()
        self._watchdog: threading.Thread | None = None
        sonar = profile.interfaces.get("sonar")
        self.devices: dict[str, Any] = {}
        makers: dict[str, Callable[[], Any]] = {
            "drive": lambda: LaunchpadDrive(self),
            "odometry": lambda: LaunchpadOdometry(self),
            "imu": lambda: LaunchpadImu(self),
            "sonar": lambda: LaunchpadSonar(self, sonar.range_max or 4.0, sonar.field_of_view or 0.26),
            "battery": lambda: LaunchpadBattery(self),
        }
        for name, device in profile.interfaces.items():
            if device.hardware == LAUNCHPAD and name in makers:
                self.devices[name] = makers[name]()

    # -- lifecycle ----------------------------------------------------------------------------

    def start_watchdog(self) -> None:
        if self._watchdog is None:
            self._watchdog = threading.Thread(target=self._watch, name="launchpad-watchdog", daemon=True)
            self._watchdog.start()

    def wait_ready(self, timeout: float) -> bool:
        """True once encoders, IMU and battery have each reported (the devices have data)."""
        return self._ready.wait(timeout)

    def close(self) -> None:
        """Stop: zero speed, then the watchdog and the link (which sends zero again)."""
        self.stop()
        self._closing.set()
        if self._watchdog is not None and self._watchdog is not threading.current_thread():
            self._watchdog.join(timeout=1.0)
        self.link.close()

    # -- commands -----------------------------------------------------------------------------

    def cmd_vel(self, v: float, w: float) -> None:
        try:
            left, right = wheel_targets(v, w, self.base)
        except ValueError:
            self.stop()  # a broken command stops the robot, and the caller hears of it
            raise
        now = self.monotonic()
        with self._lock:
            self.targets = (left, right)
            self._last_command = now
            self._watchdog_tripped = False
            self._control(now - self._last_control, now)

    def stop(self) -> None:
        """Zero at once, without the PID (the motors brake)."""
        now = self.monotonic()
        with self._lock:
            self.targets = (0.0, 0.0)
            self._last_command = now
            for controller in self.controllers:
                controller.reset()
            self._send(0, 0, now, force=True)

    def check_watchdog(self) -> bool:
        """Stop the motors if no command came for ``watchdog_s``; True when it did (once per silence)."""
        now = self.monotonic()
        with self._lock:
            if self._watchdog_tripped or now - self._last_command <= self.watchdog_s:
                return False
            self._watchdog_tripped = True
            moving = any(self.targets) or (self.sent is not None and any(self.sent))
            self.targets = (0.0, 0.0)
            for controller in self.controllers:
                controller.reset()
            self._send(0, 0, now, force=True)
            if moving:
                self.counters["watchdog_stops"] += 1
                self.warn.warning("watchdog", f"no velocity command for {self.watchdog_s:g} s: motors stopped")
            return moving

    def _watch(self) -> None:
        while not self._closing.wait(WATCHDOG_POLL_S):
            try:
                self.check_watchdog()
            except Exception as exc:  # never let the watchdog thread die
                self.counters["watchdog_errors"] += 1
                self.warn.warning("watchdog_error", f"watchdog check failed: {exc!r}")

    def _control(self, dt: float, now: float) -> None:
        """One step of the chain: the PIDs on the targets and the measured speeds, then send."""
        dt = min(max(dt, 0.0), 0.1)
        self._last_control = now
        if now - self._encoders_seen > STALE_S:
            dt = 0.0  # no news from the encoders: hold the integral
        outputs = [
            controller.step(target, speed.value, dt)
            for controller, target, speed in zip(self.controllers, self.targets, self.speeds, strict=True)
        ]
        self._send(round(outputs[0]), round(outputs[1]), now)

    def _send(self, left: int, right: int, now: float, force: bool = False) -> None:
        due = force or (left, right) != self.sent or now - self._sent_at >= RESEND_S
        if due and self.link.send_speeds(left, right):
            self.sent, self._sent_at = (left, right), now

    # -- from the board (the reader thread) ---------------------------------------------------

    def on_message(self, message: Message, received: float) -> None:
        kind = type(message)
        with self._lock:
            self._handlers[kind](message, received)
            if not self._is_ready:
                self._seen.add(kind)
                if {Encoders, Quaternion, BatteryVolts} <= self._seen:
                    self._is_ready = True
                    self._ready.set()

    def _on_sonar(self, message: Ultrasonic, received: float) -> None:
        self.sonar_m = message.cm / 100.0 if message.cm > 0 else math.inf

    def _on_battery(self, message: BatteryVolts, received: float) -> None:
        self.volts = message.volts

    def _on_speeds(self, message: MotorSpeeds, received: float) -> None:
        self.motor_speeds = (message.left, message.right)

    def on_connect(self) -> None:
        with self._lock:
            self._forget_board()
            self.sent = (0, 0)  # the link sent zero on connecting

    def on_disconnect(self) -> None:
        with self._lock:
            self._forget_board()
            self.sent = None
            self.odometry.still()

    def _forget_board(self) -> None:
        """What must be learnt again from the board: counters, clock, yaw offset, speeds, PID."""
        self._encoders = None
        self._micros = None
        self._micros_fresh = False
        self._yaw_offset = None
        for controller, speed in zip(self.controllers, self.speeds, strict=True):
            controller.reset()
            speed.reset()

    def _board_reset(self, why: str) -> None:
        self.counters["board_resets"] += 1
        self.warn.warning("board_reset", f"the Launchpad reset ({why}): odometry and IMU continue from here")
        self._forget_board()

    def _on_time(self, message: BoardTime, received: float) -> None:
        if self._micros is not None:
            forward = micros_delta(message.micros, self._micros)
            # further ahead than the time that passed (with margin) means micros() went back: a reboot
            if forward > max(5_000_000, 3e6 * (received - self._micros_at)):
                self._board_reset("its clock went back")
        self._micros, self._micros_at, self._micros_fresh = message.micros, received, True

    def _on_encoders(self, message: Encoders, received: float) -> None:
        raw = (message.left, message.right)
        micros = self._micros if self._micros_fresh else None
        self._micros_fresh = False
        previous, previous_at, previous_micros = self._encoders, self._encoders_at, self._encoders_micros
        self._encoders, self._encoders_at, self._encoders_micros = raw, received, micros
        if previous is None:
            return  # the reference for the next step
        host_dt = received - previous_at
        dt = host_dt
        if micros is not None and previous_micros is not None:
            board_dt = micros_delta(micros, previous_micros) / 1e6
            if 0 < board_dt < 1.0:
                dt = board_dt
        steps = (wrap_delta(raw[0], previous[0], self.encoder_bits), wrap_delta(raw[1], previous[1], self.encoder_bits))
        base = self.base
        possible = 2.0 * base.wheel_top_speed * base.ticks_per_metre * max(host_dt, dt, 0.05) + 20
        if max(abs(steps[0]), abs(steps[1])) > possible:
            self.counters["encoder_jumps"] += 1
            self._board_reset(f"encoders jumped by {steps[0]}, {steps[1]} ticks")
            self._encoders, self._encoders_at, self._encoders_micros = raw, received, micros
            return
        self.odometry.add(steps[0], steps[1], dt)
        for speed, step in zip(self.speeds, steps, strict=True):
            speed.add(step, dt)
        now = self.monotonic()
        self._encoders_seen = now
        self._control(now - self._last_control, now)

    def _on_imu(self, message: Quaternion, received: float) -> None:
        raw = message.yaw
        if self._yaw_offset is None:  # first reading, or after a reset: continue the heading
            heading = self.yaw if self.yaw is not None else self.start_pose.theta
            self._yaw_offset = heading - raw
            self.yaw_rate = 0.0
        else:
            dt = received - self._yaw_at
            if dt > 0 and self.yaw is not None:
                self.yaw_rate = _wrap(_wrap(raw + self._yaw_offset) - self.yaw) / dt
        self.yaw = _wrap(raw + self._yaw_offset)
        self._yaw_at = received

    # -- readings -----------------------------------------------------------------------------

    def read_odometry(self) -> OdometryReading:
        with self._lock:
            odometry = self.odometry
            if self.monotonic() - self._encoders_at > 0.5:
                odometry.still()  # no encoder news: not moving as far as we know
            return OdometryReading(self.clock.now(), odometry.pose, odometry.twist, odometry.covariance)

    def read_imu(self) -> ImuReading:
        with self._lock:
            yaw = self.yaw if self.yaw is not None else self.start_pose.theta
            return ImuReading(self.clock.now(), yaw, self.yaw_rate, (0.0, 0.0))

    def read_battery(self) -> BatteryState:
        spec = self.profile.battery
        with self._lock:
            volts = self.volts if self.volts is not None else spec.nominal_voltage
        percent = 100.0 * (volts - spec.empty_voltage) / (spec.full_voltage - spec.empty_voltage)
        return BatteryState(self.clock.now(), volts, max(0.0, min(100.0, percent)))

    def summary(self) -> dict[str, Any]:
        """The link's and the chain's counters, for the run's summary."""
        with self._lock:
            pose = self.odometry.pose
            return {
                **self.link.stats(),
                **dict(sorted(self.counters.items())),
                "odometry_pose": [round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)],
                "odometry_distance_m": round(self.odometry.distance, 4),
            }


class LaunchpadDrive:
    def __init__(self, base: ChefbotBase) -> None:
        self.base = base

    def cmd_vel(self, v: float, w: float) -> None:
        self.base.cmd_vel(v, w)

    def stop(self) -> None:
        self.base.stop()


class LaunchpadOdometry:
    def __init__(self, base: ChefbotBase) -> None:
        self.base = base

    def read(self) -> OdometryReading:
        return self.base.read_odometry()


class LaunchpadImu:
    def __init__(self, base: ChefbotBase) -> None:
        self.base = base

    def read(self) -> ImuReading:
        return self.base.read_imu()


class LaunchpadSonar:
    def __init__(self, base: ChefbotBase, max_range: float, field_of_view: float) -> None:
        self.base = base
        self.max_range = max_range
        self.field_of_view = field_of_view

    def read(self) -> SonarReading:
        metres = self.base.sonar_m
        if metres is None or metres > self.max_range:
            metres = math.inf
        return SonarReading(self.base.clock.now(), metres, self.field_of_view, self.max_range)


class LaunchpadBattery:
    def __init__(self, base: ChefbotBase) -> None:
        self.base = base

    def read(self) -> BatteryState:
        return self.base.read_battery()


def open_chefbot(
    port: str,
    profile: Profile,
    clock: Clock,
    start: Pose2D | None = None,
    *,
    watchdog_s: float | None = None,
    monotonic: Callable[[], float] = time.monotonic,
    **link_options: Any,
) -> ChefbotBase:
    """The chain on a port: the link's reader and the watchdog running (call ``close()``)."""
    link = LaunchpadDriver(port, start=False, monotonic=monotonic, **link_options)
    base = ChefbotBase(link, profile, clock, start, watchdog_s=watchdog_s, monotonic=monotonic)
    link.listener = base
    link.start()
    base.start_watchdog()
    return base
