"""The ros2 backend: a mission's devices are proxies of a robot already on a ROS 2 graph.

A fake robot (a botstage node in this process, on a free loopback port) publishes the topics and
collects the commands; the backend is opened through the registry as a run opens it, on a
simulated clock this test moves, so staleness is decided without waiting. Last, the acceptance
line with the independent client (pyzeros, its own process): a mission in its own process reads
the scan pyzeros publishes through the ros2 backend, and pyzeros receives the mission's cmd_vel
as a geometry_msgs/Twist.
"""

from __future__ import annotations

import json
import math
import queue
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from botstage.robots.backend import BackendError, OpenRequest
from botstage.robots.backend_options import OptionSources, resolve
from botstage.robots.backend_registry import BackendRegistry
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import LaserScan, OdometryReading, Pose2D, TrackedPerson, Twist2D
from botstage.robots.profile import Device, Profile, load_profile
from botstage.robots.ros2 import botstage_messages as own
from botstage.robots.ros2 import endpoints, node, readings
from botstage.robots.ros2.backend import Ros2Kind
from botstage.robots.ros2.proxies import ClockRef, Latest, StaleReadingError, anchored
from botstage.robots.ros2.topic_robot import Ros2Backend
from tests.test_ros2_interop import (  # noqa: F401  (pyzeros_codecs is a fixture)
    FAILSAFE_S,
    ClientProcess,
    free_port,
    listening_node,
    publish_until,
    pyzeros_codecs,
    until,
)

CLIENTS = Path(__file__).resolve().parent / "ros2_client"
START = Pose2D(11.0, 10.0, 0.0)


def scan_bot(**interfaces: Device) -> Profile:
    profile, problems, _ = load_profile(CLIENTS / "scan_bot.yaml")
    assert profile is not None, problems
    return profile.model_copy(update={"interfaces": {**profile.interfaces, **interfaces}}) if interfaces else profile


def a_scan(stamp: float = 123.0) -> LaserScan:
    return LaserScan(stamp, -1.0, 0.5, 0.1, 10.0, np.array([1.5, 2.0, np.inf, 3.0, 3.5]))


def odometry_at(x: float, y: float, theta: float) -> Any:
    return readings.odometry_message(OdometryReading(50.0, Pose2D(x, y, theta), Twist2D(0.1, 0.0)))


class FakeRobot:
    """A node standing for a robot: publishes what ``publish`` says until stopped, keeps what it receives."""

    def __init__(self) -> None:
        self.node, self.endpoint = listening_node("fake_robot")
        self.received: dict[str, queue.Queue[Any]] = {}
        self.publishing: dict[str, Callable[[], Any]] = {}
        self._publishers: dict[str, Any] = {}
        self._done = threading.Event()
        for topic, type_name in (
            ("/cmd_vel", "geometry_msgs/msg/Twist"),
            ("/say", "std_msgs/msg/String"),
            ("/display", "std_msgs/msg/String"),
        ):
            self.received[topic] = queue.Queue()
            self.node.subscription(topic, type_name, lambda m, _, q=self.received[topic]: q.put(m))
        self._thread: threading.Thread | None = None

    def publish(self, topic: str, type_name: str, make: Callable[[], Any]) -> None:
        """From now on publish ``make()`` on ``topic`` every 50 ms (replacing what it published)."""
        if topic not in self._publishers:
            self._publishers[topic] = self.node.publisher(topic, type_name)
        self.publishing[topic] = make
        if self._thread is None:
            self._thread = publish_until(self._publish_all, self._done)

    def _publish_all(self) -> None:
        for topic, make in list(self.publishing.items()):
            self._publishers[topic].publish(make())

    def quiet(self) -> None:
        """Stop publishing (the robot's driver died)."""
        self._done.set()
        if self._thread is not None:
            self._thread.join(FAILSAFE_S)

    def next(self, topic: str) -> Any:
        return self.received[topic].get(timeout=FAILSAFE_S)

    def close(self) -> None:
        self.quiet()
        self.node.close()


@pytest.fixture
def robot() -> Iterator[FakeRobot]:
    fake = FakeRobot()
    try:
        yield fake
    finally:
        fake.close()


def open_backend(profile: Profile, clock: SimClock, robot: FakeRobot, **options: Any) -> Ros2Backend:
    request = OpenRequest(profile, START, clock)
    given = OptionSources({"connect": robot.endpoint, "ready_timeout": FAILSAFE_S, **options})
    kind, backend = BackendRegistry.default().open("ros2", request, given)
    assert isinstance(kind, Ros2Kind) and isinstance(backend, Ros2Backend)
    return backend


def advance(clock: SimClock, seconds: float) -> None:
    for _ in range(round(seconds / clock.period)):
        clock.next_tick()


# -- opening -----------------------------------------------------------------------------------


def test_opening_names_every_topic_that_stays_silent(robot: FakeRobot) -> None:
    profile = scan_bot(odometry=Device())
    robot.publish("/scan", "sensor_msgs/msg/LaserScan", lambda: readings.scan_message(a_scan()))
    with pytest.raises(BackendError) as raised:
        open_backend(profile, SimClock(10), robot, ready_timeout=1.0)
    message = raised.value.message
    assert "no message within 1 s on /odom (odometry)" in message
    assert "/scan" not in message  # it arrived
    assert robot.endpoint in message


def test_options_are_checked_and_named(robot: FakeRobot) -> None:
    kind = Ros2Kind()
    options = resolve(kind, None, None, OptionSources({"connect": "tcp/127.0.0.1:7447, tcp/10.0.0.2:7447"}))
    assert options.connect == ["tcp/127.0.0.1:7447", "tcp/10.0.0.2:7447"]
    assert resolve(kind, None, None, OptionSources({"connect": ""})).connect == []
    defaults = resolve(kind)
    assert (defaults.connect, defaults.listen) == (["tcp/127.0.0.1:7447"], ["tcp/127.0.0.1:0"])  # loopback only
    for option, value, words in (
        ("connect", "tcp/127.0.0.1", "is not a Zenoh endpoint"),
        ("domain_id", -1, "domain"),
        ("namespace", "bad ns", "namespace"),
        ("node_name", "9lives", "node name"),
        ("ready_timeout", 0, "greater than 0"),
    ):
        with pytest.raises(BackendError) as raised:
            resolve(kind, None, None, OptionSources({option: value}))
        assert f"option {option!r}" in raised.value.message and words in raised.value.message


def test_listing_the_backends_loads_no_zenoh() -> None:
    """`botstage --help` lists every backend: the ros2 one's transport loads only when a run opens it."""
    code = (
        "import sys; from botstage.robots.backend_registry import BackendRegistry;"
        "BackendRegistry.default().get('ros2');"
        "print(sorted(m for m in ('zenoh', 'rosbags') if m in sys.modules))"
    )
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert shown.strip() == "[]"
    assert (endpoints.DEFAULT_LISTEN, endpoints.ROUTER_LISTEN) == (node.DEFAULT_LISTEN, node.ROUTER_LISTEN)


# -- readings ----------------------------------------------------------------------------------------


def test_a_scan_is_the_robots_restamped_on_the_runs_clock_and_refused_when_stale(robot: FakeRobot) -> None:
    clock = SimClock(10)
    robot.publish("/scan", "sensor_msgs/msg/LaserScan", lambda: readings.scan_message(a_scan()))
    backend = open_backend(scan_bot(), clock, robot)
    try:
        advance(clock, 0.5)
        scan = backend.devices["laser"].scan()
        assert scan.stamp == 0.0  # when it arrived on the run's clock, not the robot's 123 s
        assert list(scan.ranges) == [1.5, 2.0, math.inf, 3.0, 3.5]
        assert (scan.angle_min, scan.angle_increment, scan.range_max) == (-1.0, 0.5, 10.0)
        robot.quiet()
        advance(clock, 0.6)  # 1.1 s after the last message: stale after 1 s
        with pytest.raises(StaleReadingError, match=r"laser: the latest message on /scan is 1\.1 s old"):
            backend.devices["laser"].scan()
        assert backend.summary()["topics"]["/scan"]["stale_reads"] == 1
    finally:
        backend.close()


def test_odometry_starts_where_the_mission_put_the_robot(robot: FakeRobot) -> None:
    clock = SimClock(10)
    pose = {"at": odometry_at(5.0, 5.0, math.pi / 2)}
    robot.publish("/scan", "sensor_msgs/msg/LaserScan", lambda: readings.scan_message(a_scan()))
    robot.publish("/odom", "nav_msgs/msg/Odometry", lambda: pose["at"])
    backend = open_backend(scan_bot(odometry=Device()), clock, robot)
    try:
        odometry = backend.devices["odometry"]
        assert odometry.read().pose == START
        pose["at"] = odometry_at(5.0, 6.0, math.pi / 2)  # a metre forward in the robot's own odom frame
        assert until(lambda: odometry.read().pose.x > START.x + 0.5)
        moved = odometry.read()
        assert (moved.pose.x, moved.pose.y, moved.pose.theta) == pytest.approx((12.0, 10.0, 0.0))
        assert moved.twist == Twist2D(0.1, 0.0)
    finally:
        backend.close()


def test_anchoring_turns_the_covariance_with_the_pose() -> None:
    reading = OdometryReading(1.0, Pose2D(0.0, 2.0, math.pi / 2), Twist2D(0, 0), np.diag([0.04, 0.01, 0.001]))
    moved = anchored(reading, Pose2D(0.0, 0.0, math.pi / 2), Pose2D(1.0, 1.0, 0.0))
    assert (moved.pose.x, moved.pose.y, moved.pose.theta) == pytest.approx((3.0, 1.0, 0.0))
    assert np.allclose(moved.covariance, np.diag([0.01, 0.04, 0.001]))


def test_a_clock_change_keeps_each_readings_instant() -> None:
    old, new = SimClock(10), SimClock(10, start=5.0)
    latest = Latest("laser", "/scan", lambda message: message, ClockRef(old), stale_after=1.0)
    advance(old, 1.0)
    latest.on_message("a scan")
    advance(old, 0.4)
    latest.rebase(old, new)
    _, arrived = latest.get()
    assert arrived == pytest.approx(4.6)


def test_audio_people_and_camera_arrive_as_their_readings(robot: FakeRobot) -> None:
    clock = SimClock(10)
    frame = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    chunks = iter(range(1_000_000))
    robot.publish("/scan", "sensor_msgs/msg/LaserScan", lambda: readings.scan_message(a_scan()))
    robot.publish("/image_raw", "sensor_msgs/msg/Image", lambda: readings.image_message(frame, 1.0))
    robot.publish(
        "/people",
        "botstage_msgs/msg/PeopleTracks",
        lambda: own.people_message([TrackedPerson(7, 0.5, 2.0)], 1.0, 0.8, 4.0),
    )
    robot.publish(
        "/audio",
        "botstage_msgs/msg/AudioChunk",
        lambda: own.audio_message(np.full(160, next(chunks) % 100, np.int16), 1.0),
    )
    devices = {"camera": Device(width=6, height=4), "people": Device(), "microphone": Device()}
    backend = open_backend(scan_bot(**devices), clock, robot)
    try:
        assert np.array_equal(backend.devices["camera"].frame(), frame)
        assert backend.devices["camera"].info.width == 6
        people = backend.devices["people"]
        assert [(p.id, p.x, p.z) for p in people.people()] == [(7, 0.5, 2.0)]
        assert (people.range_min, people.range_max) == pytest.approx((0.8, 4.0))
        microphone = backend.devices["microphone"]
        assert until(lambda: backend.audio._buffered >= 320)
        heard = microphone.read()
        assert heard.dtype == np.int16 and heard.size >= 320 and heard.size % 160 == 0
        assert microphone.read().size < heard.size  # what was read is not heard again
    finally:
        backend.close()


# -- commands ------------------------------------------------------------------------------------------


def test_drive_speaker_and_display_publish_and_close_sends_zero(robot: FakeRobot) -> None:
    clock = SimClock(10)
    speaking = {"now": False}
    robot.publish("/scan", "sensor_msgs/msg/LaserScan", lambda: readings.scan_message(a_scan()))
    robot.publish("/speaking", "std_msgs/msg/Bool", lambda: own.flag_message(speaking["now"]))
    backend = open_backend(scan_bot(speaker=Device(), display=Device()), clock, robot)
    closed = False
    try:
        drive, speaker, display = (backend.devices[name] for name in ("drive", "speaker", "display"))
        sent = threading.Event()
        publish_until(lambda: drive.cmd_vel(0.2, 0.1), sent)
        first = robot.next("/cmd_vel")
        sent.set()
        assert (first.linear.x, first.angular.z) == (0.2, 0.1)
        drive.cmd_vel(9.0, -9.0)  # beyond scan_bot's limits: clamped
        assert until(lambda: _twist_seen(robot, (0.5, -2.0)))
        with pytest.raises(ValueError, match="finite"):
            drive.cmd_vel(math.nan, 0.0)

        assert speaker.busy() is False
        speaker.say("hello")
        assert robot.next("/say").data == "hello"
        assert speaker.busy() is True  # said, not yet confirmed by the robot
        speaking["now"] = True
        assert until(lambda: backend.latest["speaking"].get()[0] is True)
        assert speaker.busy() is True  # the robot says it is talking
        speaking["now"] = False
        assert until(lambda: not speaker.busy())

        display.show("Layout_1", title="Hi", body="there")
        assert own.display_of(robot.next("/display")) == ("Layout_1", {"title": "Hi", "body": "there"})

        backend.close()
        closed = True
        assert until(lambda: _twist_seen(robot, (0.0, 0.0)))
    finally:
        if not closed:
            backend.close()


def _twist_seen(robot: FakeRobot, expected: tuple[float, float]) -> bool:
    """Whether a Twist of (linear.x, angular.z) ``expected`` arrived (the ones before it are consumed)."""
    try:
        while True:
            twist = robot.received["/cmd_vel"].get_nowait()
            if (twist.linear.x, twist.angular.z) == expected:
                return True
    except queue.Empty:
        return False


# -- with the independent client ---------------------------------------------------------------------


def test_a_mission_reads_the_independent_clients_scan_and_the_client_receives_its_cmd_vel(
    pyzeros_codecs: None,  # noqa: F811
    tmp_path: Path,
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"  # the mission's node listens, the client connects
    mission = ClientProcess("scan_mission.py", str(tmp_path / "run"), endpoint)
    probe = ClientProcess("pyzeros_probe.py", endpoint, "/botstage")
    try:
        twist = probe.expect("twist")
        done = mission.expect("done")
    finally:
        probe_code = probe.stop()
        mission_code = mission.stop()
    assert twist is not None, f"the client got no Twist:\n{probe.log()}\n{mission.log()}"
    assert (twist["linear"], twist["angular"]) == ([0.2, 0.0, 0.0], [0.0])  # move's v and w
    assert done is not None and done["outcome"] == "success", f"{done}\n{mission.log()}"
    assert (mission_code, probe_code) == (0, 0)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    counters = summary["counters"]
    assert counters["scan_ranges"] == [1.5, 2.0, 2.5, 3.0, 3.5]  # the client's scan (pyzeros_probe.a_scan)
    assert counters["scan_angle_min"] == -1.0
    assert 0.0 <= counters["scan_age"] <= 1.0  # stamped on the mission's clock, not the client's 7 s
    assert summary["ros2"]["topics"]["/scan"]["received"] > 0
