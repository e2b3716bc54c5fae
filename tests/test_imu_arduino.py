"""The gesture sketch's emulator: the hand's script alone, the device side of rosserial against a
raw host on a real pty, and the round trip with the host driver, faults included.

Nothing waits for a length of time: a test waits for packets, for the driver's state (checked
whenever it changes) or for the board's loop passes, with deadlines that are failsafes only.
The hand moves in lockstep with the board's loop where a test compares values exactly; the
firmware's clock-driven behaviour runs on an injected clock.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
import serial

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.drivers.rosserial import RosserialDriver
from botstage.robots.drivers.rosserial_protocol import Packet, PacketDecoder, encode_packet
from botstage.robots.emulators.imu_arduino import (
    DEFAULT_KEYFRAMES,
    MAX_DROP,
    PUBLISH_HZ,
    HandScript,
    ImuArduino,
    as_published,
    dmp_quaternion,
)
from tests.launchpad_helpers import FAILSAFE_S, wait_until

HOST_TIME = 1_700_000_123.25
VECTOR3 = "geometry_msgs/msg/Vector3"
TF_ID, IMU_ID = 125, 126
FAST = HandScript.default().scaled(0.05)  # the default motion in 0.7 s
HOME, FORWARD, BACK = as_published((0.0, 0.0, 0.0)), as_published((0.0, 30.0, 5.0)), as_published((0.0, -30.0, -5.0))
LEFT, RIGHT = as_published((45.0, 0.0, 0.0)), as_published((-45.0, 0.0, 0.0))


# -- the script --------------------------------------------------------------------------------


def test_the_default_script_goes_home_forward_back_left_right_home() -> None:
    script = HandScript.default()
    assert script.duration == 14.0 and script.loop
    assert script.at(0.5) == (0.0, 0.0, 0.0)
    assert script.at(2.5) == (0.0, 30.0, 5.0)
    assert script.at(5.5) == (0.0, -30.0, -5.0)
    assert script.at(8.5) == (45.0, 0.0, 0.0)
    assert script.at(11.5) == (-45.0, 0.0, 0.0)
    assert script.at(13.5) == (0.0, 0.0, 0.0)
    assert script.at(1.5) == pytest.approx((0.0, 15.0, 2.5))  # interpolated
    assert script.at(10.0) == pytest.approx((0.0, 0.0, 0.0))
    assert script.at(14.0 + 2.5) == script.at(2.5)  # replayed
    once = HandScript(DEFAULT_KEYFRAMES[:3], loop=False)
    assert once.at(100.0) == (0.0, 30.0, 5.0)
    assert FAST.at(0.125) == (0.0, 30.0, 5.0)


def test_yaw_turns_the_short_way_round() -> None:
    script = HandScript([(0.0, 170.0, 0.0, 0.0), (1.0, -170.0, 0.0, 0.0)])
    assert script.at(0.5)[0] == pytest.approx(180.0)
    assert script.at(0.75)[0] == pytest.approx(-175.0)


@pytest.mark.parametrize(
    "keyframes",
    [
        [],
        [(0.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0)],  # times must increase
        [(0.0, 181.0, 0.0, 0.0)],
        [(0.0, 0.0, 91.0, 0.0)],
        [(0.0, 0.0, 0.0, -91.0)],
        [(-1.0, 0.0, 0.0, 0.0)],
        [(0.0, math.nan, 0.0, 0.0)],
        [(0.0, 0.0, 0.0)],
        [(float(t), 0.0, 0.0, 0.0) for t in range(100_001)],
    ],
)
def test_a_script_out_of_bounds_is_refused(keyframes: list[tuple[float, ...]]) -> None:
    with pytest.raises(ValueError):
        HandScript(keyframes)


def test_values_have_an_avrs_precision() -> None:
    assert as_published((0.1, -30.0, 1 / 3)) == (0.10000000149011612, -30.0, 0.3333333432674408)


def dmp_ypr(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """MPU6050_6Axis_MotionApps20's dmpGetGravity and dmpGetYawPitchRoll, in degrees."""
    gx, gy, gz = 2 * (x * z - w * y), 2 * (w * x + y * z), w * w - x * x - y * y + z * z
    yaw = math.atan2(2 * x * y - 2 * w * z, 2 * w * w + 2 * x * x - 1)
    pitch = math.atan(gx / math.sqrt(gy * gy + gz * gz))
    roll = math.atan(gy / gz)
    return math.degrees(yaw), math.degrees(pitch), math.degrees(roll)


@pytest.mark.parametrize("ypr", [(45.0, 0.0, 0.0), (-120.0, 0.0, 0.0), (0.0, 30.0, 0.0), (0.0, 0.0, -20.0)])
def test_the_tf_quaternion_gives_the_dmps_angles_back(ypr: tuple[float, float, float]) -> None:
    assert dmp_ypr(*dmp_quaternion(*ypr)) == pytest.approx(ypr, abs=1e-9)


# -- the device side against a raw host ------------------------------------------------------


class RawHost:
    """A host that is nothing but a pyserial port and a packet decoder."""

    def __init__(self, path: str) -> None:
        self.port = serial.Serial(path, 57_600, timeout=0)
        self.decoder = PacketDecoder()
        self.packets: list[Packet] = []

    def send(self, data: bytes) -> None:
        self.port.write(data)

    def wait(self, condition: Any) -> bool:
        def check() -> bool:
            self.packets += self.decoder.feed(self.port.read(65536))
            return bool(condition(self.packets))

        return wait_until(check)

    def close(self) -> None:
        self.port.close()


def on(topic_id: int, packets: Sequence[Packet]) -> list[Packet]:
    return [p for p in packets if p.topic_id == topic_id]


@pytest.fixture
def board(tmp_path: Path) -> Iterator[ImuArduino]:
    with ImuArduino(FAST, publish_hz=100, lockstep=True, link_dir=tmp_path) as board:
        yield board


def test_the_sketch_waits_for_the_host_then_announces_and_publishes(board: ImuArduino) -> None:
    host = RawHost(board.path)
    try:
        passes = board.loops + 5
        assert wait_until(lambda: board.loops >= passes)
        assert host.wait(lambda packets: True) and host.packets == []  # unconfigured: nothing to say
        host.send(rp.TOPIC_REQUEST)
        assert host.wait(lambda packets: len(on(IMU_ID, packets)) >= 20)
        time_request, tf_info, imu_info = host.packets[:3]
        assert time_request == Packet(rp.ID_TIME, bytes(8))
        infos = [rp.deserialize(p.payload, rp.TOPIC_INFO) for p in (tf_info, imu_info)]
        assert [(i.topic_id, i.topic_name, i.message_type, i.md5sum, i.buffer_size) for i in infos] == [
            (TF_ID, "/tf", "tf/tfMessage", "94810edda583a504dfda3829e70d7eec", 280),
            (IMU_ID, "imu_data", "geometry_msgs/Vector3", "4a842b65f413084dc2b10fb484ea7f17", 280),
        ]
        # each pass: imu_data, then the transform; the hand moves one period a pass
        values = [rp.deserialize(p.payload, VECTOR3) for p in on(IMU_ID, host.packets)]
        samples = list(board.samples)[: len(values)]
        assert [(v.x, v.y, v.z) for v in values] == [s.ypr for s in samples]
        assert all(s.ypr == as_published(FAST.at(s.t)) for s in samples)
        steps = [b.t - a.t for a, b in itertools.pairwise(samples)]
        assert steps == pytest.approx([0.01] * len(steps))
        tf = rp.deserialize(on(TF_ID, host.packets)[0].payload, rp.TF_MESSAGE).transforms[0]
        assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.x) == ("/base_link", "/imu_frame", 1.0)
        # the time reply sets the device's clock; tx stop silences it
        host.send(encode_packet(rp.ID_TIME, rp.serialize(rp.time_message(HOST_TIME))))
        assert wait_until(lambda: board.counters["time_syncs"] == 1)
        assert board.device_now() == pytest.approx(HOST_TIME, abs=5.0)
        host.send(rp.TX_STOP)
        assert wait_until(lambda: not board.configured)
    finally:
        host.close()


class ManualClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_time_sync_every_two_and_a_half_seconds_and_unconfigured_without_replies(tmp_path: Path) -> None:
    """node_handle.h: a time request every SYNC_SECONDS * 500 ms while configured, and no longer
    configured after SYNC_SECONDS * 2200 ms without a reply (on an injected clock)."""
    clock = ManualClock()
    with ImuArduino(FAST, publish_hz=10, lockstep=True, link_dir=tmp_path, monotonic=clock) as board:
        host = RawHost(board.path)
        try:

            def advance(seconds: float) -> None:
                passes = board.loops + 1
                clock.now += seconds
                assert wait_until(lambda: board.loops >= passes)

            host.send(rp.TOPIC_REQUEST)
            for _ in range(100):  # until a pass has heard the request
                advance(0.1)
                if host.wait(lambda packets: True) and on(rp.ID_PUBLISHER, host.packets):
                    break
            assert host.wait(lambda packets: len(on(rp.ID_PUBLISHER, packets)) == 2)
            advance(1.0)
            assert len(on(rp.ID_TIME, host.packets)) == 1
            advance(1.6)  # 2.6 s since the last request
            assert host.wait(lambda packets: len(on(rp.ID_TIME, packets)) == 2)
            assert board.configured
            advance(9.0)  # 11.7 s without a reply
            advance(0.1)
            assert not board.configured
            published = board.counters["published imu_data"]
            advance(0.1)
            assert board.counters["published imu_data"] == published
        finally:
            host.close()


def test_faults_are_bounded(board: ImuArduino) -> None:
    for fault in (board.cut_packets, board.corrupt_checksums, board.lie_about_length, board.drop_packets):
        with pytest.raises(ValueError):
            fault(-1)
        with pytest.raises(ValueError):
            fault(MAX_DROP + 1)
    with pytest.raises(ValueError):
        board.log(9, "no such level")
    with pytest.raises(ValueError):
        board.log(rp.INFO, "x" * 300)  # does not fit the Uno's 280-byte buffer
    with pytest.raises(ValueError):
        board.inject_garbage(-1)
    with pytest.raises(ValueError):
        board.disconnect(0.0)
    with pytest.raises(ValueError):
        ImuArduino(publish_hz=0.0)
    with pytest.raises(ValueError):
        ImuArduino(boot_s=-1.0)
    with pytest.raises(ValueError):
        FAST.scaled(0.0)
    assert PUBLISH_HZ == 2.5


# -- the round trip with the host driver ---------------------------------------------------------


class Received:
    """What the driver handed to an imu_data subscriber."""

    def __init__(self, driver: RosserialDriver) -> None:
        self.values: list[tuple[float, float, float]] = []
        driver.subscribe("imu_data", lambda message, received: self.values.append((message.x, message.y, message.z)))


def open_driver(board: ImuArduino, **options: Any) -> RosserialDriver:
    options = {"clock": lambda: HOST_TIME, "backoff": (0.02, 0.2), **options}
    return RosserialDriver(board.path, **options)


def is_subsequence(part: Sequence[Any], whole: Sequence[Any]) -> bool:
    items = iter(whole)
    return all(any(x == y for y in items) for x in part)


def test_the_driver_gets_the_hands_motion(board: ImuArduino) -> None:
    with open_driver(board) as driver:
        received = Received(driver)
        assert driver.wait_until(lambda: len(received.values) >= 150, FAILSAFE_S)  # two passes of the script
        assert driver.stats()["publishers"] == {"/tf": "tf/tfMessage", "imu_data": "geometry_msgs/Vector3"}
        values = list(received.values)
        samples = [s.ypr for s in board.samples]
        assert values == samples[: len(values)]  # every publication, in order, exactly
        assert is_subsequence([HOME, FORWARD, BACK, HOME, LEFT, RIGHT, HOME], values)
        orientation = driver.orientation()
        assert orientation is not None and (orientation.yaw, orientation.pitch, orientation.roll) == values[-1]
        assert wait_until(lambda: board.counters["time_syncs"] >= 1)
        assert board.device_now() == pytest.approx(HOST_TIME, abs=5.0)
        assert driver.counters["time_requests"] >= 1 and board.counters["negotiations"] == 1
        assert driver.stats()["packets_bad"] == {}


def on_path(script: HandScript, value: tuple[float, float, float], tolerance: float = 1e-3) -> bool:
    """Whether ``value`` is the script's at some time: on one of its segments, within ``tolerance``."""
    frames = script.keyframes
    for (_, *a), (_, *b) in itertools.pairwise(frames):
        span = max(range(3), key=lambda i: abs(b[i] - a[i]))
        share = 0.0 if b[span] == a[span] else min(1.0, max(0.0, (value[span] - a[span]) / (b[span] - a[span])))
        point = [a[i] + share * (b[i] - a[i]) for i in range(3)]
        if all(abs(point[i] - value[i]) <= tolerance for i in range(3)):
            return True
    return False


def test_in_real_time_the_values_lie_on_the_scripts_path(tmp_path: Path) -> None:
    script = HandScript.default().scaled(0.1)
    with ImuArduino(script, publish_hz=50, link_dir=tmp_path) as board, open_driver(board) as driver:
        received = Received(driver)
        assert driver.wait_until(lambda: len(received.values) >= 60, FAILSAFE_S)
        values = list(received.values)
        assert all(on_path(script, value) for value in values), [v for v in values if not on_path(script, v)]
        assert len(set(values)) > 10  # it moved


def test_line_faults_are_survived_and_counted(board: ImuArduino, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="botstage.robots.drivers.rosserial.device")
    with open_driver(board) as driver:
        received = Received(driver)
        assert driver.wait_until(lambda: len(received.values) >= 10, FAILSAFE_S)
        bad = driver.decoder.bad

        def then(count: int = 10) -> None:
            """Wait until ``count`` more good publications came through after a fault."""
            target = len(received.values) + count
            assert driver.wait_until(lambda: len(received.values) >= target, FAILSAFE_S)

        board.inject_garbage(300)
        then()
        assert bad["garbage"] >= 1
        board.corrupt_checksums(2)
        then()
        assert board.counters["checksums_corrupted"] == 2 and bad["checksum"] >= 2
        for fault, counter in [(board.cut_packets, "packets_cut"), (board.lie_about_length, "packets_lied")]:
            dropped = bad.total()
            fault(2)
            then()
            assert board.counters[counter] == 2 and bad.total() > dropped
        board.drop_packets(3)
        then()
        assert board.counters["lines_dropped"] == 3
        board.log(rp.WARN, "FIFO overflow!")
        assert driver.wait_until(lambda: driver.counters["device_logs"] == 1, FAILSAFE_S)
        assert any(r.getMessage().endswith("FIFO overflow!") and r.levelno == logging.WARNING for r in caplog.records)
        assert driver.link.connected
        driver.close()  # the reader has handed over all it parsed
        values = list(received.values)
        assert is_subsequence(values, [s.ypr for s in board.samples])  # what came through was sent, in order
        # every imu_data that was framed well decoded (but for one a lie made with a checksum that passed by chance)
        assert len(values) <= driver.decoder.ok["topic_126"] <= len(values) + driver.counters["undecodable"]
        assert driver.link.counters["listener_errors"] == 0


def test_unplugging_reboots_the_board_and_the_driver_negotiates_again(board: ImuArduino) -> None:
    with open_driver(board) as driver:
        received = Received(driver)
        assert driver.wait_until(lambda: len(received.values) >= 10, FAILSAFE_S)
        board.disconnect(0.2)
        assert driver.wait_until(lambda: driver.link.counters["disconnects"] == 1, FAILSAFE_S)
        count = len(received.values)
        assert driver.wait_until(lambda: len(received.values) >= count + 10, FAILSAFE_S)
        assert board.counters["plugs"] == 2 and board.counters["negotiations"] == 2
        stats = driver.stats()
        assert stats["connects"] == 2 and stats["publishers"]["imu_data"] == "geometry_msgs/Vector3"
        samples = list(board.samples)
        assert any(b.t < a.t for a, b in itertools.pairwise(samples))  # the hand starts again at boot
        assert is_subsequence(received.values[count:], [s.ypr for s in samples])


def test_a_board_still_booting_is_asked_again(tmp_path: Path) -> None:
    with (
        ImuArduino(FAST, publish_hz=100, lockstep=True, boot_s=1.0, link_dir=tmp_path) as board,
        open_driver(board, request_interval_s=0.05) as driver,
    ):
        assert driver.wait_negotiated(FAILSAFE_S)
        assert board.counters["bytes_unheard"] > 0  # the first request went to the bootloader
        assert driver.counters["topic_requests"] >= 2
        received = Received(driver)
        assert driver.wait_until(lambda: len(received.values) >= 5, FAILSAFE_S)
