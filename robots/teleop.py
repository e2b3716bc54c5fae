"""Keyboard teleoperation, as the book's keyboard_teleop: keys step the commanded velocity.

``w``/``x`` (or ↑/↓) make the robot go faster forward or backward by ``linear_step``, ``a``/``d``
(or ←/→) turn it faster left or right by ``angular_step``, ``s`` or space stop it, ``q`` (or
Ctrl-C, or the end of the input) ends the session. The command is held between keys and sent on
every tick, so the base's watchdog sees a live operator; it stops the robot when the session ends,
however it ends. Keys come from a ``KeySource``: the terminal in cbreak mode, or any stream (one
key per tick: scripts and tests).

The robot is a backend opened here, or one another process serves as ROS 2 topics
(``open_served``: ``botstage serve robot``, a deployment's robot process with ``topics: true``,
any ROS 2 robot): then teleop is a ``cmd_vel`` publisher like any ROS 2 teleop, and the robot's
own velocity watchdog stops it if teleop goes away without saying stop.
"""

from __future__ import annotations

import os
import select
import sys
import termios
import tty
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Protocol

from botstage.robots.clock import Clock
from botstage.robots.interfaces import Drive, Odometry, OdometryReading

if TYPE_CHECKING:
    pass

HELP = "w/x or up/down: faster forward/back   a/d or left/right: turn left/right   s or space: stop   q: quit"

ARROWS = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left"}
QUIT = {"q", "Q", "\x03", "\x04"}  # q, Ctrl-C, Ctrl-D
TELEOP_INTERFACES = ("drive", "odometry")  # what teleop uses of a served robot: cmd_vel out, odom in


@dataclass
class Teleop:
    """The commanded velocity and how keys change it, within the robot's limits."""

    max_linear: float
    max_angular: float
    linear_step: float = 0.05
    angular_step: float = 0.2
    v: float = 0.0
    w: float = 0.0

    def press(self, key: str) -> bool:
        """Apply one key; False when it ends the session. Unknown keys do nothing."""
        if key in QUIT:
            return False
        if key in ("w", "up"):
            self.v += self.linear_step
        elif key in ("x", "down"):
            self.v -= self.linear_step
        elif key in ("a", "left"):
            self.w += self.angular_step
        elif key in ("d", "right"):
            self.w -= self.angular_step
        elif key in ("s", " "):
            self.v = self.w = 0.0
        self.v = round(max(-self.max_linear, min(self.max_linear, self.v)), 6)
        self.w = round(max(-self.max_angular, min(self.max_angular, self.w)), 6)
        return True


class KeySource(Protocol):
    def read(self) -> list[str]:
        """The keys pressed since the last call (possibly none); never blocks for long."""


def split_keys(text: str) -> list[str]:
    """Characters to keys, arrow escape sequences as ``up``/``down``/``left``/``right``."""
    keys, i = [], 0
    while i < len(text):
        sequence = text[i : i + 3]
        if sequence in ARROWS:
            keys.append(ARROWS[sequence])
            i += 3
        else:
            keys.append(text[i])
            i += 1
    return keys


class StreamKeys:
    """One key per tick from a stream (a pipe, a file, a test's input); its end is ``q``."""

    def __init__(self, stream: IO[str]) -> None:
        self.stream = stream
        self._pending: list[str] = []

    def read(self) -> list[str]:
        if not self._pending:
            chunk = self.stream.read(1)
            if not chunk:
                return ["q"]
            if chunk == "\x1b":
                chunk += self.stream.read(2)
            self._pending = [key for key in split_keys(chunk) if key not in ("\n", "\r")]
        return [self._pending.pop(0)] if self._pending else []


class TerminalKeys:
    """Keys from a terminal in cbreak mode (no Enter needed, no echo), read without waiting."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def read(self) -> list[str]:
        data = b""
        while select.select([self.fd], [], [], 0)[0]:
            chunk = os.read(self.fd, 64)
            if not chunk:
                return ["q"]
            data += chunk
        return split_keys(data.decode("utf-8", "replace"))

    @staticmethod
    @contextmanager
    def opened(stream: IO[str] | None = None) -> Iterator[TerminalKeys]:
        """The terminal on ``stream`` (stdin) in cbreak mode for the block, restored after."""
        fd = (stream or sys.stdin).fileno()
        saved = termios.tcgetattr(fd)
        try:
            tty.setcbreak(fd)
            yield TerminalKeys(fd)
        finally:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def status(v: float, w: float, odometry: OdometryReading | None = None) -> str:
    line = f"v {v:+.2f} m/s  w {w:+.2f} rad/s"
    if odometry is not None:
        pose = odometry.pose
        line += f"  odometry x {pose.x:.2f} y {pose.y:.2f} theta {pose.theta:+.2f}"
    return line


def drive_loop(
    drive: Drive,
    commands: Callable[[], tuple[float, float] | None],
    clock: Clock,
    *,
    step: Callable[[], None] | None = None,
    odometry: Odometry | None = None,
    show: Callable[[str], None] | None = None,
    until: float | None = None,
) -> None:
    """Send ``commands()`` (v, w) every tick until it says None (or ``until`` s of clock time); the
    robot stops at the end, however it ends. Keys and a gesture controller are both such sources."""
    shown = ""
    try:
        while until is None or clock.now() < until - 1e-9:
            command = commands()
            if command is None:
                break
            drive.cmd_vel(*command)  # every tick, so the watchdog knows someone is driving
            if step is not None:
                step()
            if show is not None:
                line = status(*command, odometry.read() if odometry is not None else None)
                if line != shown:
                    show(line)
                    shown = line
            clock.next_tick()
    finally:
        drive.stop()


def run_teleop(
    drive: Drive,
    keys: KeySource,
    clock: Clock,
    state: Teleop,
    *,
    step: Callable[[], None] | None = None,
    odometry: Odometry | None = None,
    show: Callable[[str], None] | None = None,
    until: float | None = None,
) -> Teleop:
    """Drive by keys until quit (or ``until`` seconds of clock time); the robot stops at the end."""

    def commands() -> tuple[float, float] | None:
        if not all(state.press(key) for key in keys.read()):
            return None
        return state.v, state.w

    drive_loop(drive, commands, clock, step=step, odometry=odometry, show=show, until=until)
    return state
