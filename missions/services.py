"""What a run gives skills beyond the robot's devices: the pose estimate and the navigation stack.

Both are per robot and shared by every skill of the run. The localiser is updated once per
tick, after the world (or the hardware) moved, so every skill in the next tick sees the same
pose; the navigation stack plans on the run's map with that pose.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robots.clock import Clock
from robots.interfaces import Pose2D
from robots.sim.backend import SimBackend
from skills.nav.stack import NavStack


@dataclass
class RobotServices:
    interfaces: dict[str, Any] = field(default_factory=dict)
    updates: list[Callable[[], None]] = field(default_factory=list)

    @classmethod
    def for_sim(cls, sim: SimBackend, clock: Clock) -> RobotServices:
        services = cls()
        devices = sim.devices
        if "odometry" not in devices or "drive" not in devices:
            return services  # a robot that cannot tell where it is does not navigate
        odometry = devices["odometry"]

        def pose() -> Pose2D:
            return odometry.read().pose

        services.interfaces["navigation"] = NavStack.for_robot(sim.world.profile, devices, sim.world.grid, clock, pose)
        return services

    def after_step(self, step: Callable[[], None]) -> Callable[[], None]:
        """The tick's last act: move the world, then bring the estimates up to date."""

        def after() -> None:
            step()
            for update in self.updates:
                update()

        return after
