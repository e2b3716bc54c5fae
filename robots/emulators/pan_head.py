"""The face tracker over its emulated servo: the AX-12A on a pty, the camera in the simulator.

What is real is what a user would run: the ``DynamixelServo`` driver (dynamixel-sdk, protocol 1.0)
opens the emulated servo's pty as it would open ``/dev/ttyUSB0``, and the robot's ``pan`` is that
driver. What stands for the hardware is the AX-12A of ``ax12.py`` (the profile's ID, its initial
position at the joint's ``init``) and the simulated world: each pass of the servo's firmware loop
also moves the world and its people over the same ``dt``, under ``world_lock``, as the NyBoard's
and the Launchpad's emulators do. The camera is simulated and rides on the **emulated shaft**: a
frame is rendered along the angle the servo has actually reached, not the goal the driver sent, so
what the tracker sees lags its commands exactly as the servo's motion does.

Like the other emulated robots this runs in real time (the emulator's thread paces the world;
people's cues count from when the backend opened). Closing holds the servo where it is (the
driver's close: goal = present position, torque on), then unplugs the emulator.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from botstage.robots.backend import Fault, ScriptedWalk
from botstage.robots.clock import Clock
from botstage.robots.drivers.pan_head import pan_joint, servo_for
from botstage.robots.emulators.ax12 import Ax12Emulator
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, ServoJoint
from botstage.robots.sim.backend import populated_world
from botstage.robots.sim.devices import SimCamera
from botstage.robots.sim.trajectory import Trajectory
from botstage.robots.sim.world import World


class PanHeadEmulator(Ax12Emulator):
    """The AX-12A whose firmware loop also moves the simulated world (see the module)."""

    def __init__(
        self,
        world: World,
        joint: ServoJoint,
        *,
        world_lock: threading.Lock | None = None,
        extra_steps: list[Callable[[float], None]] | None = None,
        **options: Any,
    ) -> None:
        super().__init__(dxl_id=joint.id, position=joint.init, **options)
        self.world = world
        self.world_lock = world_lock or threading.Lock()
        self.extra_steps = list(extra_steps or [])

    def _loop(self, now: float, dt: float) -> None:
        super()._loop(now, dt)  # the shaft first, under the servo's own lock
        if dt > 0:
            with self.world_lock:
                self.world.step(dt)
                for step in self.extra_steps:
                    step(dt)


class _LockedCamera:
    """The simulated camera, rendered while the emulator's thread may be stepping the world."""

    def __init__(self, camera: SimCamera, lock: threading.Lock) -> None:
        self.camera = camera
        self.info = camera.info
        self.lock = lock

    def frame(self) -> np.ndarray:
        with self.lock:
            return self.camera.frame()


class PanHeadEmulatorBackend:
    """The ``emulator`` backend for a robot whose only moving part is a Dynamixel pan (the face tracker)."""

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
        *,
        servo_options: Mapping[str, Any] | None = None,
        **emulator_options: Any,
    ) -> None:
        joint = pan_joint(profile)
        if joint is None:
            raise ValueError(f"robot {profile.name!r} has no pan on a Dynamixel servo to emulate")
        if emulator_options.pop("counter_start", 0):
            raise ValueError("counter_start is the Launchpad's encoders' first count: this robot has none")
        self.clock = clock
        self.lock = threading.Lock()
        self.world, self.crowd = populated_world(profile, grid, start, seed, people, gatherings, walks)
        steps = [self.crowd.step] if self.crowd.people else []
        self.emulator = PanHeadEmulator(self.world, joint, world_lock=self.lock, extra_steps=steps, **emulator_options)
        self.emulator.start()
        self.servo = servo_for(profile, self.emulator.path, **dict(servo_options or {}))
        try:
            if not self.servo.open():
                raise ConnectionError(f"the emulated AX-12A on {self.emulator.path} does not answer")
        except Exception:
            self.servo.close()
            self.emulator.close()
            raise
        self.devices: dict[str, Any] = {"pan": self.servo}
        camera = profile.interfaces.get("camera")
        if camera is not None:
            emulator = self.emulator
            angle = (lambda: emulator.angle) if camera.mounted_on == "pan" else None
            self.devices["camera"] = _LockedCamera(
                SimCamera(self.world, self.crowd, camera, clock, pan=angle), self.lock
            )
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
        """The servo's line and body faults, as ``botstage emulate`` types them."""
        emulator = self.emulator
        return {
            "garbage": emulator.inject_garbage,
            "drop": emulator.drop_replies,
            "corrupt": emulator.corrupt_replies,
            "cut": emulator.cut_replies,
            "unplug": emulator.disconnect,
            "reset": emulator.power_cycle,
            "overload": emulator.overload,
        }

    def true_pose(self) -> Pose2D:
        with self.lock:
            return self.world.body.pose

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with this clock from now on (the run's, started once the robot is up)."""
        self.clock = clock
        camera = self.devices.get("camera")
        if isinstance(camera, _LockedCamera):
            camera.camera.clock = clock

    def step(self) -> None:
        """The world moves by itself (the emulator's thread): only the true path is recorded."""
        with self.lock:
            self.trajectory.add(self.world.time, self.world.body.pose)

    def close(self) -> None:
        try:
            self.servo.close()  # held where it is, torque on, through the pty
        finally:
            self.emulator.close()

    def write_results(self, folder: Path) -> None:
        self.trajectory.write(folder / "trajectory.csv")

    def summary(self) -> dict[str, Any]:
        with self.lock:
            people = len(self.crowd.people)
        return {
            "people": people,
            "not_simulated": self.not_simulated,
            "pan": {"final_angle": round(self.emulator.angle, 5), "held_on_close": self.servo.held_on_close},
            "servo": self.servo.stats(),
            "board": dict(sorted(self.emulator.counters.items())),
        }
