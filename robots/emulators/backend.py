"""A robot over its emulated board: the whole byte path of a real robot, in simulation.

The board that drives the profile's base is emulated (the Chefbot's Launchpad, Bittle's
NyBoard): it plays the firmware on a pty and moves the simulated world in its own thread, in
real time; the real driver (``SerialBackend``) connects to the pty, and the devices the profile
gives the board come from it. Interfaces on other hardware (the Chefbot's depth camera's scan,
the camera on Bittle's Raspberry Pi) come from the same simulated world, read under the
emulator's lock. ``step()`` only records the
true path for the report: the world moves by itself.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from botstage.robots.backend import Fault, ScriptedWalk
from botstage.robots.clock import Clock
from botstage.robots.drivers.backend import SerialBackend, board_of
from botstage.robots.drivers.bittle_base import NYBOARD
from botstage.robots.drivers.chefbot_base import LAUNCHPAD
from botstage.robots.emulators.launchpad import LaunchpadEmulator
from botstage.robots.emulators.nyboard import NyBoardEmulator
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import LaserScan, Pose2D
from botstage.robots.profile import Profile
from botstage.robots.sim.backend import populated_world
from botstage.robots.sim.devices import SimCamera, SimLaser, SimMicrophone, SimSpeaker
from botstage.robots.sim.trajectory import Trajectory
from botstage.robots.sim.voices import Voices


class _LockedLaser:
    """The simulated laser, read while the emulator's thread may be stepping the world."""

    def __init__(self, laser: SimLaser, lock: threading.Lock) -> None:
        self.laser = laser
        self.lock = lock

    def scan(self) -> LaserScan:
        with self.lock:
            return self.laser.scan()


class _LockedCamera:
    """The simulated camera, rendered while the emulator's thread may be stepping the world."""

    def __init__(self, camera: SimCamera, lock: threading.Lock) -> None:
        self.camera = camera
        self.info = camera.info
        self.lock = lock

    def frame(self) -> np.ndarray:
        with self.lock:
            return self.camera.frame()


EMULATORS: dict[str, type[LaunchpadEmulator] | type[NyBoardEmulator]] = {
    LAUNCHPAD: LaunchpadEmulator,
    NYBOARD: NyBoardEmulator,
}


class EmulatorBackend:
    """The ``emulator`` backend: the real driver's devices, over the emulated board, on a simulated robot."""

    def __init__(
        self,
        profile: Profile,
        grid: GridMap,
        start: Pose2D,
        seed: int,
        clock: Clock,
        people: int = 0,
        gatherings: list[tuple[float, tuple[float, float], int, float]] | None = None,
        walks: list[ScriptedWalk] | None = None,
        **emulator_options: Any,
    ) -> None:
        self.clock = clock
        self.lock = threading.Lock()
        self.world, self.crowd = populated_world(profile, grid, start, seed, people, gatherings, walks)
        steps = [self.crowd.step] if self.crowd.people else []
        board = board_of(profile)
        if board is None:
            raise ValueError(f"no emulated board drives robot {profile.name!r} (boards: {', '.join(EMULATORS)})")
        if board != LAUNCHPAD and emulator_options.pop("counter_start", 0):
            raise ValueError("counter_start is the Launchpad's encoders' first count: this robot has none")
        self.emulator = EMULATORS[board](self.world, world_lock=self.lock, extra_steps=steps, **emulator_options)
        self.emulator.start()
        try:
            self.serial = SerialBackend(profile, clock, self.emulator.path, start)
        except Exception:
            self.emulator.close()
            raise
        self.devices: dict[str, Any] = dict(self.serial.devices)
        if "laser" in profile.interfaces and "laser" not in self.devices:
            self.devices["laser"] = _LockedLaser(SimLaser(self.world, profile.interfaces["laser"], clock), self.lock)
        if "camera" in profile.interfaces and "camera" not in self.devices:  # the robot PC's camera
            camera = SimCamera(self.world, self.crowd, profile.interfaces["camera"], clock)
            self.devices["camera"] = _LockedCamera(camera, self.lock)
        # the speaker and microphone are the robot's PC's, not the board's: simulated, with the
        # simulator's voices (seated guests answer the robot's questions)
        self.voices: Voices | None = None
        if "speaker" in profile.interfaces:
            self.devices["speaker"] = SimSpeaker(clock)
        if "microphone" in profile.interfaces:
            self.devices["microphone"] = microphone = SimMicrophone(self.world, clock)
            self.voices = Voices.for_world(self.world, self.crowd, microphone, self.devices.get("speaker"))
        self.not_simulated = sorted(set(profile.interfaces) - set(self.devices))
        self.trajectory = Trajectory(start)

    @property
    def profile(self) -> Profile:
        return self.world.profile

    @property
    def grid(self) -> GridMap:
        return self.world.grid

    @property
    def faults(self) -> Mapping[str, Fault]:
        """The board's faults, as ``botstage emulate`` types them: garbage, drop, stall, unplug, reset."""
        emulator = self.emulator
        faults: dict[str, Fault] = {
            "garbage": emulator.inject_garbage,
            "drop": emulator.drop_lines,
            "unplug": emulator.disconnect,
            "reset": emulator.board_reset,
        }
        if isinstance(emulator, LaunchpadEmulator):
            faults["stall"] = emulator.stall
        return faults

    def true_pose(self) -> Pose2D:
        with self.lock:
            return self.world.body.pose

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with this clock from now on (the run's, started once the robot is up)."""
        self.clock = clock
        self.serial.use_clock(clock)
        laser = self.devices.get("laser")
        if isinstance(laser, _LockedLaser):
            laser.laser.clock = clock
        camera = self.devices.get("camera")
        if isinstance(camera, _LockedCamera):
            camera.camera.clock = clock
        speaker, microphone = self.devices.get("speaker"), self.devices.get("microphone")
        if isinstance(speaker, SimSpeaker):
            speaker.clock = clock
        if isinstance(microphone, SimMicrophone):
            microphone.use_clock(clock)

    def step(self) -> None:
        with self.lock:
            pose = self.world.body.pose
            self.trajectory.add(self.world.time, pose)
            if self.voices is not None:
                self.voices.step(self.clock.now())

    def close(self) -> None:
        try:
            self.serial.close()  # zero speed first, through the pty
        finally:
            self.emulator.close()

    def write_results(self, folder: Path) -> None:
        self.trajectory.write(folder / "trajectory.csv")

    def summary(self) -> dict[str, Any]:
        distance = self.trajectory.distance()
        with self.lock:
            final = self.world.body.pose
            world = {
                "distance_m": round(distance, 4),
                "final_pose": [round(final.x, 4), round(final.y, 4), round(final.theta, 4)],
                "bumps": self.world.body.bumps,
                "people": len(self.crowd.people),
                "battery_percent": round(self.world.battery_percent, 3),
                "not_simulated": self.not_simulated,
            }
        return {
            **world,
            "serial": self.serial.summary(),
            "board": dict(sorted(self.emulator.counters.items())),
        }
