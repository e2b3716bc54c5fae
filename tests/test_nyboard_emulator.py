"""The emulated NyBoard (OpenCat 2.x) on a real pty, driven byte by byte with pyserial as a driver would.

The board moves its simulated Bittle in real time, so nothing here is measured against the wall
clock: a walk lasts until the body has gone far enough, a reply is waited for line by line, and
every deadline is a failsafe. Speeds are distances over the *world's* time. What depends on the
firmware's schedule (the boot's deaf spell, the low-power stall) runs on the emulator's own
injectable clock, moved by the test.
"""

from __future__ import annotations

import math
import os
import select
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import serial

from botstage.robots.drivers.opencat_protocol import Attitude, ReplyDecoder, parse_reply
from botstage.robots.emulators.nyboard import (
    LOW_VOLTAGE_V,
    MAX_DROP,
    MAX_GARBAGE,
    MAX_UNPLUG_S,
    NyBoardEmulator,
    resolve_skill,
)
from botstage.robots.gridmap import load as load_map
from botstage.robots.gridmap import map_path
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, load_profile, profile_path
from botstage.robots.sim.world import World
from tests.launchpad_helpers import FAILSAFE_S, wait_until


def _profile(name: str) -> Profile:
    profile, problems, _ = load_profile(profile_path(name))  # type: ignore[arg-type]
    assert profile is not None, problems
    return profile


BITTLE = _profile("bittle")
GRID = load_map(map_path("restaurant"))  # type: ignore[arg-type]
OPEN_FLOOR = Pose2D(10.0, 7.0, 0.0)
BOOT_TEXT = [b"k", b"", b"* Start *", b"Bittle", b"N_250224", b"Init IMU", b"Skill", b"Ready!", b"g", b"d"]
FAST = {"boot_s": 0.05, "ack_delay_s": 0.02, "behaviour_s": 0.1}


def world() -> World:
    return World(GRID, BITTLE, OPEN_FLOOR, 0)


class Host:
    """The driver's end: pyserial on the board's path, reading whole lines (``\\r\\n`` stripped)."""

    def __init__(self, path: str, on_idle: Callable[[], None] | None = None) -> None:
        self.port = serial.Serial(path, 115200, timeout=0.02)
        self.pending = b""
        self.replies = ReplyDecoder()  # what a driver would make of the same bytes
        self.on_idle = on_idle  # called whenever nothing came (a test's clock moves on)

    def send(self, data: bytes) -> None:
        self.port.write(data)

    def until(self, last: bytes) -> list[bytes]:
        """The lines up to the first that is ``last`` (included)."""
        deadline = time.monotonic() + FAILSAFE_S
        seen: list[bytes] = []
        while True:
            while b"\n" in self.pending:
                line, self.pending = self.pending.split(b"\n", 1)
                seen.append(line.rstrip(b"\r"))
                if seen[-1] == last:
                    return seen
            assert time.monotonic() < deadline, f"no {last!r} line; got {seen}"
            data = self.port.read(max(1, self.port.in_waiting))  # waits for a byte, 20 ms at most
            self.replies.feed(data)
            self.pending += data
            if not data and self.on_idle is not None:
                self.on_idle()

    def ask(self, command: bytes, last: bytes) -> list[bytes]:
        self.send(command)
        return self.until(last)

    def waiting(self) -> bytes:
        """Whatever has arrived and not been read yet, without waiting."""
        data = self.port.read(self.port.in_waiting)
        self.pending += data
        return self.pending

    def close(self) -> None:
        self.port.close()


class Rig:
    def __init__(self, board: NyBoardEmulator) -> None:
        self.board = board
        self.host = Host(board.path)

    def pose(self) -> Pose2D:
        with self.board.lock:
            return self.board.world.body.pose

    def walk_until(self, condition: Callable[[Pose2D], bool]) -> Pose2D:
        assert wait_until(lambda: condition(self.pose())), f"the body never got there: {self.pose()}"
        return self.pose()

    def standing(self) -> bool:
        with self.board.lock:
            body = self.board.world.body
            return body.left.speed == 0 and body.right.speed == 0


@pytest.fixture
def rig() -> Iterator[Rig]:
    board = NyBoardEmulator(world(), **FAST).start()
    assert wait_until(lambda: board.ready)  # booted before the host opens the port: the text is gone
    made = Rig(board)
    yield made
    made.host.close()
    board.close()


def turned(start: float, now: float) -> float:
    return math.remainder(now - start, 2 * math.pi)


# -- names ----------------------------------------------------------------------------------


def test_opencat_2_name_matching() -> None:
    assert resolve_skill("wkF") == ("wkF", "gait")
    assert resolve_skill("wk") == ("wkL", "gait")  # the article's kwk walks left on 2.x
    assert resolve_skill("crR") == ("crR", "gait")  # the left crawl, mirrored
    assert resolve_skill("bk") == ("bk", "gait") and resolve_skill("bkR") == ("bkR", "gait")
    assert resolve_skill("sit") == ("sit", "posture") and resolve_skill("balance") == ("balance", "posture")
    assert resolve_skill("hi") == ("hi", "behaviour") and resolve_skill("pu1") == ("pu1", "behaviour")
    assert resolve_skill("kcR") == ("kcR", "behaviour")
    assert resolve_skill("moonwalk") is None and resolve_skill("") is None and resolve_skill("rnF") is None


# -- boot -----------------------------------------------------------------------------------


def test_boot_text_then_ready_then_the_first_command_leaves_the_rest(rig: Rig) -> None:
    board, host = rig.board, rig.host
    board.board_reset()
    assert host.until(b"d") == BOOT_TEXT  # then the implicit rest: g, d
    assert board.counters["boots"] == 2 and board.counters["resets"] == 1
    assert host.ask(b"?\n", b"?") == [b"G", b"Bittle", b"N_250224", b"?"]  # G: out of the rest
    assert board.first_commands == ["?"]
    assert host.replies.ok["ready"] == 1 and host.replies.bad == {}


# -- walking --------------------------------------------------------------------------------


def test_walk_forward_at_the_gait_tables_speed(rig: Rig) -> None:
    board, host = rig.board, rig.host
    assert host.ask(b"kwkF\n", b"k") == [b"G", b"k"]
    assert board.skill == "wkF" and board.motion == (0.1, 0.0)
    with board.lock:
        start, started = board.world.body.pose, board.world.time
    end = rig.walk_until(lambda pose: pose.x - start.x >= 0.05)
    with board.lock:
        took = board.world.time - started  # the world's time, not the wall clock's
    assert abs(end.y - start.y) < 0.005 and abs(turned(start.theta, end.theta)) < 0.05
    assert 0.07 < math.hypot(end.x - start.x, end.y - start.y) / took < 0.115  # wkF: 0.1 m/s
    assert host.ask(b"kwkF\n", b"k") == [b"k"]  # the same gait: acknowledged, not restarted
    assert board.motion == (0.1, 0.0)


def test_crawl_left_turns_counter_clockwise_and_right_clockwise(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kcrL\n", b"k")
    start = rig.pose()
    end = rig.walk_until(lambda pose: abs(turned(start.theta, pose.theta)) >= 0.1)
    assert turned(start.theta, end.theta) > 0  # counter-clockwise, as ROS's left
    assert board.motion == (0.03, 0.5)
    host.ask(b"kcrR\n", b"k")
    assert board.skill == "crR"
    start = rig.pose()
    end = rig.walk_until(lambda pose: abs(turned(start.theta, pose.theta)) >= 0.1)
    assert turned(start.theta, end.theta) < 0


def test_the_articles_kwk_walks_left_which_the_table_does_not_move(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kwk\n", b"k")
    assert board.skill == "wkL" and board.motion == (0.0, 0.0)  # no speed in the profile for wkL


def test_an_unknown_skill_is_refused_and_the_skill_kept(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"ksit\n", b"k")
    assert host.ask(b"kmoonwalk\n", b"k") == [b"?", b"k"]  # 2.x confirms anyway
    assert board.skill == "sit" and board.counters["unknown_skills"] == 1


def test_a_behaviour_is_acknowledged_at_its_end_and_the_gait_goes_on(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kwkF\n", b"k")
    host.send(b"khi\n?\n")  # the question waits for the behaviour
    assert host.until(b"?") == [b"k", b"Bittle", b"N_250224", b"?"]
    assert board.skill == "wkF" and board.motion == (0.1, 0.0)


def test_rest_stops_the_body_and_the_next_command_says_G(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kwkF\n", b"k")
    start = rig.pose()
    rig.walk_until(lambda pose: pose.x - start.x > 0.01)
    assert host.ask(b"d\n", b"d") == [b"g", b"d"]
    assert wait_until(rig.standing)
    assert board.skill == "rest" and not board.gyro
    assert host.ask(b"kbalance\n", b"k") == [b"G", b"k"]
    assert board.gyro


def test_pause_toggles_and_any_other_command_resumes(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kwkF\n", b"k")
    assert host.ask(b"p\n", b"P") == [b"P"]
    assert board.paused and board.motion == (0.0, 0.0)
    assert wait_until(rig.standing)
    assert host.ask(b"p\n", b"p") == [b"p"]
    assert not board.paused and board.motion == (0.1, 0.0)
    host.ask(b"p\n", b"P")
    assert host.ask(b"kbalance\n", b"k") == [b"p", b"k"]
    assert not board.paused and board.skill == "balance"


def test_gyro_beep_joints_and_attitude(rig: Rig) -> None:
    board, host = rig.board, rig.host
    assert host.ask(b"g\n", b"g") == [b"G", b"g"]  # out of the rest (gyro on), then the toggle (off)
    assert host.ask(b"g\n", b"G") == [b"G"]
    assert host.ask(b"b 12 8\n", b"b") == [b"b"]
    assert host.ask(b"i 0 30 8 -20\n", b"i") == [b"i"]
    angles = [30, 0, 0, 0, 0, 0, 0, 0, -20, 0, 0, 0, 0, 0, 0, 0]
    table = [b"\t".join(b"%d" % i for i in range(16)), b"\t".join(b"%d" % a for a in angles)]
    assert host.ask(b"j\n", b"j") == [b"=", *table, b"j"]
    assert host.ask(b"j 8\n", b"j") == [b"=", b"-20", b"j"]
    assert host.ask(b"m 1\n", b"m") == [b"m"] and board.counters["bad_arguments"] == 1  # half a pair
    assert host.ask(b"m 1 200\n", b"m") == [b"m"] and board.counters["bad_arguments"] == 2  # beyond 125
    assert board.joints == angles
    attitude, _ = host.ask(b"v\n", b"v")
    reply = parse_reply(attitude)
    assert isinstance(reply, Attitude) and reply.pitch == reply.roll == 0 and abs(reply.yaw) < 5
    assert host.ask(b"c 0 5\n", b"c")[1:] == [b"\t".join([b"5"] + [b"0"] * 15), b"c"]
    assert host.ask(b"a\n", b"a") == [b"G", b"aborted", b"a"] and board.offsets == [0] * 16


# -- faults ---------------------------------------------------------------------------------


def test_garbage_and_dropped_lines_leave_the_rest(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kbalance\n", b"k")
    sent = board.counters["bytes_sent"]
    board.inject_garbage(2000)
    assert wait_until(lambda: board.counters["bytes_sent"] >= sent + 2000)
    lines = host.ask(b"?\n", b"?")  # the first line may be glued to the garbage's tail
    assert lines[-2:] == [b"N_250224", b"?"]
    assert sum(host.replies.bad.values()) > 0
    board.drop_lines(3)
    host.send(b"?\n")
    assert wait_until(lambda: board.counters["lines_dropped"] == 3)
    assert host.ask(b"b 1 1\n", b"b") == [b"b"]  # Bittle, the version and ? were lost


def test_unplug_and_replug_boot_the_board_again(rig: Rig) -> None:
    board, host = rig.board, rig.host
    host.ask(b"kwkF\n", b"k")
    board.unplug()
    host.close()
    assert not os.path.exists(board.path)
    assert board.motion == (0.1, 0.0)  # on its battery, it walks on with nobody listening
    board.replug()
    assert os.path.exists(board.path)
    raw = os.open(board.path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)  # no flush: what was printed since
    try:
        received = b""
        deadline = time.monotonic() + FAILSAFE_S
        while not received.endswith(b"d\r\n") and time.monotonic() < deadline:
            if select.select([raw], [], [], 0.1)[0]:
                received += os.read(raw, 4096)
    finally:
        os.close(raw)
    assert received.split(b"\r\n")[:-1] == [b"k", b"\n* Start *", *BOOT_TEXT[3:]]
    assert board.skill == "rest" and wait_until(rig.standing)
    rig.host = host = Host(board.path)
    assert host.ask(b"d\n", b"d") == [b"G", b"g", b"d"]
    assert board.first_commands == ["kwkF", "d"]
    assert board.counters["plugs"] == 2 and board.counters["unplugs"] == 1 and board.counters["boots"] == 2
    host.close()
    board.disconnect(0.1)
    assert not os.path.exists(board.path)
    assert wait_until(lambda: board.counters["boots"] == 3 and board.ready)
    assert os.path.exists(board.path)
    rig.host = host = Host(board.path)
    assert host.ask(b"?\n", b"?")[-2:] == [b"N_250224", b"?"]
    assert board.counters["boots"] == 3 and board.first_commands[-1] == "?"


def test_fault_arguments_are_bounded(rig: Rig) -> None:
    board = rig.board
    for fault, argument in [
        (board.inject_garbage, -1),
        (board.inject_garbage, MAX_GARBAGE + 1),
        (board.drop_lines, -1),
        (board.drop_lines, MAX_DROP + 1),
        (board.disconnect, 0.0),
        (board.disconnect, float("nan")),
        (board.disconnect, MAX_UNPLUG_S + 1),
    ]:
        with pytest.raises(ValueError):
            fault(argument)
    assert os.path.exists(board.path) and board.counters["unplugs"] == 0
    for options in [{"boot_s": -1.0}, {"ack_delay_s": math.nan}, {"battery_check_s": 0.0}, {"loop_hz": 0.0}]:
        with pytest.raises(ValueError):
            NyBoardEmulator(world(), **options)
    with pytest.raises(ValueError, match="no gaits"):
        NyBoardEmulator(World(GRID, _profile("chefbot"), OPEN_FLOOR, 0))


# -- the firmware's schedule, on the board's own clock ------------------------------------


class Clock:
    """The board's ``monotonic``: it stands still until the test moves it."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now

    def advance(self) -> None:
        self.now += 0.1


def test_deaf_while_booting_and_low_power_stalls_the_loop(tmp_path: Path) -> None:
    empty = world()
    empty.battery_charge_ah = 0.01  # 1 %: about 6.02 V
    assert empty.battery_voltage < LOW_VOLTAGE_V
    clock = Clock()
    board = NyBoardEmulator(
        empty, boot_s=0.1, ack_delay_s=0.05, battery_check_s=2.5, link_dir=tmp_path, monotonic=clock
    ).start()
    host = Host(board.path, on_idle=clock.advance)
    try:
        host.send(b"kwkF\n")  # while it boots: never heard
        assert wait_until(lambda: board.counters["bytes_ignored"] == 5)
        assert host.until(b"Ready!")[-2:] == [b"Skill", b"Ready!"]
        assert host.until(b"Low power:6V") == [b"g", b"d", b"Low power:6V"]  # nothing acknowledged the walk
        stalled_at, loops = clock.now, board.loops
        host.send(b"kbalance\n" + b"b 1 1\n" * 20)  # more than the receive buffer holds
        assert wait_until(lambda: board.counters["command_b"] == 20)
        assert board.counters["commands_lost"] == 11  # 9 bytes of kbalance, then nine 6-byte beeps fit in 64
        clock.now = stalled_at + 1.0  # half way through the stall
        assert wait_until(lambda: board.loops > loops)
        assert host.waiting() == b"" and board.motion == (0.0, 0.0)  # the loop is blocked: nothing done
        assert host.until(b"k") == [b"G", b"k"]  # once the stall is over the command is done
        for _ in range(9):  # and the beeps that fitted
            assert host.until(b"b")[-1] == b"b"
        assert board.skill == "balance" and board.counters["low_power"] == 1
        assert board.first_commands == ["kbalance"]
    finally:
        host.close()
        board.close()
