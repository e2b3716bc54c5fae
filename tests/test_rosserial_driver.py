"""The rosserial host driver on a real pseudo-terminal, the test playing the device byte by byte.

Nothing waits for a length of time: a test waits for the driver to have handled what it sent
(``wait_until`` on the driver's state, checked whenever it changes) or for bytes from the
driver (``Board.wait_for``), with deadlines that are failsafes only. The re-request timing runs
on an injected clock, and a test knows the keeper looked at it by counting its passes.
"""

from __future__ import annotations

import logging
import random
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.drivers.rosserial import BAUD, Orientation, RosserialDriver
from botstage.robots.drivers.rosserial_protocol import Packet, PacketDecoder, encode_packet
from tests.launchpad_helpers import FAILSAFE_S, Board, wait_until

HOST_TIME = 1_700_000_123.25
TYPES = rp.TYPESTORE.types
VECTOR3 = "geometry_msgs/msg/Vector3"
IMU_ID, TF_ID = 126, 125


def vector3(x: float, y: float, z: float) -> Any:
    return TYPES[VECTOR3](x=x, y=y, z=z)


def announce(
    board: Board, topic_id: int, name: str, typename: str, *, md5: str = "", side: int = 0, size: int = 280
) -> None:
    info = rp.topic_info(topic_id, name, typename, size, md5=md5)
    board.send(encode_packet(side, rp.serialize(info)))


def publish(board: Board, topic_id: int, message: Any) -> None:
    board.send(encode_packet(topic_id, rp.serialize(message)))


def from_host(board: Board) -> list[Packet]:
    return PacketDecoder().feed(board.read())


def requests(data: bytes) -> int:
    return sum(p.topic_id == rp.ID_PUBLISHER for p in PacketDecoder().feed(data))


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Board]:
    board = Board(tmp_path)
    yield board
    board.close()


def open_driver(board: Board, **options: Any) -> RosserialDriver:
    options = {"clock": lambda: HOST_TIME, "backoff": (0.02, 0.2), "silence_s": None, **options}
    driver = RosserialDriver(board.path, **options)
    # connected, and the driver has taken note (the link says so before it tells the driver)
    assert driver.wait_until(lambda: driver.counters["topic_requests"] >= 1, FAILSAFE_S)
    return driver


@pytest.fixture
def driver(board: Board) -> Iterator[RosserialDriver]:
    driver = open_driver(board, request_interval_s=60.0)
    yield driver
    driver.close()


@pytest.fixture
def negotiated(board: Board, driver: RosserialDriver) -> RosserialDriver:
    """The gesture sketch's two publishers, announced."""
    assert board.wait_for(lambda data: requests(data) >= 1)
    announce(board, TF_ID, "/tf", rp.TF_MESSAGE)
    announce(board, IMU_ID, "imu_data", VECTOR3)
    assert driver.wait_until(lambda: len(driver.publishers) == 2, FAILSAFE_S)
    return driver


def ypr(driver: RosserialDriver) -> tuple[float, float, float] | None:
    orientation = driver.orientation()
    return None if orientation is None else (orientation.yaw, orientation.pitch, orientation.roll)


def passes(driver: RosserialDriver, count: int = 2) -> bool:
    """Wait until the keeper has looked at the clock ``count`` more times."""
    target = driver.keeps + count
    return driver.wait_until(lambda: driver.keeps >= target, FAILSAFE_S)


def test_defaults_are_rosserial_arduinos() -> None:
    assert BAUD == 57_600
    driver = RosserialDriver("/nonexistent/tty", start=False)
    assert driver.link.baud == 57_600 and driver.link.safe_command == rp.TOPIC_REQUEST
    assert driver.link.parting_command == rp.TX_STOP


def test_topics_are_requested_until_the_device_announces_them(board: Board) -> None:
    clock = FakeClock()
    driver = open_driver(board, request_interval_s=2.0, sync_timeout_s=15.0, monotonic=clock)
    try:
        assert board.wait_for(lambda data: data.startswith(rp.TOPIC_REQUEST))  # the first word on the link
        for asked in (2, 3):
            clock.now += 2.0
            assert board.wait_for(lambda data, asked=asked: requests(data) >= asked)
        announce(board, IMU_ID, "imu_data", VECTOR3)
        assert driver.wait_negotiated(FAILSAFE_S)
        clock.now += 10.0
        assert passes(driver)
        assert requests(board.read()) == 3  # announced: no more requests
        clock.now += 5.0  # 15 s without a time request from the device: lost sync, ask again
        assert board.wait_for(lambda data: requests(data) >= 4)
        assert driver.counters["sync_lost"] == 1
        board.send(encode_packet(rp.ID_TIME, bytes(8)))  # a device that asks for the time is in sync
        assert driver.wait_until(lambda: driver.counters["time_requests"] == 1, FAILSAFE_S)
        clock.now += 14.0
        assert passes(driver)
        assert requests(board.read()) == 4 and driver.counters["sync_lost"] == 1
    finally:
        driver.close()


def test_time_requests_are_answered_with_the_hosts_clock(board: Board, driver: RosserialDriver) -> None:
    board.send(encode_packet(rp.ID_TIME, bytes(8)))  # ros_lib's requestSyncTime: a zero Time
    assert board.wait_for(lambda data: any(p.topic_id == rp.ID_TIME for p in PacketDecoder().feed(data)))
    (reply,) = [p for p in from_host(board) if p.topic_id == rp.ID_TIME]
    assert rp.time_seconds(rp.deserialize(reply.payload, rp.TIME)) == pytest.approx(HOST_TIME)
    assert driver.wait_until(lambda: driver.counters["time_replies"] == 1, FAILSAFE_S)
    assert driver.counters["time_requests"] == 1


def test_publications_reach_their_subscribers(board: Board, negotiated: RosserialDriver) -> None:
    driver = negotiated
    got: list[tuple[Any, float]] = []
    also: list[Any] = []
    driver.subscribe("imu_data", lambda message, received: got.append((message, received)))
    unsubscribe = driver.subscribe("/imu_data", lambda message, received: also.append(message))
    assert driver.orientation() is None
    publish(board, IMU_ID, vector3(12.5, -20.25, 3.0))  # yaw, pitch, roll in degrees
    assert driver.wait_until(lambda: len(got) == 1, FAILSAFE_S)
    message, received = got[0]
    assert (message.x, message.y, message.z) == (12.5, -20.25, 3.0) and len(also) == 1
    assert driver.orientation() == Orientation(12.5, -20.25, 3.0, received)
    unsubscribe()
    publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
    assert driver.wait_until(lambda: len(got) == 2, FAILSAFE_S)
    assert len(also) == 1
    # the sketch's TF broadcast, a nested message, decoded too
    header = TYPES["std_msgs/msg/Header"](seq=0, stamp=rp.time_message(5.5).data, frame_id="/base_link")
    transform = TYPES["geometry_msgs/msg/TransformStamped"](
        header=header,
        child_frame_id="/imu_frame",
        transform=TYPES["geometry_msgs/msg/Transform"](
            translation=vector3(1.0, 0.0, 0.0), rotation=TYPES["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1)
        ),
    )
    publish(board, TF_ID, TYPES[rp.TF_MESSAGE](transforms=[transform]))
    assert driver.wait_until(lambda: driver.latest("/tf") is not None, FAILSAFE_S)
    tf = driver.latest("tf")[0]  # type: ignore[index]
    assert tf.transforms[0].child_frame_id == "/imu_frame" and tf.transforms[0].header.stamp.sec == 5
    stats = driver.stats()
    assert stats["publishers"] == {"/tf": "tf/tfMessage", "imu_data": "geometry_msgs/Vector3"}
    assert stats["packets_ok"] == {"publisher": 2, "topic_125": 1, "topic_126": 2} and stats["packets_bad"] == {}
    assert stats["messages"] == 3


def test_an_endpoint_that_does_not_check_out_is_refused(board: Board, driver: RosserialDriver) -> None:
    got: list[Any] = []
    driver.subscribe("imu_data", lambda message, received: got.append(message))
    announce(board, IMU_ID, "imu_data", VECTOR3, md5="0" * 32)
    announce(board, 130, "thing", "my_msgs/msg/Thing", md5="1" * 32)  # a type nobody here knows
    announce(board, 50, "hijack", VECTOR3)  # an endpoint on a reserved id
    assert driver.wait_until(lambda: driver.counters["bad_topic_id"] == 1, FAILSAFE_S)
    assert driver.counters["md5_mismatch"] == 1 and driver.counters["unknown_type"] == 1
    assert driver.publishers == {} and driver.negotiated
    publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
    assert driver.wait_until(lambda: driver.counters["refused_topic_messages"] == 1, FAILSAFE_S)
    assert got == [] and requests(board.read()) == 1  # a refused topic is not asked for again
    announce(board, IMU_ID, "imu_data", VECTOR3)  # the right sketch now
    publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
    assert driver.wait_until(lambda: len(got) == 1, FAILSAFE_S)


def test_a_publication_on_an_unknown_topic_asks_for_the_topics(board: Board) -> None:
    """The device kept its configuration while the host was away: SerialClient's "Tried to
    publish before configured" asks again, at most once per interval."""
    clock = FakeClock()
    driver = open_driver(board, request_interval_s=2.0, monotonic=clock)
    try:
        assert board.wait_for(lambda data: requests(data) == 1)
        announce(board, 140, "other", "std_msgs/msg/Bool")  # announced: the keeper leaves it
        assert driver.wait_negotiated(FAILSAFE_S)
        clock.now += 2.0
        publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
        publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
        assert driver.wait_until(lambda: driver.counters["unknown_topic_messages"] == 2, FAILSAFE_S)
        assert board.wait_for(lambda data: requests(data) == 2)
        assert passes(driver)
        assert requests(board.read()) == 2
    finally:
        driver.close()


def test_device_logs_go_to_python_logging(
    board: Board, driver: RosserialDriver, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="botstage.robots.drivers.rosserial.device")
    for level, text in [(rp.ROSDEBUG, "dmp ready"), (rp.WARN, "fifo overflow"), (rp.FATAL, "no imu")]:
        board.send(encode_packet(rp.ID_LOG, rp.serialize(rp.log_message(level, text))))
    assert driver.wait_until(lambda: driver.counters["device_logs"] == 3, FAILSAFE_S)
    records = [(r.levelno, r.getMessage().rsplit(": ", 1)[1]) for r in caplog.records if r.name.endswith(".device")]
    assert records == [(logging.DEBUG, "dmp ready"), (logging.WARNING, "fifo overflow"), (logging.CRITICAL, "no imu")]


def test_garbage_and_bad_packets_are_survived_and_counted(board: Board, negotiated: RosserialDriver) -> None:
    driver = negotiated
    good = encode_packet(IMU_ID, rp.serialize(vector3(1.0, 2.0, 3.0)))
    corrupt = good[:-1] + bytes(((good[-1] + 1) % 256,))
    board.send(b"noise\x00\x01" + good + corrupt + good + good[:12] + good)
    assert driver.wait_until(lambda: driver.counters["messages"] == 3, FAILSAFE_S)
    assert driver.stats()["packets_bad"] == {"garbage": 1, "checksum": 2}
    publish(board, IMU_ID, TYPES["std_msgs/msg/Bool"](data=True))  # framed well, not a Vector3
    assert driver.wait_until(lambda: driver.counters["undecodable"] == 1, FAILSAFE_S)
    board.send(encode_packet(rp.ID_SERVICE_SERVER, b""))
    assert driver.wait_until(lambda: driver.counters["unsupported_endpoint"] == 1, FAILSAFE_S)
    publish(board, IMU_ID, vector3(4.0, 5.0, 6.0))
    assert driver.wait_until(lambda: driver.counters["messages"] == 4, FAILSAFE_S)
    assert ypr(driver) == (4.0, 5.0, 6.0)
    assert driver.link.counters["listener_errors"] == 0


def test_fuzz_a_megabyte_through_the_pty(board: Board, negotiated: RosserialDriver) -> None:
    """Random bytes, cut and corrupted packets around good ones: the reader keeps going and a
    last message, which no other is, tells when the driver has handled all of it."""
    driver = negotiated
    rng = random.Random(7)
    chunks, size = [], 0
    while size < 1_000_000:
        packet = encode_packet(IMU_ID, rp.serialize(vector3(rng.uniform(-180, 180), rng.uniform(-90, 90), 0.0)))
        roll = rng.random()
        if roll < 0.3:
            piece = packet
        elif roll < 0.5:
            piece = packet[: rng.randint(1, len(packet) - 1)]
        elif roll < 0.65:
            index = rng.randrange(len(packet))
            piece = packet[:index] + bytes(((packet[index] + rng.randint(1, 255)) % 256,)) + packet[index + 1 :]
        else:
            piece = rng.randbytes(rng.randint(1, 300))
        chunks.append(piece)
        size += len(piece)
    board.send(b"".join(chunks))
    publish(board, IMU_ID, vector3(0.0, 0.0, 77.0))  # no roll in the fuzz is 77
    assert driver.wait_until(lambda: (driver.orientation() or Orientation(0, 0, 0, 0)).roll == 77.0, FAILSAFE_S)
    bad = driver.stats()["packets_bad"]
    assert bad["garbage"] > 100 and bad["checksum"] > 100
    assert driver.decoder.buffered <= rp.OVERHEAD + rp.DEFAULT_MAX_PAYLOAD
    assert driver.link.counters["listener_errors"] == 0 and driver.link.connected


def test_unplug_and_replug_asks_for_the_topics_again(board: Board, negotiated: RosserialDriver) -> None:
    driver = negotiated
    publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
    assert driver.wait_until(lambda: driver.counters["messages"] == 1, FAILSAFE_S)
    board.unplug()
    # what was learned belongs to that link
    assert driver.wait_until(lambda: not driver.connected and not driver.publishers, FAILSAFE_S)
    assert not driver.negotiated
    assert wait_until(lambda: driver.link.counters["open_failures"] >= 2)
    board.plug()
    assert driver.wait_until(lambda: driver.connected, FAILSAFE_S)
    assert board.wait_for(lambda data: data.startswith(rp.TOPIC_REQUEST))
    publish(board, IMU_ID, vector3(4.0, 5.0, 6.0))  # a device that kept its configuration
    assert driver.wait_until(lambda: driver.counters["unknown_topic_messages"] == 1, FAILSAFE_S)
    announce(board, IMU_ID, "imu_data", VECTOR3)
    publish(board, IMU_ID, vector3(7.0, 8.0, 9.0))
    assert driver.wait_until(lambda: driver.counters["messages"] == 2, FAILSAFE_S)
    assert ypr(driver) == (7.0, 8.0, 9.0)
    stats = driver.stats()
    assert stats["connects"] == 2 and stats["disconnects"] == 1


def test_close_says_tx_stop_last(board: Board, driver: RosserialDriver) -> None:
    driver.close()
    assert board.wait_for(lambda data: data.endswith(rp.TX_STOP))
    assert not driver.connected
    driver.close()  # twice is fine


def test_a_failing_subscriber_does_not_stop_the_others(board: Board, negotiated: RosserialDriver) -> None:
    driver = negotiated
    got: list[Any] = []

    def broken(message: Any, received: float) -> None:
        raise RuntimeError("bug")

    driver.subscribe("imu_data", broken)
    driver.subscribe("imu_data", lambda message, received: got.append(message))
    publish(board, IMU_ID, vector3(1.0, 2.0, 3.0))
    assert driver.wait_until(lambda: len(got) == 1, FAILSAFE_S)
    assert driver.counters["subscriber_errors"] == 1


def test_messages_go_to_the_devices_subscribers(board: Board, driver: RosserialDriver) -> None:
    announce(board, 100, "led", "std_msgs/msg/Bool", side=rp.ID_SUBSCRIBER)
    announce(board, 101, "display", "std_msgs/msg/String", side=rp.ID_SUBSCRIBER, size=16)
    assert driver.wait_until(lambda: len(driver.device_subscribers) == 2, FAILSAFE_S)
    assert driver.publish("/led", TYPES["std_msgs/msg/Bool"](data=True))
    assert board.wait_for(lambda data: any(p.topic_id == 100 for p in PacketDecoder().feed(data)))
    assert [p.payload for p in from_host(board) if p.topic_id == 100] == [b"\x01"]
    assert not driver.publish("display", TYPES["std_msgs/msg/String"](data="more than sixteen bytes"))
    assert driver.counters["publish_oversize"] == 1
    assert not driver.publish("nobody", TYPES["std_msgs/msg/Bool"](data=True))
    with pytest.raises(TypeError):
        driver.publish("led", vector3(1.0, 2.0, 3.0))


def test_parameter_requests_are_answered_from_params(board: Board) -> None:
    driver = open_driver(board, params={"gains": [0.5, 1.5], "mixed": [1, "a"]})
    try:
        for name in ("gains", "mixed", "missing"):
            board.send(encode_packet(rp.ID_PARAMETER_REQUEST, rp.serialize(TYPES[rp.PARAM_REQUEST](name=name))))
        assert driver.wait_until(lambda: driver.counters["parameters_missing"] == 2, FAILSAFE_S)
        assert board.wait_for(
            lambda data: any(p.topic_id == rp.ID_PARAMETER_REQUEST for p in PacketDecoder().feed(data))
        )
        (answer,) = [p for p in from_host(board) if p.topic_id == rp.ID_PARAMETER_REQUEST]
        assert list(rp.deserialize(answer.payload, rp.PARAM_RESPONSE).floats) == [0.5, 1.5]
    finally:
        driver.close()


def test_a_groovy_device_is_told_apart(board: Board, driver: RosserialDriver, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="botstage.robots.drivers.rosserial")
    body = (126).to_bytes(2, "little") + (24).to_bytes(2, "little") + rp.serialize(vector3(1.0, 2.0, 3.0))
    board.send(b"\xff\xff" + body + bytes((rp.checksum(body),)))  # rosserial 0.4: no length checksum
    assert driver.wait_until(lambda: driver.decoder.bad["protocol_version"] == 1, FAILSAFE_S)
    assert passes(driver)
    assert any("groovy" in r.getMessage() for r in caplog.records)
    assert driver.counters["messages"] == 0
