"""The Launchpad driver and its controller chain on a real pseudo-terminal (the test plays the board),
and the chain alone with an injectable clock.

Nothing waits for a length of time or counts lines in a time window: a test waits for the
driver to have handled what it sent (an event), or for a state no event announces (polled),
with deadlines that are failsafes only. The watchdog runs on an injected clock.
"""

from __future__ import annotations

import logging
import math
import random
from collections.abc import Iterator
from pathlib import Path

import pytest

from botstage.robots.clock import SimClock
from botstage.robots.drivers.chefbot_base import ChefbotBase, open_chefbot
from botstage.robots.drivers.launchpad_protocol import BatteryVolts, BoardTime, Encoders, Quaternion
from botstage.robots.drivers.serial_link import RateLimitedLog
from botstage.robots.drivers.wheel_control import wheel_targets
from botstage.robots.interfaces import Battery, Drive, Imu, Odometry, Pose2D, Sonar, check_interfaces
from tests.launchpad_helpers import FAILSAFE_S, Board, Delivered, chefbot, commands, wait_until
from tests.test_launchpad_protocol import VALID, mutate

PROFILE = chefbot()
PER_METRE = PROFILE.base.ticks_per_metre
START = Pose2D(1.0, 2.0, 0.5)


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Board]:
    board = Board(tmp_path)
    yield board
    board.close()


@pytest.fixture
def robot(board: Board) -> Iterator[ChefbotBase]:
    base = open_chefbot(board.path, PROFILE, SimClock(10), START, backoff=(0.02, 0.2), silence_s=60)
    assert base.link.wait_connected(FAILSAFE_S)
    yield base
    base.close()


@pytest.fixture
def handled(robot: ChefbotBase) -> Delivered:
    """What the chain has handled of what the board sent (the board sends nothing unasked)."""
    return Delivered(robot.link)


def lines(*items: bytes) -> bytes:
    return b"".join(item + b"\n" for item in items)


def greet(board: Board, left: int = 0, right: int = 0, micros: int = 1_000_000) -> None:
    board.send(lines(b"t\t%d\t0.02" % micros, b"e\t%d\t%d" % (left, right), b"i\t0\t0\t0\t1", b"b\t12.30", b"u\t0"))


def test_readings_reach_the_robot_interfaces(board: Board, robot: ChefbotBase) -> None:
    greet(board)
    assert robot.wait_ready(FAILSAFE_S)
    assert check_interfaces(robot.devices) == []
    devices = robot.devices
    assert isinstance(devices["drive"], Drive) and isinstance(devices["odometry"], Odometry)
    assert isinstance(devices["imu"], Imu) and isinstance(devices["sonar"], Sonar)
    assert isinstance(devices["battery"], Battery) and "laser" not in devices  # the depth camera is not on the board
    assert devices["imu"].read().yaw == pytest.approx(START.theta)  # the DMP's zero is the start heading
    assert math.isinf(devices["sonar"].read().range)  # 0 cm: no echo
    battery = devices["battery"].read()
    assert battery.voltage == 12.3 and battery.percent == pytest.approx(100 * (12.3 - 10.5) / 2.1)
    # both wheels 0.5 m forward and a quarter turn of the IMU, in steps the wheels can make
    ticks = 0
    for k in range(1, 41):
        ticks = round(k * 0.5 / 40 * PER_METRE)
        board.send(lines(b"t\t%d\t0.02" % (1_000_000 + 20_000 * k), b"e\t%d\t%d" % (ticks, ticks)))
    board.send(lines(b"i\t0\t0\t0.7071\t0.7071", b"u\t87"))
    assert wait_until(lambda: robot.odometry.distance > 0.499)
    pose = devices["odometry"].read().pose
    assert (pose.x, pose.y) == pytest.approx((START.x + 0.5 * math.cos(0.5), START.y + 0.5 * math.sin(0.5)), abs=1e-3)
    assert wait_until(lambda: devices["sonar"].read().range == 0.87)
    assert devices["imu"].read().yaw == pytest.approx(START.theta + math.pi / 2, abs=1e-3)
    assert robot.link.stats()["lines_bad"] == {}


def test_encoder_counters_wrap_around_without_a_jump(board: Board, robot: ChefbotBase, handled: Delivered) -> None:
    top = 2**31 - 1
    start = top - 1000
    greet(board, start, start)
    assert robot.wait_ready(FAILSAFE_S)
    for k in range(1, 21):  # 20 steps of 100 ticks: across 2**31 - 1 -> -2**31
        count = (start + 100 * k + 2**31) % 2**32 - 2**31
        board.send(lines(b"t\t%d\t0.02" % (1_000_000 + 20_000 * k), b"e\t%d\t%d" % (count, count)))
    assert handled.reached("Encoders", 21)
    assert count < 0  # it did wrap
    assert robot.odometry.distance == pytest.approx(2000 / PER_METRE)
    assert robot.counters["board_resets"] == 0 and robot.counters["encoder_jumps"] == 0


def test_a_board_reset_is_counted_and_the_pose_continues(
    board: Board, robot: ChefbotBase, handled: Delivered, caplog: pytest.LogCaptureFixture
) -> None:
    greet(board, 5000, 5000, micros=50_000_000)
    assert robot.wait_ready(FAILSAFE_S)
    board.send(lines(b"t\t50020000\t0.02", b"e\t5100\t5100"))
    assert handled.reached("Encoders", 2)
    before = robot.odometry.pose
    caplog.set_level(logging.WARNING)
    # the board rebooted: its clock and its counters start again from zero
    board.send(b"Reset Done\r\n" + lines(b"t\t1200\t0.00", b"e\t0\t0", b"i\t0\t0\t0\t1"))
    board.send(lines(b"t\t21200\t0.02", b"e\t100\t100"))
    assert handled.reached("Encoders", 4)
    assert robot.counters["board_resets"] == 1
    after = robot.odometry.pose
    assert after.x - before.x == pytest.approx(100 / PER_METRE * math.cos(START.theta), abs=1e-6)  # no jump
    assert robot.read_imu().yaw == pytest.approx(START.theta)  # the IMU's new zero is re-aligned
    # without its clock line, a counter jump the wheels cannot make is a reset too
    board.send(lines(b"e\t-90000\t7"))
    assert handled.reached("Encoders", 5)
    assert robot.counters["encoder_jumps"] == 1
    assert robot.counters["board_resets"] == 2
    assert any("Launchpad reset" in record.message for record in caplog.records)


def test_warnings_are_rate_limited() -> None:
    now = [0.0]
    records: list[str] = []

    class Sink(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record.getMessage())

    logger = logging.getLogger("test.ratelimit")
    logger.addHandler(Sink())
    logger.propagate = False
    warn = RateLimitedLog(logger, interval_s=5.0, monotonic=lambda: now[0])
    for i in range(100):
        now[0] = i * 0.1  # 100 warnings over 10 s
        warn.warning("reset", "the board reset")
    assert records == ["the board reset", "the board reset (49 more like it since the last report)"]


def test_fuzz_megabytes_through_the_pty(board: Board, robot: ChefbotBase) -> None:
    """Random bytes and mutated lines around valid ones (2 MB), through the real pty: the reader
    keeps going, and every valid line among them (one that starts a line) is parsed. A last
    line no other can be tells when the driver has handled all of it."""
    rng = random.Random(3)
    chunks, valid, size = [b"\n"], 0, 0
    while size < 2_000_000:
        roll = rng.random()
        if roll < 0.3:
            piece = rng.choice(VALID) + b"\n"
            valid += chunks[-1].endswith(b"\n")  # noise before it on its line makes it noise too
        elif roll < 0.65:
            piece = mutate(rng.choice(VALID), rng) + b"\n"
        else:
            piece = rng.randbytes(rng.randint(1, 300))  # raw noise, newlines and all
        chunks.append(piece)
        size += len(piece)
    stream = b"".join(chunks)
    last = b"\nb\t99.25\n"  # a battery no valid line reports; the newline ends whatever came before
    assert b"99.25" not in stream
    board.send(stream + last)
    assert wait_until(lambda: robot.volts == 99.25)
    parsed = robot.link.decoder.lines_ok - 1
    assert valid <= parsed <= valid * 1.3, (valid, parsed)
    assert robot.link.counters["listener_errors"] == 0
    assert robot.link.connected and robot.link._thread is not None and robot.link._thread.is_alive()


def test_unplug_and_replug_reconnects_and_sends_zero_first(
    board: Board, robot: ChefbotBase, handled: Delivered
) -> None:
    greet(board)
    assert robot.wait_ready(FAILSAFE_S)
    robot.cmd_vel(0.2, 0.0)
    assert board.wait_for(lambda data: any(c != (0, 0) for c in commands(data)))
    board.unplug()
    assert handled.reached("disconnect", 1)
    assert not robot.link.connected and robot.link.counters["disconnects"] == 1
    # a few failed attempts while the path is gone
    assert wait_until(lambda: robot.link.counters["open_failures"] >= 2)
    reconnected = handled.counts["connect"] + 1  # the first connection may have been counted or not
    board.plug()
    assert handled.reached("connect", reconnected)
    assert robot.link.counters["connects"] == 2
    assert board.wait_for(lambda data: len(commands(data)) >= 1)
    assert commands(board.read())[0] == (0, 0)  # the board kept the old speed: zero comes first
    greet(board, 777, 777)  # new counters are a new reference, not a step
    greet(board, 800, 800, micros=1_020_000)
    assert handled.reached("Encoders", 3)
    assert robot.counters["encoder_jumps"] == 0 and robot.counters["board_resets"] == 0
    assert robot.odometry.distance == pytest.approx(23 / PER_METRE)  # 777 -> 800, and not 0 -> 777


def test_a_silent_port_is_reopened(board: Board) -> None:
    robot = open_chefbot(board.path, PROFILE, SimClock(10), START, silence_s=0.3)
    try:
        assert wait_until(lambda: robot.link.counters["connects"] >= 2)
        assert robot.link.counters["silences"] >= 1 and robot.link.counters["disconnects"] >= 1
    finally:
        robot.close()


def test_zero_speed_on_shutdown(board: Board) -> None:
    robot = open_chefbot(board.path, PROFILE, SimClock(10), START)
    assert robot.link.wait_connected(FAILSAFE_S)
    robot.cmd_vel(0.3, 0.5)
    assert board.wait_for(lambda data: any(c != (0, 0) for c in commands(data)))
    robot.close()
    assert board.wait_for(lambda data: commands(data)[-1] == (0, 0))
    robot.close()  # twice is harmless


def test_the_watchdog_stops_after_half_a_second_over_the_pty(board: Board) -> None:
    """The watchdog's own thread, on an injected clock: it stops the motors at 0.5 s, not before."""
    now = [100.0]
    robot = open_chefbot(board.path, PROFILE, SimClock(10), START, monotonic=lambda: now[0])
    checks = [0]
    check = robot.check_watchdog

    def counted() -> bool:
        try:
            return check()
        finally:
            checks[0] += 1

    robot.check_watchdog = counted  # type: ignore[method-assign]  # what the watchdog thread calls

    def checked_again() -> bool:
        """True once the watchdog thread has looked twice more (so at least once since now)."""
        seen = checks[0]
        return wait_until(lambda: checks[0] >= seen + 2)

    try:
        assert robot.link.wait_connected(FAILSAFE_S)
        robot.cmd_vel(0.2, 0.0)
        assert board.wait_for(lambda data: any(c != (0, 0) for c in commands(data)))
        now[0] += 0.45
        assert checked_again()
        assert commands(board.read())[-1] != (0, 0) and robot.counters["watchdog_stops"] == 0  # not before its time
        now[0] += 0.1
        assert checked_again()
        assert robot.counters["watchdog_stops"] == 1
        assert board.wait_for(lambda data: commands(data)[-1] == (0, 0))
    finally:
        robot.close()


class FakeLink:
    def __init__(self) -> None:
        self.sent: list[tuple[int, int]] = []

    def send_speeds(self, left: int, right: int) -> bool:
        self.sent.append((left, right))
        return True

    def stats(self) -> dict:
        return {}

    def close(self) -> None:
        pass


def chain(now: list[float], **options) -> tuple[ChefbotBase, FakeLink]:
    link = FakeLink()
    base = ChefbotBase(link, PROFILE, SimClock(10), START, monotonic=lambda: now[0], **options)  # type: ignore[arg-type]
    return base, link


def test_the_watchdog_with_an_injected_clock() -> None:
    now = [100.0]
    base, link = chain(now)
    base.cmd_vel(0.2, 0.0)
    assert link.sent[-1] != (0, 0)
    now[0] += 0.45
    assert base.check_watchdog() is False
    now[0] += 0.1
    assert base.check_watchdog() is True and link.sent[-1] == (0, 0)
    assert base.targets == (0.0, 0.0) and base.counters["watchdog_stops"] == 1
    now[0] += 5
    assert base.check_watchdog() is False  # once per silence
    base.cmd_vel(0.2, 0.0)  # the next command drives again
    assert link.sent[-1] != (0, 0)
    base, link = chain(now, watchdog_s=2.0)  # configurable (and from the profile's control.watchdog_s)
    base.cmd_vel(0.2, 0.0)
    now[0] += 1.5
    assert base.check_watchdog() is False


def test_limits_are_enforced_whatever_the_caller_asks() -> None:
    base = PROFILE.base
    assert wheel_targets(5.0, 0.0, base) == pytest.approx((0.35, 0.35))
    left, right = wheel_targets(0.35, 2.0, base)  # the outer wheel would pass its top speed
    assert max(abs(left), abs(right)) == pytest.approx(base.wheel_top_speed)
    assert (right - left) / (left + right) == pytest.approx(2.0 * 0.15 / 0.35)  # the turn keeps its shape
    now = [0.0]
    chefbot_base, link = chain(now)
    chefbot_base.cmd_vel(50.0, -30.0)
    assert chefbot_base.targets == pytest.approx(wheel_targets(0.35, -2.0, base))
    with pytest.raises(ValueError, match="finite"):
        chefbot_base.cmd_vel(math.nan, 0.0)
    assert link.sent[-1] == (0, 0) and chefbot_base.targets == (0.0, 0.0)  # a broken command stops


def test_the_pid_saturates_without_winding_up_on_a_stalled_wheel() -> None:
    now = [0.0]
    base, link = chain(now)
    base.on_message(BoardTime(0, 0.0), now[0])
    base.on_message(Encoders(0, 0), now[0])
    for k in range(1, 301):  # 6 s: the left wheel is stalled, the right one turns as asked
        now[0] = k * 0.02
        base.cmd_vel(0.3, 0.0)
        right = round(min(0.3, 0.5 * now[0]) * now[0] * PER_METRE)  # roughly, it does not matter
        base.on_message(Encoders(0, right), now[0])
    left_output = link.sent[-1][0]
    assert left_output == 255  # saturated, and never beyond
    assert all(abs(a) <= 255 and abs(b) <= 255 for a, b in link.sent)
    stalled = base.controllers[0]
    assert abs(stalled.integral) * PROFILE.control.pid.ki <= 2 * 255 + 1e-6  # bounded: no lurch when it frees
    assert stalled.saturated
    quaternion_yaw = Quaternion(0.0, 0.0, math.sin(0.3), math.cos(0.3)).yaw
    assert quaternion_yaw == pytest.approx(0.6)
    base.on_message(BatteryVolts(11.0), now[0])
    assert base.read_battery().percent == pytest.approx(100 * 0.5 / 2.1)


def test_bench_serial_prints_json_lines() -> None:
    import json
    import subprocess
    import sys

    root = Path(__file__).resolve().parent.parent
    result = subprocess.run(
        [sys.executable, "-m", "tests.bench", "serial", "--quick"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert [row["bench"] for row in rows[:5]] == [
        "parser",
        "end_to_end_pty",
        "pty_floor",
        "command_latency",
        "command_latency_while_streaming",
    ]
    # the same under SCHED_FIFO where the OS allows it, else said so
    fifo = [row["bench"] for row in rows[5:]]
    assert fifo in (
        ["pty_floor_sched_fifo", "command_latency_sched_fifo", "command_latency_while_streaming_sched_fifo"],
        ["sched_fifo"] * 3,
    )
    assert rows[1]["lines_parsed"] == rows[1]["lines"] and rows[3]["p99_ms"] > 0
