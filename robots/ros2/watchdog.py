"""The drive's velocity watchdog of a robot process: no command for a while, and the robot stops.

A robot served over ROS 2 is driven by whoever publishes ``cmd_vel``: a mission in another
process, teleop, a navigation stack. If that process dies or the network breaks, nobody sends the
zero. The watchdog, in the robot process, stops the drive when no command came for ``timeout_s``
(the profile's ``control.watchdog_s``, 0.5 s by default), and records each trip: the stamp of the
last command and of the stop, both on the robot process's clock. It trips once per silence; the
next command re-arms it.

Commands are noted on Zenoh's threads and checked on the robot's loop: the state is behind a lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Trip:
    """One stop for silence: when the last command came and when the drive was stopped (s, server clock)."""

    last_command: float
    stopped_at: float

    @property
    def silence(self) -> float:
        return self.stopped_at - self.last_command


class VelocityWatchdog:
    def __init__(self, timeout_s: float = 0.5) -> None:
        if not timeout_s > 0:
            raise ValueError(f"a watchdog timeout must be positive, got {timeout_s!r}")
        self.timeout_s = timeout_s
        self.trips: list[Trip] = []
        self._lock = threading.Lock()
        self._last: float | None = None  # the last command's stamp while armed

    def commanded(self, at: float) -> None:
        """A velocity command arrived at ``at``: (re-)arm."""
        with self._lock:
            self._last = at

    @property
    def last_command(self) -> float | None:
        with self._lock:
            return self._last

    def due(self) -> float | None:
        """When it will trip if no command comes (None while disarmed)."""
        with self._lock:
            return None if self._last is None else self._last + self.timeout_s

    def check(self, now: float) -> Trip | None:
        """A trip if the last command is more than ``timeout_s`` old at ``now`` (then disarmed), else None."""
        with self._lock:
            if self._last is None or now - self._last <= self.timeout_s:
                return None
            trip = Trip(self._last, now)
            self._last = None
        self.trips.append(trip)
        return trip
