"""A real robot as a run's backend: its hardware drivers on a serial port, giving the devices
for the interfaces the profile assigns to them (the same ``devices`` dict the simulator gives).

The board that drives the base is chosen by the drive's ``hardware:`` in the profile: the
Chefbot's Launchpad (``launchpad``) or Bittle's NyBoard (``nyboard``). An interface whose driver
does not exist yet (the Chefbot's depth camera, ``hardware: astra``) is listed in
``not_connected`` and left out.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from botstage.robots.backend import Fault
from botstage.robots.clock import Clock
from botstage.robots.drivers.bittle_base import NYBOARD, open_bittle
from botstage.robots.drivers.chefbot_base import LAUNCHPAD, open_chefbot
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile

DRIVERS: dict[str, Callable[..., Any]] = {LAUNCHPAD: open_chefbot, NYBOARD: open_bittle}  # board -> opener
BOARD_NAMES = {LAUNCHPAD: "Launchpad", NYBOARD: "NyBoard"}


def board_of(profile: Profile) -> str | None:
    """The board a driver here knows that drives the profile's base, if any."""
    drive = profile.interfaces.get("drive")
    return drive.hardware if drive is not None and drive.hardware in DRIVERS else None


def drivable(profile: Profile) -> bool:
    """True when a driver here provides the profile's drive."""
    return board_of(profile) is not None


class SerialBackend:
    """The Launchpad on ``port``; the robot starts at ``start`` (its odometry's origin, as an
    operator or a dock tells a real robot where it is)."""

    def __init__(
        self,
        profile: Profile,
        clock: Clock,
        port: str,
        start: Pose2D,
        *,
        grid: GridMap | None = None,
        ready_timeout: float = 5.0,
        **options: Any,
    ) -> None:
        board = board_of(profile)
        if board is None:
            raise ValueError(f"no hardware driver for robot {profile.name!r} yet (drivers: {', '.join(DRIVERS)})")
        self.profile = profile
        self.grid = grid  # the map of where the robot is, for localisation and navigation
        self.port = port
        self.board = board
        self.base = DRIVERS[board](port, profile, clock, start, **options)
        if not self.base.wait_ready(ready_timeout):
            stats = self.base.link.stats()
            self.base.close()
            raise ConnectionError(
                f"no readings from the {BOARD_NAMES[board]} on {port} within {ready_timeout:g} s "
                f"(connected: {stats['connected']}, lines parsed: {sum(stats['lines_ok'].values())})"
            )
        self.devices: dict[str, Any] = dict(self.base.devices)
        self.not_connected = sorted(set(profile.interfaces) - set(self.devices))

    @property
    def faults(self) -> Mapping[str, Fault]:
        """None: faults are not injected into a real robot."""
        return MappingProxyType({})

    def true_pose(self) -> None:
        """A real robot's true pose is unknown (its odometry is in the summary)."""
        return None

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with this clock from now on (the run's, started once the robot is up)."""
        self.base.clock = clock

    def step(self) -> None:
        """Nothing to move: the robot moves itself; readings arrive on the reader thread."""

    def close(self) -> None:
        self.base.close()  # zero speed, then the port

    def write_results(self, folder: Path) -> None:
        """A real robot's true path is unknown: no trajectory.csv (odometry is in the summary)."""

    def summary(self) -> dict[str, Any]:
        return {**self.base.summary(), "not_connected": self.not_connected}
