"""The simulator as a backend: a world and the devices for the interfaces a profile lists."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from botstage.robots.backend import Fault, ScriptedWalk
from botstage.robots.clock import Clock
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile
from botstage.robots.sim.devices import (
    SimBattery,
    SimCamera,
    SimDisplay,
    SimDrive,
    SimGaitDrive,
    SimGaitOdometry,
    SimImu,
    SimLaser,
    SimMicrophone,
    SimOdometry,
    SimPan,
    SimPeopleTracker,
    SimSonar,
    SimSpeaker,
)
from botstage.robots.sim.people import PERSON_RADIUS, Crowd
from botstage.robots.sim.trajectory import Trajectory
from botstage.robots.sim.voices import Voices
from botstage.robots.sim.world import Bump, World

WHEEL_SLIP = 0.02  # the World's default: wheels on a hard floor
LEGGED_SLIP = 0.05  # decision: feet slip and gaits vary step to step more than wheels


def populated_world(
    profile: Profile,
    grid: GridMap,
    start: Pose2D,
    seed: int,
    people: int = 0,
    gatherings: list[tuple[float, tuple[float, float], int, float]] | None = None,
    walks: list[ScriptedWalk] | None = None,
) -> tuple[World, Crowd]:
    """The robot's world and the people in it, wired together: people are laser returns and
    obstacles, and keep clear of the robot themselves. ``gatherings``: (time, centre, size, stay);
    ``walks``: people who walk a given path (after the others: their ids follow)."""
    legged = profile.base.kind == "legged"
    world = World(grid, profile, start, seed, slip_std=LEGGED_SLIP if legged else WHEEL_SLIP)
    crowd = Crowd.populate(grid, world.rng, people, avoid=(start.x, start.y))
    crowd.scripted = sorted(gatherings or [])
    for walk in walks or []:
        crowd.add_walk(walk)
    world.movers = crowd.positions
    world.mover_radius = PERSON_RADIUS
    crowd.robot = lambda: (world.body.pose.x, world.body.pose.y)
    crowd.robot_radius = profile.base.footprint_radius
    return world, crowd


def write_bumps(bumps: list[Bump], path: Path) -> None:
    """bumps.csv: one row per contact event (t, x, y, what), for the report's map."""
    lines = ["t,x,y,what"] + [f"{b.t:.6g},{b.x:.6f},{b.y:.6f},{b.what}" for b in bumps]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


class SimBackend:
    """The ``sim`` backend: every interface the profile lists that the simulator has a device for."""

    def __init__(
        self,
        profile: Profile,
        grid: GridMap,
        start: Pose2D,
        seed: int,
        clock: Clock,
        people: int = 0,
        gatherings: list[tuple[float, tuple[float, float], int, float]] | None = None,
        voices: dict[str, Any] | None = None,
        walks: list[ScriptedWalk] | None = None,
    ) -> None:
        self.clock = clock
        self.world, self.crowd = populated_world(profile, grid, start, seed, people, gatherings, walks)
        self.devices: dict[str, Any] = {}
        self.not_simulated: list[str] = []
        gaits = profile.gaits
        walker = SimGaitDrive(self.world, gaits) if gaits is not None else None  # a legged base walks in gaits
        pan_spec = profile.interfaces.get("pan")
        pan = SimPan(self.world, pan_spec.joint) if pan_spec is not None and pan_spec.joint is not None else None
        makers = {
            "drive": lambda d: walker or SimDrive(self.world),
            "odometry": lambda d: SimGaitOdometry(walker, clock) if walker else SimOdometry(self.world, clock),
            "imu": lambda d: SimImu(self.world, clock),
            "laser": lambda d: SimLaser(self.world, d, clock),
            "sonar": lambda d: SimSonar(self.world, d, clock),
            "battery": lambda d: SimBattery(self.world, clock),
            "speaker": lambda d: SimSpeaker(clock),
            "display": lambda d: SimDisplay(clock),
            "people": lambda d: SimPeopleTracker(self.world, self.crowd, d, clock),
            "camera": lambda d: SimCamera(
                self.world, self.crowd, d, clock, pan=_angle_of(pan) if d.mounted_on == "pan" else None
            ),
            "pan": lambda d: pan,
            "microphone": lambda d: SimMicrophone(self.world, clock),
        }
        for name, device in profile.interfaces.items():
            if name in makers:
                self.devices[name] = makers[name](device)
            else:
                self.not_simulated.append(name)  # an interface the simulator has no device for
        self.trajectory = Trajectory(start)
        # people near the robot speak into its microphone (robots/sim/voices.py)
        microphone = self.devices.get("microphone")
        speaker = self.devices.get("speaker")
        self.voices = (
            Voices.for_world(self.world, self.crowd, microphone, speaker, **(voices or {}))
            if microphone is not None
            else None
        )

    @property
    def profile(self) -> Profile:
        return self.world.profile

    @property
    def grid(self) -> GridMap:
        return self.world.grid

    @property
    def faults(self) -> Mapping[str, Fault]:
        """None yet: a simulated robot's troubles come from its world (bumps, slip, a draining battery)."""
        return MappingProxyType({})

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with this clock from now on."""
        self.clock = clock
        for device in self.devices.values():
            if hasattr(device, "use_clock"):
                device.use_clock(clock)
            elif hasattr(device, "clock"):
                device.clock = clock

    def true_pose(self) -> Pose2D:
        return self.world.body.pose

    def step(self) -> None:
        self.world.step(self.clock.period)
        self.crowd.step(self.clock.period)
        if self.voices is not None:
            self.voices.step(self.clock.now())
        pose = self.world.body.pose
        self.trajectory.add(self.world.time, pose)

    def close(self) -> None:
        self.world.stop()  # zero velocity on every exit path
        pan = self.devices.get("pan")
        if isinstance(pan, SimPan):
            pan.hold()  # the servo stays where it is, as the driver's close holds it

    def write_results(self, folder: Path) -> None:
        self.trajectory.write(folder / "trajectory.csv")
        write_bumps(self.world.body.bump_log, folder / "bumps.csv")

    def summary(self) -> dict[str, Any]:
        """The sim block of summary.json. ``bumps`` counts contact events (entering contact with
        a wall or a person; pushing on is the same bump), split into ``bumps_walls`` and
        ``bumps_people``; ``bump_ticks`` counts the steps spent in contact; bumps.csv says where."""
        distance = self.trajectory.distance()
        body = self.world.body
        final = body.pose
        return {
            "distance_m": round(distance, 4),
            "final_pose": [round(final.x, 4), round(final.y, 4), round(final.theta, 4)],
            "bumps": body.bumps,
            "bumps_walls": body.wall_bumps,
            "bumps_people": body.person_bumps,
            "bump_ticks": body.contact_steps,
            "people": len(self.crowd.people),
            "utterances": len(self.voices.spoken) if self.voices is not None else 0,
            "battery_percent": round(self.world.battery_percent, 3) if self.profile.battery is not None else None,
            "not_simulated": self.not_simulated,
            **pan_summary(self.devices.get("pan")),
        }


def _angle_of(pan: SimPan | None) -> Callable[[], float]:
    """What a camera on the pan reads its angle from (the shaft, exactly)."""
    if pan is None:
        raise ValueError("a camera mounted on the pan needs a pan")
    return lambda: pan.angle


def pan_summary(pan: Any) -> dict[str, Any]:
    """The pan's block of summary.json: where it ended and how often it was told to move."""
    if not isinstance(pan, SimPan):
        return {}
    return {"pan": {"final_angle": round(pan.angle, 5), "commands": pan.commands, "clamped": pan.clamped}}
