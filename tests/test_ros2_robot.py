"""Robot processes: `botstage serve robot` serves a robot's devices as ROS 2 topics.

A simulated PeopleBot is served in its own process on a free loopback port; test nodes and
processes drive it over cmd_vel and watch its odometry, its /clock, the watchdog's stops (asserted
on the stamps the server records on its own clock, never on this process's clock), a mission on
the ros2 backend driving it, and a clean exit on SIGTERM. The server's parts are also tested in
this process on a simulated clock, tick by tick, as a lockstep mode will drive them.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from botstage.missions.check import check
from botstage.missions.cli.serve import profile_name, serve_app
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import OdometryReading, Twist2D
from botstage.robots.places import robot_place
from botstage.robots.profile import load_profile
from botstage.robots.ros2 import readings, types
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.robot_server import RobotServer
from botstage.robots.ros2.topics import CHANNELS, routes
from botstage.robots.sim.backend import SimBackend
from tests.test_ros2_interop import FAILSAFE_S, ClientProcess, free_port, listening_node, until

ROOT = Path(__file__).resolve().parent.parent
CLIENTS = Path(__file__).resolve().parent / "ros2_client"
RATE_HZ = 20.0  # the lockstep tests' clock
SERVED_RATE_HZ = 10.0  # the served robot's loop: the watchdog stops it within 0.5 s and one period of it
WATCHDOG_S = 0.5  # peoplebot's control.watchdog_s
TRIP = re.compile(r"watchdog: no cmd_vel .* \(last cmd_vel at ([0-9.]+) s, stopped at ([0-9.]+) s, server clock\)")


def clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH_", "ROS_"))}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


class ServedRobot:
    """`botstage serve robot ...` in its own process: its stdout lines, and the watchdog's trips from its log."""

    def __init__(self, *args: str) -> None:
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        command = [sys.executable, "-m", "botstage.missions.cli", "serve", "robot", *args, "--listen", self.endpoint]
        self.process = subprocess.Popen(
            command, cwd=ROOT, env=clean_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.trips: queue.Queue[tuple[float, float]] = queue.Queue()
        self.log: list[str] = []
        threading.Thread(target=self._read_stdout, daemon=True).start()
        threading.Thread(target=self._read_stderr, daemon=True).start()

    def _read_stdout(self) -> None:
        for line in self.process.stdout:
            self.log.append(line)
            self.lines.put(line.rstrip("\n"))

    def _read_stderr(self) -> None:
        for line in self.process.stderr:
            self.log.append(line)
            match = TRIP.search(line)
            if match:
                self.trips.put((float(match.group(1)), float(match.group(2))))

    def expect_line(self, prefix: str) -> str | None:
        deadline = time.monotonic() + FAILSAFE_S
        while (left := deadline - time.monotonic()) > 0:
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                return None
            if line.startswith(prefix):
                return line
        return None

    def next_trip(self) -> tuple[float, float] | None:
        try:
            return self.trips.get(timeout=FAILSAFE_S)
        except queue.Empty:
            return None

    def drain_trips(self) -> None:
        while not self.trips.empty():
            self.trips.get_nowait()

    def stop(self, sig: int = signal.SIGINT) -> int | None:
        if self.process.poll() is None:
            self.process.send_signal(sig)
        try:
            return self.process.wait(timeout=FAILSAFE_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            return None

    def output(self) -> str:
        return "".join(self.log)[-4000:]


def serve_peoplebot() -> ServedRobot:
    """A simulated PeopleBot in the museum's hall, served; ready (or failed, with its log)."""
    robot = ServedRobot(
        "peoplebot", "--backend", "sim", "--world", "museum", "--start", "hall_centre", "--rate", str(SERVED_RATE_HZ)
    )
    if robot.expect_line("serving ") is None:
        robot.stop()
        pytest.fail(f"the robot process did not come up:\n{robot.output()}")
    return robot


class Observer:
    """A test node on the served robot: its latest odometry and /clock, and a cmd_vel publisher."""

    def __init__(self, endpoint: str) -> None:
        self.node = Ros2Node("observer", connect=[endpoint])
        self.odometry: OdometryReading | None = None
        self.clock: list[float] = []
        self.node.subscription("/odom", "nav_msgs/msg/Odometry", self._on_odom)
        self.node.subscription("/clock", "rosgraph_msgs/msg/Clock", self._on_clock)
        self.cmd_vel = self.node.publisher("/cmd_vel", "geometry_msgs/msg/Twist")

    def _on_odom(self, message: Any, _: Any) -> None:
        self.odometry = readings.odometry_of(message)

    def _on_clock(self, message: Any, _: Any) -> None:
        self.clock.append(readings.seconds_of(message.clock))

    def pose_now(self) -> OdometryReading:
        assert until(lambda: self.odometry is not None), "no odometry from the served robot"
        assert self.odometry is not None
        return self.odometry

    def still(self) -> bool:
        odometry = self.odometry
        return odometry is not None and abs(odometry.twist.v) < 1e-3 and abs(odometry.twist.w) < 1e-3

    def drive_until(self, twist: Twist2D, condition: Any) -> bool:
        """Publish ``twist`` every 50 ms until ``condition()`` holds (or the failsafe)."""
        message = readings.twist_message(twist)
        pace, deadline = threading.Event(), time.monotonic() + FAILSAFE_S
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.cmd_vel.publish(message)
            pace.wait(0.05)
        return True


@pytest.fixture(scope="module")
def served() -> Iterator[ServedRobot]:
    robot = serve_peoplebot()
    try:
        yield robot
    finally:
        robot.stop()


@pytest.fixture
def observer(served: ServedRobot) -> Iterator[Observer]:
    watching = Observer(served.endpoint)
    try:
        yield watching
    finally:
        watching.node.close()


def moved(start: OdometryReading, observer: Observer, metres: float) -> bool:
    odometry = observer.odometry
    return (
        odometry is not None and math.dist((odometry.pose.x, odometry.pose.y), (start.pose.x, start.pose.y)) >= metres
    )


def assert_watchdog_stop(trip: tuple[float, float] | None, robot: ServedRobot) -> None:
    assert trip is not None, f"the watchdog never stopped the robot:\n{robot.output()}"
    last_command, stopped_at = trip
    assert WATCHDOG_S < stopped_at - last_command <= WATCHDOG_S + 1 / SERVED_RATE_HZ, trip


# -- the served robot, from other processes -----------------------------------------------------


def test_a_simulated_robot_publishes_clock_and_lists_its_topics(served: ServedRobot, observer: Observer) -> None:
    assert until(lambda: len(observer.clock) >= 5), f"no /clock:\n{served.output()}"
    times = list(observer.clock)
    assert all(b > a for a, b in itertools.pairwise(times)), times
    graph = observer.node.graph()
    assert "/peoplebot" in graph.node_names()
    topics = graph.topic_names_and_types()
    for name, type_name in (
        ("/cmd_vel", "geometry_msgs/msg/Twist"),
        ("/odom", "nav_msgs/msg/Odometry"),
        ("/scan", "sensor_msgs/msg/LaserScan"),
        ("/people", "botstage_msgs/msg/PeopleTracks"),
        ("/image_raw", "sensor_msgs/msg/Image"),
        ("/audio", "botstage_msgs/msg/AudioChunk"),
        ("/battery_state", "sensor_msgs/msg/BatteryState"),
        ("/say", "std_msgs/msg/String"),
        ("/speaking", "std_msgs/msg/Bool"),
        ("/display", "std_msgs/msg/String"),
        ("/clock", "rosgraph_msgs/msg/Clock"),
    ):
        assert type_name in topics.get(name, []), (name, topics)


def test_cmd_vel_drives_the_robot_and_the_watchdog_stops_it_when_commands_stop(
    served: ServedRobot, observer: Observer
) -> None:
    start = observer.pose_now()
    served.drain_trips()
    assert observer.drive_until(Twist2D(0.3, 0.0), lambda: moved(start, observer, 0.1)), served.output()
    assert_watchdog_stop(served.next_trip(), served)  # nothing more is published: the robot's watchdog
    assert until(observer.still), f"the robot kept moving: {observer.odometry}"


def test_the_watchdog_stops_the_robot_when_the_driving_process_is_killed(
    served: ServedRobot, observer: Observer
) -> None:
    served.drain_trips()
    driver = ClientProcess("cmd_vel_sender.py", served.endpoint, "0.2", "0.0")
    try:
        assert driver.expect("ready") is not None, driver.log()
        assert until(lambda: observer.odometry is not None and observer.odometry.twist.v > 0.1), driver.log()
        driver.process.send_signal(signal.SIGKILL)  # the mission process dies: nobody sends a zero
        driver.process.wait(timeout=FAILSAFE_S)
        assert_watchdog_stop(served.next_trip(), served)
        assert until(observer.still), f"the robot kept moving: {observer.odometry}"
    finally:
        driver.stop()


def test_a_mission_on_the_ros2_backend_drives_the_served_robot(
    served: ServedRobot, observer: Observer, tmp_path: Path
) -> None:
    before = observer.pose_now()
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "run",
        str(CLIENTS / "drive_served.yaml"),
        "--backend",
        "ros2",
        "--backend-opt",
        f"connect={served.endpoint}",
        "--backend-opt",
        "ready_timeout=60",
        "--out",
        str(tmp_path / "run"),
    ]
    result = subprocess.run(command, cwd=ROOT, env=clean_env(), capture_output=True, text=True, timeout=FAILSAFE_S * 2)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert (summary["backend"], summary["outcome"]) == ("ros2", "success")
    assert summary["skill_outcomes"] == {"move": {"success": 1}}
    assert summary["ros2"]["velocity_commands"] >= 20  # 2 s at 10 Hz, and the stop
    assert summary["ros2"]["topics"]["/odom"]["received"] > 0
    assert until(observer.still)
    after = observer.pose_now()
    assert math.dist((after.pose.x, after.pose.y), (before.pose.x, before.pose.y)) > 0.3  # 2 s at 0.3 m/s
    assert abs(after.pose.theta - before.pose.theta) > 0.2  # and 0.3 rad/s


def test_sigterm_stops_the_robot_leaves_the_graph_and_exits_zero() -> None:
    robot = serve_peoplebot()
    watching = Observer(robot.endpoint)
    try:
        assert until(lambda: "/peoplebot" in watching.node.graph().node_names())
        assert robot.stop(signal.SIGTERM) == 0, robot.output()
        assert robot.expect_line("stopped") is not None, robot.output()
        assert until(lambda: "/peoplebot" not in watching.node.graph(timeout=0.5).node_names())
    finally:
        robot.stop()
        watching.node.close()


# -- the server's parts, tick by tick on a simulated clock --------------------------------------


@pytest.fixture
def lockstep() -> Iterator[tuple[RobotServer, SimClock, SimBackend]]:
    profile, grid, pose = robot_place("peoplebot", "museum", "hall_centre")
    clock = SimClock(RATE_HZ)
    backend = SimBackend(profile, grid, pose, 0, clock, people=3)
    node = Ros2Node("lockstep")
    server = RobotServer(backend, node, clock, routes(profile), publish_clock=True)
    try:
        yield server, clock, backend
    finally:
        server.close()


def tick(server: RobotServer, clock: SimClock) -> None:
    server.take_commands()
    clock.next_tick()
    server.advance()


def test_every_channel_reads_now_as_its_message(lockstep: tuple[RobotServer, SimClock, SimBackend]) -> None:
    server, clock, _ = lockstep
    for _ in range(4):
        tick(server, clock)
    for route in server.readings:
        message = server.message_now(route.key)
        assert message is not None, route.key
        assert message.__msgtype__ == route.channel.type_name
        types.serialize(message)  # each goes on the wire as it is
    scan = server.message_now("laser")
    assert (scan.header.stamp.sec, scan.header.stamp.nanosec) == (0, 200_000_000)  # the clock's time: 4 ticks
    assert len(scan.ranges) == 181
    assert set(server.counts) >= {f"{key}_published" for key in ("odometry", "laser", "people", "camera", "microphone")}


def test_commands_are_applied_on_the_loop_and_the_watchdog_trips_once_per_silence(
    lockstep: tuple[RobotServer, SimClock, SimBackend],
) -> None:
    server, clock, backend = lockstep
    server._on_twist(readings.twist_message(Twist2D(0.4, 0.0)), None)  # as Zenoh's thread delivers it
    assert backend.world._command == (0.0, 0.0)  # queued: devices are touched by the loop only
    tick(server, clock)
    assert backend.world._command == (0.4, 0.0)
    while clock.now() < 0.5 + 1e-9:
        tick(server, clock)
        assert server.watchdog.trips == []
    for _ in range(3):
        tick(server, clock)
    assert [(t.last_command, t.stopped_at) for t in server.watchdog.trips] == [(0.0, pytest.approx(0.55))]
    assert backend.world._command == (0.0, 0.0)
    server._on_twist(readings.twist_message(Twist2D(0.1, 0.2)), None)
    tick(server, clock)
    assert backend.world._command == (0.1, 0.2) and len(server.watchdog.trips) == 1  # re-armed


def test_say_display_and_bad_commands(lockstep: tuple[RobotServer, SimClock, SimBackend]) -> None:
    server, clock, backend = lockstep
    String = types.message_class("std_msgs/msg/String")
    server._on_say(String(data="hello there"), None)
    server._on_display(String(data=json.dumps({"layout": "Layout_1", "content": {"title": "Hi"}})), None)
    server._on_display(String(data="not json"), None)
    not_a_number = readings.twist_message(Twist2D(0.0, 0.0))
    not_a_number.linear.x = math.nan
    server._on_twist(not_a_number, None)
    tick(server, clock)
    assert [text for _, text in backend.devices["speaker"].said] == ["hello there"]
    assert [(layout, content) for _, layout, content in backend.devices["display"].shown] == [
        ("Layout_1", {"title": "Hi"})
    ]
    assert server.message_now("speaking").data is True
    assert (server.counts["display_rejected"], server.counts["cmd_vel_rejected"]) == (1, 1)
    assert server.watchdog.last_command is None  # a rejected command arms nothing


def test_close_stops_the_drive_and_undeclares(lockstep: tuple[RobotServer, SimClock, SimBackend]) -> None:
    server, _, backend = lockstep
    backend.world.cmd_vel(0.3, 0.0)
    server.close()
    assert backend.world._command == (0.0, 0.0)
    assert server.node.closed


# -- the profile's ros2 section and the command line ------------------------------------------------


def test_routes_take_names_and_rates_from_the_profile_else_ros_defaults() -> None:
    profile, _, _ = load_profile(ROOT / "robots" / "profiles" / "peoplebot.yaml")
    assert profile is not None
    by_key = {route.key: route for route in routes(profile)}
    assert set(by_key) == {
        "drive",
        "odometry",
        "laser",
        "people",
        "camera",
        "microphone",
        "speaker",
        "speaking",
        "display",
        "battery",
    }
    assert (by_key["drive"].topic, by_key["laser"].topic, by_key["camera"].rate_hz) == ("cmd_vel", "scan", 5.0)
    assert by_key["odometry"].rate_hz == CHANNELS["odometry"].rate_hz
    renamed = profile.model_copy(update={"ros2": profile.ros2.model_copy(update={"topics": {"laser": "base_scan"}})})
    assert {route.key: route.topic for route in routes(renamed)}["laser"] == "base_scan"


def test_a_bad_ros2_section_is_a_located_error_from_the_ros2_backend(tmp_path: Path) -> None:
    """The profile's `ros2:` section is the ros2 backend's to check (the core only reads its shape):
    checking a mission on that robot reports each problem where it is written."""
    text = (ROOT / "robots" / "profiles" / "chefbot.yaml").read_text()
    text = (
        text.split("\nros2:")[0]
        + "\nros2:\n  topics: {lazer: scan, odometry: 9odom, camera: image}\n  rates_hz: {drive: 10}\n"
    )
    path = tmp_path / "bot.yaml"
    path.write_text(text)
    _, problems, _ = load_profile(path)
    assert problems == []  # not the core's business
    mission = tmp_path / "mission.yaml"
    mission.write_text(
        "name: m\nrobot: bot.yaml\nmachine:\n  outcomes: [done]\n  states:\n"
        "    waiting: {skill: wait, inputs: {duration: 1}, transitions: {success: done, failure: done}}\n"
    )
    checked = check(mission)
    shown = [str(problem).split(": error: ", 1)[1] for problem in checked.problems]
    assert sorted(shown) == sorted(
        [
            "ros2: unknown channel 'lazer' (did you mean 'laser'?)",
            "ros2: the robot has no 'camera' interface (list it under interfaces:)",
            "ros2: 'drive' is a command: its rate is its sender's",
            "ros2: topic name '9odom': a token must not start with a digit (index 0)",
        ]
    )
    assert all(str(problem).startswith(f"{path}:") for problem in checked.problems)


def cli(*args: str) -> Any:
    app = typer.Typer()
    app.add_typer(serve_app, name="serve")

    @app.callback()
    def _root() -> None:
        """botstage."""

    return CliRunner().invoke(app, ["serve", "robot", *args])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["peoplebot", "--backend", "ros2"], "--backend ros2 drives a robot already on the graph"),
        (["peoplebot", "--listen", "tcp/127.0.0.1"], "is not a Zenoh endpoint"),
        (["peoplebot", "--namespace", "bad ns"], "namespace"),
        (["nobot"], "unknown robot 'nobot'"),
        (["peoplebot", "--backend", "sim", "--world", "moon"], "unknown world 'moon'"),
        (["peoplebot", "--domain-id", "-1"], "greater than or equal to 0"),
    ],
)
def test_usage_errors_exit_2_before_anything_starts(args: list[str], message: str) -> None:
    result = cli(*args)
    assert result.exit_code == 2, result.output
    assert message in result.output


def test_a_taken_port_is_an_error_that_says_what_to_do() -> None:
    holder, endpoint = listening_node("holder")
    try:
        result = cli("peoplebot", "--listen", endpoint)
    finally:
        holder.close()
    assert result.exit_code == 1, result.output
    assert f"cannot open the ROS 2 node on {endpoint}" in result.output
    assert "--listen tcp/127.0.0.1:0 --connect tcp/127.0.0.1:7447" in result.output


def test_node_names_come_from_the_profile() -> None:
    assert profile_name("peoplebot") == "peoplebot"
    assert profile_name("robots/my-bot.yaml") == "my_bot"
    assert profile_name("2d.yaml") == "robot_2d"
