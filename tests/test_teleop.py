"""Keyboard teleop: keys to velocities, a scripted session on the simulator, the command line."""

from __future__ import annotations

import io
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from botstage.missions.cli import app
from botstage.robots.clock import SimClock
from botstage.robots.gridmap import load as load_map
from botstage.robots.gridmap import map_path
from botstage.robots.interfaces import Pose2D
from botstage.robots.sim.backend import SimBackend
from botstage.robots.teleop import StreamKeys, Teleop, run_teleop, split_keys, status
from tests.launchpad_helpers import chefbot

ROOT = Path(__file__).resolve().parent.parent


def test_keys_step_the_velocity_within_the_limits() -> None:
    state = Teleop(max_linear=0.35, max_angular=2.0)
    for key in "www":
        assert state.press(key)
    assert (state.v, state.w) == (0.15, 0.0)
    state.press("a")
    state.press("left")
    assert state.w == pytest.approx(0.4)
    state.press("d")
    assert state.w == pytest.approx(0.2)
    for _ in range(20):
        state.press("up")
    assert state.v == 0.35  # never beyond the profile's limit
    state.press("x")
    assert state.v == pytest.approx(0.30)
    state.press("?")  # unknown keys do nothing
    assert (state.v, state.w) == (pytest.approx(0.30), pytest.approx(0.2))
    state.press(" ")
    assert (state.v, state.w) == (0.0, 0.0)
    for _ in range(30):
        state.press("down")
    assert state.v == -0.35
    state.press("s")
    assert (state.v, state.w) == (0.0, 0.0)
    assert not state.press("q") and not state.press("\x03")


def test_arrow_keys_are_read_from_their_escape_sequences() -> None:
    assert split_keys("w\x1b[A\x1b[Dx\x1b[B\x1b[C") == ["w", "up", "left", "x", "down", "right"]
    keys = StreamKeys(io.StringIO("w\x1b[Ad\n"))
    assert [keys.read() for _ in range(5)] == [["w"], ["up"], ["d"], [], ["q"]]  # a newline is no key


class RecordingDrive:
    def __init__(self, drive) -> None:
        self.drive = drive
        self.commands: list[tuple[float, float]] = []
        self.stopped = False

    def cmd_vel(self, v: float, w: float) -> None:
        self.commands.append((v, w))
        self.drive.cmd_vel(v, w)

    def stop(self) -> None:
        self.stopped = True
        self.drive.stop()


def test_a_scripted_session_drives_the_simulated_chefbot_and_stops_it() -> None:
    clock = SimClock(10)
    grid = load_map(map_path("restaurant"))  # type: ignore[arg-type]
    sim = SimBackend(chefbot(), grid, Pose2D(10.0, 7.0, 0.0), 1, clock)
    drive = RecordingDrive(sim.devices["drive"])
    keys = StreamKeys(io.StringIO("wwww" + "." * 30 + "a" + "." * 10 + "q"))
    shown: list[str] = []
    state = run_teleop(
        drive, keys, clock, Teleop(0.35, 2.0), step=sim.step, odometry=sim.devices["odometry"], show=shown.append
    )
    assert (state.v, state.w) == (pytest.approx(0.2), pytest.approx(0.2))
    assert drive.commands[3] == (pytest.approx(0.2), 0.0)
    assert len(drive.commands) == 45  # one command every tick, keys or not (the watchdog sees a driver)
    assert drive.stopped  # however the session ends
    pose = sim.world.body.pose
    assert pose.x > 10.5 and pose.theta > 0.1
    assert shown[0].startswith("v +0.05 m/s  w +0.00 rad/s  odometry x 10.00")
    assert status(state.v, state.w) == "v +0.20 m/s  w +0.20 rad/s"


def test_a_session_ends_at_its_time_limit_and_stops() -> None:
    clock = SimClock(10)

    class Idle:
        def read(self) -> list[str]:
            return []

    class Drive:
        stopped = False

        def cmd_vel(self, v: float, w: float) -> None: ...

        def stop(self) -> None:
            Drive.stopped = True

    run_teleop(Drive(), Idle(), clock, Teleop(0.35, 2.0), until=2.0)
    assert clock.now() == pytest.approx(2.0) and Drive.stopped


def test_teleop_command_line_session_on_the_simulator() -> None:
    result = CliRunner().invoke(app, ["teleop", "chefbot", "--rate", "50", "--start", "10,7,0"], input="ww" + "." * 20)
    assert result.exit_code == 0, result.output
    assert "w/x or up/down" in result.output
    assert "v +0.10 m/s  w +0.00 rad/s" in result.output
    assert result.output.rstrip().endswith("stopped")  # the end of the input ends the session
    bad = CliRunner().invoke(app, ["teleop", "chefbot", "--backend", "hardware"])
    assert bad.exit_code == 2 and "serial port" in bad.output


def test_teleop_with_certs_takes_the_operators_folder_or_the_one_botstage_certs_wrote(tmp_path: Path) -> None:
    """``--certs`` names the operator's identity (missions/distributed/security.py): its own folder, or the
    deployment's certificate folder with ``operator/`` in it; without one it says how to make it."""
    from botstage.missions.distributed.security import credentials
    from botstage.robots.ros2.certs import make_certificates

    make_certificates(tmp_path / "certs", ["pi", "operator"])
    assert credentials(tmp_path / "certs", "operator").cert == tmp_path / "certs" / "operator" / "cert.pem"
    assert credentials(tmp_path / "certs" / "operator", "operator").cert.parent == tmp_path / "certs" / "operator"
    (tmp_path / "empty").mkdir()
    missing = CliRunner().invoke(
        app, ["teleop", "bittle", "--connect", "tls/127.0.0.1:7447", "--certs", str(tmp_path / "empty")]
    )
    assert missing.exit_code == 2
    said = " ".join(missing.output.split())
    assert "no TLS credentials for 'operator'" in said and "botstage certs" in said and "--deployment" in said


def test_teleop_over_the_emulated_board_in_a_real_terminal() -> None:
    """The keys come from a terminal (a pty in cbreak mode); the robot behind is the emulator."""
    master, slave = os.openpty()
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "botstage.missions.cli",
            "teleop",
            "chefbot",
            "--backend",
            "emulator",
            "--start",
            "10,7,0",
        ],
        cwd=ROOT,
        stdin=slave,
        stdout=slave,
        stderr=slave,
        env={**os.environ, "TERM": "xterm", "COLUMNS": "200"},
    )
    os.close(slave)
    output = b""

    def read_until(text: bytes, timeout: float = 20.0) -> bool:
        nonlocal output
        deadline = time.monotonic() + timeout
        while text not in output and time.monotonic() < deadline:
            if select.select([master], [], [], 0.1)[0]:
                try:
                    output += os.read(master, 4096)
                except OSError:
                    break
        return text in output

    try:
        assert read_until(b"q: quit"), output
        os.write(master, b"w\x1b[A")  # w and the up arrow
        assert read_until(b"v +0.10 m/s"), output
        time.sleep(0.5)
        os.write(master, b"q")
        assert read_until(b"stopped"), output
        assert process.wait(timeout=10) == 0
    finally:
        if process.poll() is None:
            process.kill()
        os.close(master)
