"""Bittle's NyBoard driver on a real pseudo-terminal: the test plays the board byte by byte.

What goes out is checked on the wire (the article's tokens, safe ones on every exit path), what
comes in is the firmware's lines (acknowledgements, boot text, warnings, garbage). Nothing waits
for a length of time: every wait is for bytes or a state, with failsafe deadlines; odometry runs
on an injected monotonic clock.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from botstage.robots import PROFILES_DIR
from botstage.robots.clock import SimClock
from botstage.robots.drivers.bittle_base import BittleBase, open_bittle
from botstage.robots.interfaces import Battery, Drive, Odometry, Pose2D, check_interfaces
from botstage.robots.profile import Profile, load_profile
from tests.launchpad_helpers import FAILSAFE_S, Board, wait_until

START = Pose2D(1.0, 2.0, 0.5)


def bittle() -> Profile:
    profile, problems, _ = load_profile(PROFILES_DIR / "bittle.yaml")
    assert profile is not None, problems
    return profile


PROFILE = bittle()


class FakeTime:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Board]:
    board = Board(tmp_path)
    yield board
    board.close()


@pytest.fixture
def time_now() -> FakeTime:
    return FakeTime()


def open_robot(board: Board, time_now: FakeTime, **options: object) -> BittleBase:
    options = {"ack_timeout_s": 1e9, "watchdog_s": 1e9, **options}  # off unless a test turns them on
    base = open_bittle(board.path, PROFILE, SimClock(10), START, backoff=(0.02, 0.2), monotonic=time_now, **options)  # type: ignore[arg-type]
    assert base.link.wait_connected(FAILSAFE_S)
    return base


@pytest.fixture
def robot(board: Board, time_now: FakeTime) -> Iterator[BittleBase]:
    base = open_robot(board, time_now)
    yield base
    base.close()


def sent(board: Board) -> list[bytes]:
    """The commands the driver wrote so far, one per line."""
    return [line for line in board.read().split(b"\n") if line]


def wait_sent(board: Board, command: bytes, times: int = 1) -> bool:
    return board.wait_for(lambda data: data.split(b"\n").count(command) >= times)


def ack(board: Board, robot: BittleBase, token: bytes = b"k") -> None:
    before = robot.counters["acks"] + robot.counters["acks_unasked"]
    board.send(token + b"\r\n")
    assert wait_until(lambda: robot.counters["acks"] + robot.counters["acks_unasked"] > before)


def test_the_devices_are_the_robot_interfaces(robot: BittleBase) -> None:
    devices = robot.devices
    assert check_interfaces(devices) == []
    assert isinstance(devices["drive"], Drive) and isinstance(devices["odometry"], Odometry)
    assert isinstance(devices["battery"], Battery) and "camera" not in devices  # the Pi's camera is not on the board


def test_balance_goes_out_first_then_the_article_s_tokens_on_each_change(board: Board, robot: BittleBase) -> None:
    assert wait_sent(board, b"kbalance")
    assert sent(board)[0] == b"kbalance"  # the board keeps its last gait while the PC is away
    for v, w, token in [
        (0.1, 0.0, b"kwkF"),
        (0.1, 0.5, b"kwkF"),  # linear first: no new token
        (0.0, 0.4, b"kcrL"),  # counter-clockwise is left (the article's repository sends kcrR)
        (0.0, -0.4, b"kcrR"),
        (-0.1, 0.0, b"kbk"),
        (0.25, 0.0, b"ktrF"),  # the gait nearest the speed asked (clamped to the fastest)
        (0.0, 0.0, b"kbalance"),
    ]:
        robot.cmd_vel(v, w)
        assert wait_sent(board, token)
        ack(board, robot)
    assert sent(board)[1:] == [b"kwkF", b"kcrL", b"kcrR", b"kbk", b"ktrF", b"kbalance"]
    assert robot.counters["resends"] == 0


def test_an_unacknowledged_token_is_sent_again_until_the_board_takes_it(board: Board, time_now: FakeTime) -> None:
    robot = open_robot(board, time_now, ack_timeout_s=0.05)
    try:
        assert wait_sent(board, b"kbalance")
        ack(board, robot)
        robot.cmd_vel(0.1, 0.0)
        time_now.now += 1.0  # past the acknowledgement's timeout
        assert wait_sent(board, b"kwkF", 2)
        ack(board, robot)
        resent = robot.counters["resends"]
        assert resent >= 1
        time_now.now += 10.0
        passes = robot.supervised
        assert wait_until(lambda: robot.supervised >= passes + 2)  # the supervisor has looked again since
        assert sent(board).count(b"kwkF") == resent + 1  # taken: not sent again
    finally:
        robot.close()


def test_an_unknown_skill_is_not_repeated(board: Board, time_now: FakeTime) -> None:
    robot = open_robot(board, time_now, ack_timeout_s=0.05)
    try:
        robot.cmd_vel(0.1, 0.0)
        assert wait_sent(board, b"kwkF")
        board.send(b"?\r\nk\r\n")  # OpenCat 2: not in this board, then the previous skill's echo
        assert wait_until(lambda: robot.counters["unknown_skills"] == 1)
        time_now.now += 10.0
        passes = robot.supervised
        assert wait_until(lambda: robot.supervised >= passes + 2)
        robot.cmd_vel(0.0, 0.4)
        assert wait_sent(board, b"kcrL")
        assert sent(board).count(b"kwkF") == 1
        assert robot.summary()["refused_skills"] == ["wkF"]
    finally:
        robot.close()


def test_the_watchdog_stands_the_robot_when_commands_stop(board: Board, time_now: FakeTime) -> None:
    robot = open_robot(board, time_now, watchdog_s=0.5)
    try:
        robot.cmd_vel(0.1, 0.0)
        assert wait_sent(board, b"kwkF")
        ack(board, robot)
        time_now.now += 0.6
        assert wait_sent(board, b"kbalance", 2)
        assert robot.counters["watchdog_stops"] == 1
        robot.cmd_vel(0.1, 0.0)  # the next command walks again
        assert wait_sent(board, b"kwkF", 2)
    finally:
        robot.close()


def test_close_lies_the_robot_down(board: Board, time_now: FakeTime) -> None:
    robot = open_robot(board, time_now)
    robot.cmd_vel(0.1, 0.0)
    assert wait_sent(board, b"kwkF")
    robot.close()
    commands = sent(board)
    assert commands[-1] == b"d"  # rest: servos off
    assert b"kbalance" in commands[commands.index(b"kwkF") :]  # it stood first
    robot.cmd_vel(0.2, 0.0)  # after close nothing moves it
    assert sent(board)[-1] == b"d"


def test_odometry_follows_the_acknowledged_gait(board: Board, robot: BittleBase, time_now: FakeTime) -> None:
    robot.cmd_vel(0.1, 0.0)
    assert wait_sent(board, b"kwkF")
    time_now.now += 5.0  # not acknowledged yet: still standing
    assert robot.devices["odometry"].read().pose == START
    ack(board, robot)
    time_now.now += 2.0
    reading = robot.devices["odometry"].read()
    assert (reading.pose.x, reading.pose.y) == pytest.approx(
        (START.x + 0.2 * math.cos(0.5), START.y + 0.2 * math.sin(0.5))
    )
    assert reading.twist.v == 0.1 and reading.covariance[0, 0] > 0


def test_board_news_and_garbage(board: Board, robot: BittleBase) -> None:
    assert robot.devices["battery"].read().percent == 100.0  # no warning yet: the board reports no level
    board.send(b"Bittle\r\n")  # the first line on a new link may be cut: counted apart
    board.send(b"\x00\xff garbage \x07\r\n" + b"z" * 600 + b"\r\nLow power:6V\r\n12.0\t1.0\t-2.0\r\nG\r\n")
    assert wait_until(lambda: robot.counters["low_battery_warnings"] == 1)
    battery = robot.devices["battery"].read()
    assert (battery.voltage, battery.percent) == (6.0, 0.0)
    bad = robot.link.stats()["lines_bad"]
    assert bad.get("control_bytes") == 1 and bad.get("too_long") == 1


def test_a_reboot_or_a_replug_sends_the_wanted_gait_again(board: Board, robot: BittleBase) -> None:
    robot.cmd_vel(0.1, 0.0)
    assert wait_sent(board, b"kwkF")
    ack(board, robot)
    board.send(b"k\r\n\r\n* Start *\r\nBittle\r\nReady!\r\ng\r\nd\r\n")  # a brown-out: it rebooted and rests
    assert wait_sent(board, b"kwkF", 2)
    ack(board, robot)
    board.unplug()
    assert wait_until(lambda: not robot.link.connected)
    board.plug()
    assert wait_until(lambda: robot.link.connected)
    assert board.wait_for(lambda data: b"kwkF\n" in data)
    assert sent(board)[0] == b"kbalance"  # on the new link: balance first, then the gait
    assert robot.link.stats()["connects"] == 2
