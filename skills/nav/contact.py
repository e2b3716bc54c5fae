"""Noticing contact: the robot is told to move and its odometry says it does not.

Most robots here have no bumper (the PeopleBot has no sensor at its back, Chefbot none at all),
so a skill that drives learns it touched something from its wheels: in contact they stop, or
spin without the body moving. The watch compares the motion commanded with the headway the
odometry shows over a short window and says so once there was none, so that the skill stops at
the first contact instead of pushing every tick until its timeout.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from botstage.robots.clock import Clock
from botstage.robots.interfaces import Pose2D

MOVING_SPEED = 0.02  # m/s: a command at least this fast is expected to move the robot
MOVING_TURN = 0.1  # rad/s
STALL_SPEED = 0.01  # m/s: headway slower than this over the window is none
STALL_TURN = 0.05  # rad/s
WINDOW = 0.2  # s without headway that make a contact (2 ticks at 10 Hz: one may bring no reading)
GRACE = 0.3  # s after a motion starts (or turns round) before its headway is judged: the wheels speed up


class ContactWatch:
    """Call ``check`` once a tick before commanding and ``commanded`` with what was commanded."""

    def __init__(self, pose: Callable[[], Pose2D], clock: Clock, window: float = WINDOW, grace: float = GRACE) -> None:
        self._pose = pose
        self.clock = clock
        self.window = window
        self.grace = grace
        self._command = (0.0, 0.0)
        self._since: float | None = None  # when the current motion started
        self._history: deque[tuple[float, Pose2D, tuple[float, float]]] = deque()

    @classmethod
    def for_robot(cls, interfaces: Mapping[str, Any], clock: Clock) -> ContactWatch | None:
        """A watch on the robot's odometry: its wheels, not the localiser's estimate, which a
        map correction may move back while the robot creeps forward; None without odometry, or
        when the odometry is reckoned from the commands (``measured = False``), not measured."""
        odometry = interfaces.get("odometry")
        if odometry is None:
            navigation = interfaces.get("navigation")
            odometry = getattr(navigation, "odometry", None)
        if odometry is None or getattr(odometry, "measured", True) is False:
            return None  # odometry from the commands themselves (a legged robot's gaits) shows no contact
        return cls(lambda: odometry.read().pose, clock)

    @property
    def last_command(self) -> tuple[float, float]:
        return self._command

    def commanded(self, v: float, w: float) -> None:
        """What the skill told the drive this tick (0, 0 for a stop)."""
        before = self._command
        moving = _moving(v, w)
        if not moving:
            self._since = None
        elif self._since is None or not _moving(*before) or v * before[0] < 0 or w * before[1] < 0:
            self._since = self.clock.now()  # from rest, or turned round: the wheels need time
        self._command = (v, w)

    def check(self) -> str | None:
        """A reason when the motion commanded over the last ``window`` seconds made no headway."""
        now, pose = self.clock.now(), self._pose()
        history = self._history
        if history and history[-1][0] == now:
            history.pop()  # asked twice in a tick: the last reading counts
        history.append((now, pose, self._command))
        while len(history) > 1 and history[1][0] <= now - self.window:
            history.popleft()
        then, before, _ = history[0]
        if self._since is None or now - self._since < self.grace or now - then < self.window - 1e-9:
            return None
        # each reading holds the command given before it: the first one's came before the window
        commands = [command for _, _, command in history][1:]
        if not commands or not all(_moving(*command) for command in commands):
            return None
        elapsed = now - then
        speed = math.hypot(pose.x - before.x, pose.y - before.y) / elapsed
        turn = abs(math.remainder(pose.theta - before.theta, math.tau)) / elapsed
        if speed >= STALL_SPEED or turn >= STALL_TURN:  # any headway: moving on, or turning
            return None
        v, w = self._command
        return f"no headway for {elapsed:.1f} s while driving at {v:.2f} m/s, {w:.2f} rad/s: in contact with something"


def _moving(v: float, w: float) -> bool:
    return abs(v) >= MOVING_SPEED or abs(w) >= MOVING_TURN


def touched(command: tuple[float, float], radius: float) -> np.ndarray:
    """Where, in the base frame, a robot that stalled under ``command`` most likely touched
    something: at its edge in the direction it drove (none known for a turn in place)."""
    v, _ = command
    if abs(v) < MOVING_SPEED:
        return np.empty((0, 2))
    return np.array([[math.copysign(radius + 0.05, v), 0.0]])
