"""What a run gives skills beyond the robot's devices: the pose estimate and the navigation stack.

Both are per robot and shared by every skill of the run. The localiser is updated once per
tick, after the world (or the hardware) moved, so every skill in the next tick sees the same
pose; the navigation stack plans on the run's map with that pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from botstage.robots.clock import Clock
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile
from botstage.robots.sim.backend import SimBackend
from botstage.skills.nav.ekf import wrap
from botstage.skills.nav.localization import Localizer
from botstage.skills.nav.stack import NavStack
from botstage.skills.perception.camera_people import CameraPeopleTracker
from botstage.skills.perception.people_tracking import PeopleTracking


@dataclass
class RobotServices:
    interfaces: dict[str, Any] = field(default_factory=dict)
    updates: list[Callable[[], Any]] = field(default_factory=list)
    localizer: Localizer | None = None
    closers: list[Callable[[], Any]] = field(default_factory=list)

    @classmethod
    def for_sim(cls, sim: SimBackend, clock: Clock) -> RobotServices:
        return cls.for_robot(sim.devices, sim.world.grid, sim.world.profile, clock)

    @classmethod
    def for_robot(cls, devices: dict[str, Any], grid: GridMap, profile: Profile, clock: Clock) -> RobotServices:
        """The services for any backend's devices (simulated, emulated or real) on the run's map."""
        services = cls()
        if "odometry" not in devices or "drive" not in devices:
            return services  # a robot that cannot tell where it is does not navigate
        # the run starts where the mission put the robot: the localiser is told so, as an operator
        # (or a dock) tells a real robot; from then on only the devices and the map are used
        localizer = Localizer.for_devices(devices, grid, profile)
        localizer.update()
        services.localizer = localizer
        services.updates.append(localizer.update)
        services.interfaces["localization"] = localizer
        services.interfaces["navigation"] = NavStack.for_robot(profile, devices, grid, clock, localizer.pose)
        if "people" in devices:
            mount = profile.interfaces["people"].pose
            services.interfaces["people_tracking"] = PeopleTracking(devices["people"], localizer.pose, mount, clock)
        elif "camera" in devices:  # a robot with only a camera finds people by their faces
            tracker = CameraPeopleTracker(devices["camera"], simulated=clock.simulated)
            services.closers.append(tracker.close)
            mount = profile.interfaces["camera"].pose
            services.interfaces["people_tracking"] = PeopleTracking(tracker, localizer.pose, mount, clock)
        return services

    def after_step(self, step: Callable[[], None]) -> Callable[[], None]:
        """The tick's last act: move the world, then bring the estimates up to date."""

        def after() -> None:
            step()
            for update in self.updates:
                update()

        return after

    def close(self) -> None:
        for close in self.closers:
            close()

    def summary(self, truth: Pose2D | None = None) -> dict[str, Any]:
        """The localiser's counters and final estimate; with the true pose (simulation), its error."""
        if self.localizer is None:
            return {}
        estimate = self.localizer.estimate()
        pose = estimate.pose
        summary: dict[str, Any] = {
            "source": estimate.source,
            "final_estimate": [round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)],
            **self.localizer.summary(),
        }
        if truth is not None:
            summary["final_error_cm"] = round(math.hypot(pose.x - truth.x, pose.y - truth.y) * 100, 2)
            summary["final_error_deg"] = round(math.degrees(abs(wrap(pose.theta - truth.theta))), 3)
        return summary
