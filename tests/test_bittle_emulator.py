"""Bittle's driver against its emulated NyBoard through a real pty: the whole byte path.

The backend the CLI opens (``--backend emulator``) is used as a mission would use it. The
board moves its simulated body in real time: every wait is for a state (the board's skill, the
body's pose), with failsafe deadlines, and distances are compared, never durations.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from botstage.robots.clock import WallClock
from botstage.robots.drivers.bittle_base import BittleBase
from botstage.robots.emulators.backend import EmulatorBackend
from botstage.robots.emulators.nyboard import NyBoardEmulator
from botstage.robots.gridmap import load as load_map
from botstage.robots.gridmap import map_path
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, load_profile, profile_path
from tests.launchpad_helpers import wait_until

OPEN_FLOOR = Pose2D(10.0, 7.0, 0.0)
ROOT = Path(__file__).resolve().parent.parent


def _bittle() -> Profile:
    profile, problems, _ = load_profile(profile_path("bittle"))  # type: ignore[arg-type]
    assert profile is not None, problems
    return profile


@pytest.fixture
def backend() -> Iterator[EmulatorBackend]:
    grid = load_map(map_path("restaurant"))  # type: ignore[arg-type]
    backend = EmulatorBackend(_bittle(), grid, OPEN_FLOOR, 0, WallClock(20.0), boot_s=0.05)
    yield backend
    backend.close()


def board(backend: EmulatorBackend) -> NyBoardEmulator:
    assert isinstance(backend.emulator, NyBoardEmulator)
    return backend.emulator


def driver(backend: EmulatorBackend) -> BittleBase:
    base = backend.serial.base
    assert isinstance(base, BittleBase)
    return base


def walk(backend: EmulatorBackend, v: float, w: float, until: object) -> None:
    """Command (v, w) over and over (as a mission's ticks do) until ``until()`` holds."""
    drive = backend.devices["drive"]

    def commanded() -> bool:
        drive.cmd_vel(v, w)
        return bool(until())  # type: ignore[operator]

    assert wait_until(commanded)


def test_the_devices_come_from_the_board_and_the_camera_from_the_pi(backend: EmulatorBackend) -> None:
    assert set(backend.devices) == {"drive", "odometry", "battery", "camera"}
    assert backend.devices["camera"].frame().shape == (480, 640, 3)
    # the driver's first word on the link (said again if the board was still booting, deaf)
    assert wait_until(lambda: bool(board(backend).first_commands))
    assert board(backend).first_commands[0] == "kbalance"


def test_the_article_s_directions_walk_the_body_the_right_way(backend: EmulatorBackend) -> None:
    start = backend.true_pose()
    walk(backend, 0.1, 0.0, lambda: math.hypot(backend.true_pose().x - start.x, backend.true_pose().y - start.y) > 0.1)
    assert board(backend).skill == "wkF"
    ahead = backend.true_pose()
    assert (ahead.x - start.x) * math.cos(start.theta) + (ahead.y - start.y) * math.sin(start.theta) > 0.09
    heading = backend.true_pose().theta
    walk(backend, 0.0, 0.4, lambda: math.remainder(backend.true_pose().theta - heading, math.tau) > 0.3)
    assert board(backend).skill == "crL"  # counter-clockwise: left
    heading = backend.true_pose().theta
    walk(backend, 0.0, -0.4, lambda: math.remainder(backend.true_pose().theta - heading, math.tau) < -0.3)
    assert board(backend).skill == "crR"
    # odometry from the gaits followed the body: within the profile's 20 % on this short walk
    odometry = backend.devices["odometry"].read().pose
    true = backend.true_pose()
    assert math.hypot(odometry.x - true.x, odometry.y - true.y) < 0.1


def test_the_watchdog_stands_the_robot_and_close_lies_it_down(backend: EmulatorBackend) -> None:
    walk(backend, 0.2, 0.0, lambda: board(backend).skill == "trF")
    assert wait_until(lambda: board(backend).skill == "balance")  # no more commands: the driver's watchdog
    assert driver(backend).counters["watchdog_stops"] == 1
    body = backend.world.body
    assert wait_until(lambda: body.left.speed == body.right.speed == 0.0)  # it has come to a halt
    still, loops = backend.true_pose(), board(backend).loops
    assert wait_until(lambda: board(backend).loops > loops + 5)
    assert backend.true_pose() == still
    backend.serial.close()  # the driver's exit path (the board stays up to see it)
    assert wait_until(lambda: board(backend).skill == "rest")


def test_a_replugged_board_gets_the_gait_again(backend: EmulatorBackend) -> None:
    walk(backend, 0.1, 0.0, lambda: board(backend).skill == "wkF")
    board(backend).disconnect(0.2)  # USB out, back in: the board reboots and rests
    walk(backend, 0.1, 0.0, lambda: driver(backend).link.stats()["connects"] == 2 and board(backend).skill == "wkF")
    assert board(backend).first_commands[-1] in ("kbalance", "kwkF")
    assert driver(backend).counters["board_boots"] >= 0  # it may have connected after the boot text


def test_the_patrol_mission_runs_over_the_emulator(tmp_path: Path) -> None:
    """`botstage run missions/examples/bittle_patrol.yaml --backend emulator`: the mission's walk reaches the
    board as gait tokens and the simulated body walks (a few seconds of it, in real time)."""
    out = tmp_path / "run"
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "run",
        str(ROOT / "missions" / "examples" / "bittle_patrol.yaml"),
    ]
    command += ["--backend", "emulator", "--until", "6", "--out", str(out)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "time_limit"
    emulator = summary["emulator"]
    assert emulator["board"]["command_k"] >= 2 and emulator["serial"]["lines_bad"] == {}
    assert emulator["distance_m"] > 0.2  # it walked
