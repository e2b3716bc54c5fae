"""The emulated Launchpad on a real pty, the real driver connected to it, the simulated Chefbot moving.

Bytes really cross the pty and the emulated board moves its world in real time, so nothing here
is measured against the clock: a drive lasts until the simulated robot has gone far enough, a
check waits for the driver to have handled the board's next lines (an event), and the only
deadlines are failsafes. The firmware's schedule is checked on the emulator's own injectable
clock. Distances are compared with tolerances.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from botstage.missions.runner import RunError, run
from botstage.robots.clock import WallClock
from botstage.robots.drivers.launchpad_protocol import LineDecoder
from botstage.robots.emulators.backend import EmulatorBackend
from botstage.robots.emulators.launchpad import LaunchpadEmulator
from botstage.robots.gridmap import load as load_map
from botstage.robots.gridmap import map_path
from botstage.robots.interfaces import Pose2D, check_interfaces
from botstage.robots.sim.backend import populated_world
from tests.launchpad_helpers import FAILSAFE_S, Delivered, chefbot, wait_until

ROOT = Path(__file__).resolve().parent.parent
PROFILE = chefbot()
GRID = load_map(map_path("restaurant"))  # type: ignore[arg-type]
OPEN_FLOOR = Pose2D(10.0, 7.0, 0.0)


@dataclass
class Rig:
    """The backend, and what its driver has handled."""

    robot: EmulatorBackend
    delivered: Delivered

    @property
    def body(self):
        return self.robot.world.body


def backend(start: Pose2D = OPEN_FLOOR, **options) -> Rig:
    robot = EmulatorBackend(PROFILE, GRID, start, 1, WallClock(10), **options)
    return Rig(robot, Delivered(robot.serial.base.link))


@pytest.fixture
def rig() -> Iterator[Rig]:
    made = backend()
    yield made
    made.robot.close()


def travelled(rig: Rig, at_least: float) -> Callable[[], bool]:
    """True once the simulated robot is ``at_least`` metres from where it was asked."""
    with rig.robot.lock:
        start = rig.body.pose
    return lambda: math.hypot(rig.body.pose.x - start.x, rig.body.pose.y - start.y) >= at_least


def drive(rig: Rig, v: float, w: float, until: Callable[[], bool]) -> None:
    """Command as a mission's skill does, every fifth board loop, until ``until`` holds; then stop
    and settle."""
    deadline = time.monotonic() + FAILSAFE_S
    command = rig.robot.devices["drive"]
    while not until():
        assert time.monotonic() < deadline, "the robot never got there"
        command.cmd_vel(v, w)
        rig.delivered.more("Encoders", 5, timeout=0.2)  # well inside the driver's 0.5 s watchdog
    settle(rig)


def settle(rig: Rig) -> None:
    """Stop; wait until the wheels stand, then until the driver has handled the board's lines of
    later loops (the final counters and heading)."""
    rig.robot.devices["drive"].stop()
    body = rig.body
    assert wait_until(lambda: body.left.speed == 0 and body.right.speed == 0)
    assert rig.delivered.more("Encoders", 2)
    assert rig.delivered.more("Quaternion", 2)


def assert_odometry_agrees(rig: Rig, cm: float = 3.0, degrees: float = 2.0) -> None:
    with rig.robot.lock:
        truth = rig.body.pose
    pose = rig.robot.devices["odometry"].read().pose
    assert math.hypot(pose.x - truth.x, pose.y - truth.y) < cm / 100, (pose, truth)
    assert abs(math.remainder(pose.theta - truth.theta, 2 * math.pi)) < math.radians(degrees), (pose, truth)


def test_a_short_drive_moves_the_simulated_robot_and_odometry_agrees(rig: Rig) -> None:
    robot = rig.robot
    assert check_interfaces(robot.devices) == []
    # the board's five, the depth scan, and the PC's speaker and microphone (simulated beside it)
    assert set(robot.devices) == {"drive", "odometry", "imu", "sonar", "battery", "laser", "speaker", "microphone"}
    assert robot.not_simulated == []
    drive(rig, 0.25, 0.4, until=travelled(rig, 0.5))
    assert rig.body.pose.theta > 0.6  # it turned left as it went (0.8 rad on a 0.625 m radius)
    assert_odometry_agrees(rig)
    assert robot.devices["imu"].read().yaw == pytest.approx(robot.world.imu_yaw, abs=0.01)
    assert robot.devices["battery"].read().percent > 99
    stats = robot.serial.summary()
    assert stats["lines_bad"] == {} and stats["connects"] == 1
    ok = stats["lines_ok"]  # every kind of line the firmware prints got through
    assert set(ok) == {"BoardTime", "Encoders", "Ultrasonic", "MotorSpeeds", "Quaternion", "BatteryVolts"}
    assert abs(ok["Encoders"] - ok["BoardTime"]) <= 1  # printed together: one loop may be half read


def test_the_firmware_prints_each_reading_at_its_rate() -> None:
    """One loop at a time, on the emulator's own clock: 2 s of the firmware's output."""
    world, _ = populated_world(PROFILE, GRID, OPEN_FLOOR, 1)
    now = [100.0]
    emulator = LaunchpadEmulator(world, monotonic=lambda: now[0])
    emulator.replug()
    board = os.open(emulator.path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    decoder = LineDecoder()
    try:
        for k in range(101):  # 50 Hz
            now[0] = 100.0 + k / 50
            emulator._loop(now[0], 0.02)
            decoder.feed(os.read(board, 65536))
    finally:
        os.close(board)
        emulator.close()
    ok = decoder.ok
    assert decoder.bad == {}
    assert ok["Encoders"] == ok["BoardTime"] == ok["MotorSpeeds"] == 101  # every loop
    assert ok["Quaternion"] == pytest.approx(2 * 20 + 1, abs=1)  # the profile's IMU rate
    assert ok["Ultrasonic"] == pytest.approx(2 * 10 + 1, abs=1)  # the profile's sonar rate
    assert ok["BatteryVolts"] == 3  # once a second: at 0, 1 and 2 s


def test_garbage_and_dropped_lines_leave_the_good_ones(rig: Rig) -> None:
    robot = rig.robot
    link = robot.serial.base.link
    robot.emulator.inject_garbage(20_000)
    robot.emulator.drop_lines(200)
    assert wait_until(lambda: robot.emulator.counters["lines_dropped"] == 200)
    drive(rig, 0.2, 0.0, until=travelled(rig, 0.3))
    assert link.decoder.lines_bad > 0  # the garbage reached the driver before the last lines did
    assert link.counters["listener_errors"] == 0
    assert_odometry_agrees(rig)


def test_a_stalled_wheel_saturates_its_motor_and_odometry_follows_the_encoders(rig: Rig) -> None:
    robot = rig.robot
    robot.emulator.stall("left")
    drive(rig, 0.2, 0.0, until=lambda: rig.body.right.ticks > 2000)
    body = rig.body
    assert abs(body.left.ticks) <= 1  # the left wheel never turned
    assert robot.serial.base.controllers[0].integral * PROFILE.control.pid.ki <= 2 * 255 + 1e-6
    assert_odometry_agrees(rig)  # it pivoted about the stalled wheel, and odometry saw it
    assert body.pose.theta > 0.3  # 2000 ticks of the right wheel about the left: 0.42 rad


def test_unplug_and_replug_through_the_emulator(rig: Rig) -> None:
    robot = rig.robot
    link, emulator = robot.serial.base.link, robot.emulator
    drive_device = robot.devices["drive"]
    drive_device.cmd_vel(0.2, 0.0)
    assert wait_until(lambda: emulator.speeds != (0, 0))
    emulator.unplug()
    assert rig.delivered.reached("disconnect", 1)
    # the board keeps its last speeds while unplugged (the book's firmware has no watchdog)...
    assert emulator.speeds != (0, 0)
    emulator.replug()
    assert rig.delivered.reached("connect", 1)
    # ...and the driver's first words on the new link are zero
    assert emulator.first_speeds[-1] == (0, 0)
    assert wait_until(lambda: emulator.speeds == (0, 0))
    assert link.counters["connects"] == 2 and link.counters["disconnects"] == 1
    # unplugged for a while: the emulator plugs itself back in, and the driver finds it again
    emulator.disconnect(0.3)
    assert rig.delivered.reached("connect", 2)
    assert link.counters["connects"] == 3 and emulator.first_speeds[-1] == (0, 0)
    drive(rig, 0.2, 0.0, until=travelled(rig, 0.1))  # driving again after the reconnections
    assert robot.serial.base.counters["encoder_jumps"] == 0
    assert_odometry_agrees(rig)


def test_a_board_reset_is_survived(rig: Rig) -> None:
    robot = rig.robot
    drive(rig, 0.2, 0.3, until=travelled(rig, 0.2))
    base = robot.serial.base
    assert base.link.reset_board()
    assert wait_until(lambda: robot.emulator.counters["resets"] == 1)
    assert wait_until(lambda: base.counters["board_resets"] >= 1)
    assert base.link.decoder.bad["unknown_tag"] >= 1  # "Reset Done"
    drive(rig, 0.2, -0.3, until=travelled(rig, 0.2))
    assert_odometry_agrees(rig)
    assert robot.devices["imu"].read().yaw == pytest.approx(robot.world.imu_yaw, abs=0.02)


def test_encoder_counters_wrap_during_a_drive() -> None:
    made = backend(counter_start=2**31 - 2000)
    try:
        body = made.body
        drive(made, 0.3, 0.0, until=lambda: min(body.left.ticks, body.right.ticks) > 4000)  # through the wrap
        base = made.robot.serial.base
        assert base._encoders is not None and base._encoders[0] < 0  # the counters wrapped
        assert base.counters["encoder_jumps"] == 0 and base.counters["board_resets"] == 0
        assert_odometry_agrees(made)
    finally:
        made.robot.close()


def test_zero_speed_when_the_backend_closes(rig: Rig) -> None:
    robot = rig.robot
    emulator = robot.emulator
    command = robot.devices["drive"]

    def moving() -> bool:
        command.cmd_vel(0.3, 0.0)  # kept commanded: the watchdog must not be what stops it
        return emulator.speeds != (0, 0)

    assert wait_until(moving)
    robot.serial.close()
    assert wait_until(lambda: emulator.speeds == (0, 0))


def test_a_mission_runs_over_the_emulator(tmp_path: Path) -> None:
    result = run(ROOT / "missions/examples/drive_demo.yaml", backend="emulator", until=4.0, out=tmp_path / "run")
    summary = result.summary
    assert result.outcome == "time_limit" and summary["backend"] == "emulator"
    emulated = summary["emulator"]
    assert emulated["distance_m"] > 0.1  # it backed out of the dock (about 0.9 m in the first 3 s)
    serial = emulated["serial"]
    # what the driver made of the encoders matches where the simulated robot went
    assert serial["odometry_distance_m"] == pytest.approx(emulated["distance_m"], abs=0.05)
    assert serial["lines_bad"] == {} and serial["connects"] == 1
    assert emulated["board"]["command_s"] >= 1 and emulated["board"]["unplugs"] == 1  # once, when it closed
    assert summary["localization"]["final_error_cm"] < 5
    assert (tmp_path / "run" / "trajectory.csv").exists()
    with pytest.raises(RunError, match="names no robot"):
        run(ROOT / "missions/examples/hello.yaml", backend="emulator", out=tmp_path / "hello")
    with pytest.raises(RunError, match="serial port"):
        run(ROOT / "missions/examples/drive_demo.yaml", backend="hardware", out=tmp_path / "hw")
    with pytest.raises(RunError, match="no readings from the Launchpad"):  # a port with no board behind it
        master, slave = os.openpty()
        try:
            run(
                ROOT / "missions/examples/drive_demo.yaml",
                backend="hardware",
                port=os.ttyname(slave),
                out=tmp_path / "hw2",
            )
        finally:
            os.close(master)
            os.close(slave)


def test_botstage_emulate_launchpad_prints_its_path_and_runs_until_interrupted() -> None:
    import serial

    process = subprocess.Popen(
        [sys.executable, "-m", "botstage.missions.cli", "emulate", "launchpad", "--start", "10,7,0"],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first = process.stdout.readline()  # type: ignore[union-attr]
        assert "connect to" in first, first + process.stderr.read()  # type: ignore[union-attr]
        path = first.split("connect to ")[1].split()[0]
        with serial.Serial(path, 115200, timeout=0.1) as port:
            port.write(b"s 120 120\r")
            data = b""
            deadline = time.monotonic() + FAILSAFE_S
            while b"s\t120\t120" not in data and time.monotonic() < deadline:  # until the board echoes it
                data += port.read(1000)
            assert b"s\t120\t120" in data and b"\ne\t" in data
            port.write(b"s 0 0\r")
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=FAILSAFE_S) == 0
        assert not Path(path).exists()  # its pty and path are gone
    finally:
        if process.poll() is None:
            process.kill()
