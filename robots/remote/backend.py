"""A robot whose backend runs in another process, as a Backend to the run that uses it.

The robot's process serves its devices and, under the reserved interface name ``@backend``, a
``BackendControl``: the run's after-tick ``step`` (with the mission clock's ticks, so the robot's
clock is the mission's), the true pose, the summary block and the result files. They travel on
the same ordered channel as the device calls, so the world moves exactly between the same reads
as in one process. ``RemoteRobot`` is the run's side: proxies for the devices, ``step`` and the
rest forwarded; ``close`` stops the robot (zero velocity) without ending its process.
"""

from __future__ import annotations

import base64
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from botstage.robots.backend import Backend, Fault
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import Pose2D

CONTROL = "@backend"  # never an interface name (not an identifier)


class BackendControl:
    """What a run does with a backend around its ticks, offered to a run in another process."""

    def __init__(self, backend: Backend, clock: SimClock) -> None:
        self.backend, self.clock = backend, clock

    def step(self, ticks: int) -> None:
        """The mission's tick ``ticks`` has ended: the robot's clock follows it, then the world moves."""
        self.clock.ticks = ticks
        self.backend.step()

    def true_pose(self) -> Pose2D | None:
        return self.backend.true_pose()

    def summary(self) -> dict[str, Any]:
        return self.backend.summary()

    def results(self) -> dict[str, bytes]:
        """The files the backend leaves in a run folder, by name."""
        with tempfile.TemporaryDirectory(prefix="botstage-results-") as folder:
            self.backend.write_results(Path(folder))
            return {path.name: path.read_bytes() for path in sorted(Path(folder).iterdir()) if path.is_file()}

    def faults(self) -> list[str]:
        return sorted(self.backend.faults)

    def inject(self, fault: str, args: list[Any]) -> None:
        self.backend.faults[fault](*args)

    def stop(self) -> None:
        """Zero velocity: the run using it has ended (the process serves on)."""
        drive = self.backend.devices.get("drive")
        if drive is not None:
            drive.stop()


def served_devices(backend: Backend, clock: SimClock) -> dict[str, Any]:
    """What a robot process serves: the backend's devices and its control."""
    return {**backend.devices, CONTROL: BackendControl(backend, clock)}


class RemoteRobot:
    """A Backend whose devices and world are in the robot's process."""

    def __init__(self, proxies: Mapping[str, Any], profile: Any, grid: Any, clock: Any, link: Any = None) -> None:
        self.devices = {name: device for name, device in proxies.items() if name != CONTROL}
        self._control = proxies[CONTROL]
        self.profile, self.grid, self.clock, self.link = profile, grid, clock, link
        self._closed = False

    @property
    def faults(self) -> Mapping[str, Fault]:
        def fault(name: str) -> Fault:
            return lambda *args: self._control.inject(name, list(args))

        return {name: fault(name) for name in self._control.faults()}

    def step(self) -> None:
        self._control.step(self.clock.ticks)

    def use_clock(self, clock: Any) -> None:
        self.clock = clock

    def true_pose(self) -> Pose2D | None:
        return self._control.true_pose()

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._control.stop()

    def summary(self) -> dict[str, Any]:
        return self._control.summary()

    def write_results(self, folder: Path) -> None:
        for name, data in self._control.results().items():
            (folder / Path(name).name).write_bytes(data if isinstance(data, bytes) else base64.b64decode(data))
