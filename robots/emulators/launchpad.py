"""The Chefbot's Tiva C Launchpad firmware on a pseudo-terminal, driving the simulated Chefbot.

The emulator opens a pty (``os.openpty``) and gives its slave a stable path, a symlink in a
private folder (as udev's ``/dev/serial/by-id`` names a USB board), which the driver opens
with pyserial like ``/dev/ttyACM0``. Its own thread plays the firmware's ``loop()`` at
``loop_hz`` (decision: 50 Hz; the chapter gives no rate): it reads ``s``/``r`` commands as
they come (the Messenger library), sets the simulated wheels to the commanded motor outputs,
**steps the World by the wall-clock time since its last loop** (the emulator's thread is the
only one that moves the world, so the robot moves in real time, whatever the mission's tick
rate), and prints the firmware's lines in its loop order: ``t`` and ``e`` and ``s`` every loop,
``u`` at the sonar's rate, ``i`` at the IMU's (the profile's ``rate_hz``, else 10 and 20 Hz)
and ``b`` once a second (decision), about 3 KB/s of the line's 11.5 KB/s.

Like the book's firmware, the board keeps the last motor outputs it was given until told
otherwise: it has no watchdog (the driver has). A motor output becomes a wheel speed through
``MotorModel`` (the PWM share of the wheels' top speed, with a deadband), which the driver's PID
loop has to close. Encoder counters are C ``long`` (32-bit, wrapping; ``counter_start`` puts
them near the wrap for tests), ``micros()`` is unsigned 32-bit, the IMU's yaw starts at 0 at
boot (the MPU-6050's DMP knows no heading), printed with ``imu_decimals`` decimals (decision:
4; Energia's ``Serial.print(float)`` prints 2, a 1.1° step).

Faults on request: ``inject_garbage``, ``drop_lines``, ``stall`` (a wheel that does not turn
whatever its motor gets), ``unplug``/``replug``/``disconnect`` (the pty goes away; the path
comes back with a new pty), ``board_reset`` (as ``r``: "Reset Done", a boot pause, counters and
clock from zero, motors off). Their arguments are bounded (``ValueError`` beyond): a fault
never asks for more memory or time than a test could want.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import shutil
import tempfile
import threading
import time
import tty
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robots.drivers.launchpad_protocol import PWM_LIMIT, CommandDecoder
from robots.sim.world import World

SONAR_RAYS = 7
WHEELS = ("left", "right")
MAX_GARBAGE = 2**20  # bytes waiting to go out at once: a megabyte is 90 s of the line
MAX_DROP = 1_000_000  # lines (over an hour of the firmware's output)
MAX_UNPLUG_S = 3600.0


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


class LaunchpadEmulator:
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
        self.world = world
        self.lock = world_lock or threading.Lock()
        interfaces = world.profile.interfaces
        self.period = 1.0 / loop_hz
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
        self.rng = np.random.default_rng(seed)  # garbage bytes
        self.monotonic = monotonic
        self._own_dir = link_dir is None
        self.link_dir = Path(tempfile.mkdtemp(prefix="botstage-launchpad-")) if link_dir is None else link_dir
        self.path = str(self.link_dir / "ttyLaunchpad")
        self.pty_path: str | None = None
        self.counters: Counter[str] = Counter()
        # the first speed command heard on each link (the first plug and every replug)
        self.first_speeds: list[tuple[int, int]] = []
        self._fresh_link = True
        self.commands = CommandDecoder()
        self.speeds = (0, 0)  # motor outputs applied (PWM)
        self.stalled: set[str] = set()
        self._master: int | None = None
        self._slave: int | None = None
        self._garbage = b""
        self._drop = 0
        self._replug_at: float | None = None
        self._booting_until = 0.0
        self._fault_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._boot(monotonic())

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> LaunchpadEmulator:
        self.replug()
        self._thread = threading.Thread(target=self._run, name="launchpad-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self.unplug()
        if self._own_dir:
            shutil.rmtree(self.link_dir, ignore_errors=True)

    def __enter__(self) -> LaunchpadEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- faults -------------------------------------------------------------------------------

    def inject_garbage(self, count: int) -> None:
        """``count`` random bytes go out between two lines of the next loop (at most ``MAX_GARBAGE``
        waiting at once)."""
        with self._fault_lock:
            waiting = len(self._garbage)
            if not 0 <= count <= MAX_GARBAGE - waiting:
                raise ValueError(f"garbage of {count} bytes: 0 to {MAX_GARBAGE - waiting:,} more may wait to go out")
            self._garbage += self.rng.integers(0, 256, count, dtype=np.uint8).tobytes()

    def drop_lines(self, count: int) -> None:
        """The next ``count`` lines are lost (at most ``MAX_DROP`` waiting)."""
        with self._fault_lock:
            if not 0 <= count <= MAX_DROP - self._drop:
                raise ValueError(f"dropping {count} lines: 0 to {MAX_DROP - self._drop:,} more may wait")
            self._drop += count

    def stall(self, wheel: str | None) -> None:
        """``left`` or ``right`` stops turning whatever its motor gets; None frees both."""
        if wheel is not None and wheel not in WHEELS:
            raise ValueError(f"no wheel {wheel!r}: left or right")
        with self._fault_lock:
            self.stalled = set() if wheel is None else {*self.stalled, wheel}

    def unplug(self) -> None:
        """The board's USB goes away: the pty closes and the path disappears."""
        with self._fault_lock:
            master, slave, self._master, self._slave = self._master, self._slave, None, None
            self.pty_path = None
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        for fd in (master, slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        if master is not None:
            self.counters["unplugs"] += 1

    def replug(self) -> None:
        """A new pty behind the same path (a board plugged back in)."""
        self.unplug()
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no newline translation before the driver configures it
        os.set_blocking(master, False)
        pty_path = os.ttyname(slave)
        temporary = f"{self.path}.{os.getpid()}.tmp"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(pty_path, temporary)
        os.replace(temporary, self.path)
        with self._fault_lock:
            self._master, self._slave, self.pty_path = master, slave, pty_path
            self._replug_at = None
            self._fresh_link = True
        self.counters["plugs"] += 1

    def disconnect(self, for_s: float) -> None:
        """Unplug now and plug back in after ``for_s`` seconds (more than 0, at most ``MAX_UNPLUG_S``)."""
        if not (math.isfinite(for_s) and 0 < for_s <= MAX_UNPLUG_S):
            raise ValueError(f"unplugged for {for_s} s: more than 0 and at most {MAX_UNPLUG_S:g}")
        self.unplug()
        with self._fault_lock:
            self._replug_at = self.monotonic() + for_s

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

    def _run(self) -> None:
        next_loop = self.monotonic()
        last_step = next_loop
        while not self._stop.is_set():
            now = self.monotonic()
            if self._replug_at is not None and now >= self._replug_at:
                self.replug()
            master = self._master
            wait = max(0.0, next_loop - now)
            if master is None:
                self._stop.wait(wait)
            else:
                try:
                    ready, _, _ = select.select([master], [], [], wait)
                except (OSError, ValueError):  # closed under us by unplug()
                    continue
                if ready:
                    self._read_commands(master)
            now = self.monotonic()
            if now < next_loop:
                continue
            dt = min(max(now - last_step, 0.0), 0.1)
            last_step = now
            self._loop(now, dt)
            next_loop += self.period
            if next_loop < now:  # late: start again from now rather than bursting
                next_loop = now + self.period

    def _read_commands(self, master: int) -> None:
        try:
            data = os.read(master, 4096)
        except BlockingIOError:
            return
        except OSError:  # EIO: nobody holds the slave (cannot happen while we hold it)
            return
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
        with self._fault_lock:
            garbage, self._garbage = self._garbage, b""
            if self._drop:
                dropped = min(self._drop, len(lines))
                self._drop -= dropped
                self.counters["lines_dropped"] += dropped
                lines = lines[dropped:]
        if garbage:
            lines.insert(len(lines) // 2, garbage)
        self.counters["lines_sent"] += len(lines)
        self._write(b"".join(lines))

    def _write(self, data: bytes) -> None:
        master = self._master
        if master is None or not data:
            return
        try:
            written = os.write(master, data)
        except BlockingIOError:  # nobody reads: a UART's bytes are lost
            written = 0
        except OSError:
            return
        self.counters["bytes_sent"] += written
        self.counters["bytes_lost"] += len(data) - written
