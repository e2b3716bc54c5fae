"""The emulated Launchpad on a real pty, the real driver connected to it, the simulated Chefbot moving.

Everything here runs in real time (bytes really cross the pty); waits are bounded waits for
events, and distances are compared with tolerances, never timings.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from missions.runner import RunError, run
from robots.clock import WallClock
from robots.emulators.backend import EmulatorBackend
from robots.gridmap import load as load_map
from robots.interfaces import Pose2D, check_interfaces
from robots.sim.backend import map_path
from tests.launchpad_helpers import chefbot, wait_until

ROOT = Path(__file__).resolve().parent.parent
PROFILE = chefbot()
GRID = load_map(map_path("restaurant"))  # type: ignore[arg-type]
OPEN_FLOOR = Pose2D(10.0, 7.0, 0.0)


def backend(start: Pose2D = OPEN_FLOOR, **options) -> EmulatorBackend:
    return EmulatorBackend(PROFILE, GRID, start, 1, WallClock(10), **options)


@pytest.fixture
def chefbot_over_serial() -> Iterator[EmulatorBackend]:
    robot = backend()
    yield robot
    robot.close()


def drive(robot: EmulatorBackend, v: float, w: float, seconds: float) -> None:
    """Command at 10 Hz as a mission's skill does, then stop and wait until the wheels stand."""
    drive = robot.devices["drive"]
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        drive.cmd_vel(v, w)
        time.sleep(0.1)
    drive.stop()
    body = robot.world.body
    assert wait_until(lambda: body.left.speed == 0 and body.right.speed == 0)
    time.sleep(0.1)  # the last encoder lines reach the driver


def assert_odometry_agrees(robot: EmulatorBackend, cm: float = 3.0, degrees: float = 2.0) -> None:
    with robot.lock:
        truth = robot.world.body.pose
    pose = robot.devices["odometry"].read().pose
    assert math.hypot(pose.x - truth.x, pose.y - truth.y) < cm / 100, (pose, truth)
    assert abs(math.remainder(pose.theta - truth.theta, 2 * math.pi)) < math.radians(degrees), (pose, truth)


def test_a_short_drive_moves_the_simulated_robot_and_odometry_agrees(chefbot_over_serial: EmulatorBackend) -> None:
    robot = chefbot_over_serial
    assert check_interfaces(robot.devices) == []
    # the board's five, the depth scan, and the PC's speaker and microphone (simulated beside it)
    assert set(robot.devices) == {"drive", "odometry", "imu", "sonar", "battery", "laser", "speaker", "microphone"}
    assert robot.not_simulated == []
    drive(robot, 0.25, 0.4, 2.5)
    truth = robot.world.body.pose
    assert math.hypot(truth.x - OPEN_FLOOR.x, truth.y - OPEN_FLOOR.y) > 0.4  # it moved
    assert truth.theta > 0.6  # and turned left
    assert_odometry_agrees(robot)
    assert robot.devices["imu"].read().yaw == pytest.approx(robot.world.imu_yaw, abs=0.01)
    assert robot.devices["battery"].read().percent > 99
    stats = robot.serial.summary()
    assert stats["lines_bad"] == {} and stats["connects"] == 1
    ok = stats["lines_ok"]  # the firmware's rates: encoders every loop, IMU, sonar, battery slower
    assert ok["Encoders"] > ok["Quaternion"] > ok["Ultrasonic"] >= ok["BatteryVolts"] >= 1
    assert ok["Encoders"] == pytest.approx(ok["BoardTime"], abs=2) and ok["MotorSpeeds"] > 0


def test_garbage_and_dropped_lines_leave_the_good_ones(chefbot_over_serial: EmulatorBackend) -> None:
    robot = chefbot_over_serial
    link = robot.serial.base.link
    robot.emulator.inject_garbage(20_000)
    robot.emulator.drop_lines(200)
    assert wait_until(lambda: robot.emulator.counters["lines_dropped"] == 200)
    before = link.decoder.ok["Encoders"]
    drive(robot, 0.2, 0.0, 1.5)
    assert link.decoder.lines_bad > 0 and link.decoder.ok["Encoders"] > before + 40
    assert link.counters["listener_errors"] == 0
    assert_odometry_agrees(robot)


def test_a_stalled_wheel_saturates_its_motor_and_odometry_follows_the_encoders(
    chefbot_over_serial: EmulatorBackend,
) -> None:
    robot = chefbot_over_serial
    robot.emulator.stall("left")
    drive(robot, 0.2, 0.0, 2.0)
    body = robot.world.body
    assert abs(body.left.ticks) <= 1 and body.right.ticks > 1000  # the left wheel never turned
    assert robot.emulator.counters["command_s"] > 10
    assert robot.serial.base.controllers[0].integral * PROFILE.control.pid.ki <= 2 * 255 + 1e-6
    assert_odometry_agrees(robot)  # it pivoted about the stalled wheel, and odometry saw it
    assert robot.world.body.pose.theta > 0.3


def test_unplug_and_replug_through_the_emulator(chefbot_over_serial: EmulatorBackend) -> None:
    robot = chefbot_over_serial
    link, emulator = robot.serial.base.link, robot.emulator
    drive_device = robot.devices["drive"]
    for _ in range(10):
        drive_device.cmd_vel(0.2, 0.0)
        time.sleep(0.05)
    assert emulator.speeds != (0, 0)
    emulator.disconnect(0.6)
    assert wait_until(lambda: not link.connected)
    # the board keeps its last speeds while unplugged (the book's firmware has no watchdog)...
    assert emulator.speeds != (0, 0)
    assert wait_until(lambda: link.counters["connects"] == 2, timeout=10)
    # ...and the driver's first words on the new link are zero
    assert wait_until(lambda: emulator.speeds == (0, 0))
    assert link.counters["disconnects"] == 1
    drive(robot, 0.2, 0.0, 1.0)  # driving again after the reconnection
    assert robot.serial.base.counters["encoder_jumps"] == 0


def test_a_board_reset_is_survived(chefbot_over_serial: EmulatorBackend) -> None:
    robot = chefbot_over_serial
    drive(robot, 0.2, 0.3, 1.5)
    base = robot.serial.base
    assert base.link.reset_board()
    assert wait_until(lambda: robot.emulator.counters["resets"] == 1)
    assert wait_until(lambda: base.counters["board_resets"] >= 1)
    assert base.link.decoder.bad["unknown_tag"] >= 1  # "Reset Done"
    drive(robot, 0.2, -0.3, 1.5)
    assert_odometry_agrees(robot)
    assert robot.devices["imu"].read().yaw == pytest.approx(robot.world.imu_yaw, abs=0.02)


def test_encoder_counters_wrap_during_a_drive() -> None:
    robot = backend(counter_start=2**31 - 2000)
    try:
        drive(robot, 0.3, 0.0, 1.5)  # about 5,000 ticks a wheel: through the wrap
        base = robot.serial.base
        assert base._encoders is not None and base._encoders[0] < 0  # the counters wrapped
        assert base.counters["encoder_jumps"] == 0 and base.counters["board_resets"] == 0
        assert_odometry_agrees(robot)
    finally:
        robot.close()


def test_zero_speed_when_the_backend_closes() -> None:
    robot = backend()
    emulator = robot.emulator
    robot.devices["drive"].cmd_vel(0.3, 0.0)
    assert wait_until(lambda: emulator.speeds != (0, 0))
    robot.serial.close()
    assert wait_until(lambda: emulator.speeds == (0, 0))
    robot.close()


def test_a_mission_runs_over_the_emulator(tmp_path: Path) -> None:
    result = run(ROOT / "missions/drive_demo.yaml", backend="emulator", until=4.0, out=tmp_path / "run")
    summary = result.summary
    assert result.outcome == "time_limit" and summary["backend"] == "emulator"
    emulated = summary["emulator"]
    assert emulated["distance_m"] > 0.3  # backing out of the dock at 0.3 m/s
    assert emulated["serial"]["lines_ok"]["Encoders"] > 100
    assert emulated["board"]["command_s"] > 20
    assert summary["localization"]["final_error_cm"] < 5
    assert (tmp_path / "run" / "trajectory.csv").exists()
    with pytest.raises(RunError, match="names no robot"):
        run(ROOT / "missions/hello.yaml", backend="emulator", out=tmp_path / "hello")
    with pytest.raises(RunError, match="serial port"):
        run(ROOT / "missions/drive_demo.yaml", backend="hardware", out=tmp_path / "hw")
    with pytest.raises(RunError, match="no readings from the Launchpad"):  # a port with no board behind it
        master, slave = os.openpty()
        try:
            run(
                ROOT / "missions/drive_demo.yaml",
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
        [sys.executable, "-m", "missions.cli", "emulate", "launchpad", "--start", "10,7,0"],
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
            deadline = time.monotonic() + 5
            while b"s\t120\t120" not in data and time.monotonic() < deadline:
                data += port.read(1000)
            assert b"s\t120\t120" in data and b"\ne\t" in data
            port.write(b"s 0 0\r")
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=10) == 0
        assert not Path(path).exists()  # its pty and path are gone
    finally:
        if process.poll() is None:
            process.kill()
