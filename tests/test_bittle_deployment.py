"""The Bittle article's split as a deployment: the robot process on the Pi, the mission and teleop on the PC.

``missions/deployments/bittle_pi_pc.yaml`` runs with real processes on loopback, talking over
real Zenoh sessions in ROS 2's wire format:

- ``botstage up`` runs the patrol as two processes and leaves the one-process run's trace with
  the same seed, even while an operator publishes ``cmd_vel`` meanwhile (the robot process refuses
  it: the mission drives);
- ``botstage teleop bittle --connect`` walks the simulated Bittle the Pi's process serves: letting
  go stops it (teleop sends the zero; the watchdog's later trip finds it standing), and a teleop
  killed while walking leaves it to the robot process's 0.5 s watchdog;
- the Pi's process on its own backend (``--backend emulator``: the emulated NyBoard, the driver
  on a pty) is walked the same way, and the patrol runs over it in real time;
- a secured Pi (mutual TLS, across machines) is driven by a teleop with the operator's
  certificate, and by nobody without one.

What is asserted is what happened (the robot moved, it stopped, who stopped it, the traces),
never how long it took on the wall: a failsafe bounds each wait.
"""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.cli.distributed import free_port, process_commands
from botstage.missions.deployment import OPERATOR, check_deployment
from botstage.missions.distributed.operator import Operator
from botstage.missions.distributed.supervisor import Supervisor
from botstage.missions.runner import run
from botstage.robots.clock import SimClock, WallClock
from botstage.robots.interfaces import OdometryReading, Twist2D
from botstage.robots.places import robot_place
from botstage.robots.ros2 import readings
from botstage.robots.ros2.certs import Credentials, make_certificates
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.security import security_options
from botstage.robots.ros2.teleop import open_served
from botstage.robots.ros2.topics import routes
from botstage.robots.sim.backend import SimBackend
from botstage.robots.teleop import Teleop, run_teleop
from tests.test_ros2_interop import listening_node

ROOT = Path(__file__).resolve().parent.parent
DEPLOYMENT = ROOT / "missions" / "deployments" / "bittle_pi_pc.yaml"
PATROL = ROOT / "missions" / "examples" / "bittle_patrol.yaml"
SEED, UNTIL = 2, 12.0  # with this seed a guest steps into Bittle's way at 7.2 s, after its first leg
FAILSAFE_S = 120.0  # a bound for what must happen, never a measure
WATCHDOG_S = 0.5  # bittle's control.watchdog_s
STOPPED = re.compile(r"watchdog: no cmd_vel for ([0-9.]+) s: drive stopped$")
ALREADY = re.compile(r"watchdog: no cmd_vel for ([0-9.]+) s: drive stopped \(it was told to stop already\)$")


@dataclass(frozen=True)
class Line:
    at: float  # monotonic, when it reached this process
    process: str
    text: str


class Lines:
    """Every line some processes print, kept with its arrival; waits for one to come."""

    def __init__(self) -> None:
        self.lines: list[Line] = []
        self._changed = threading.Condition()

    def keep(self, process: str, text: str) -> None:
        print(f"{process:>8} | {text}")
        with self._changed:
            self.lines.append(Line(time.monotonic(), process, text))
            self._changed.notify_all()

    def expect(self, process: str, pattern: str | re.Pattern[str], after: float = 0.0) -> Line:
        found = re.compile(pattern)

        def match() -> Line | None:
            return next((x for x in self.lines if x.process == process and x.at > after and found.search(x.text)), None)

        with self._changed:
            line = self._changed.wait_for(match, FAILSAFE_S)
        assert line is not None, f"{process} never said {found.pattern!r}: {[x.text for x in self.lines][-20:]}"
        return line

    def said(self, process: str, pattern: str | re.Pattern[str]) -> list[Line]:
        with self._changed:
            return [x for x in self.lines if x.process == process and re.search(pattern, x.text)]


class Watcher:
    """A test node on the graph: the robot's odometry as it comes, and every cmd_vel anyone publishes."""

    def __init__(self, endpoint: str, security: dict[str, Any] | None = None) -> None:
        listen = ["tls/127.0.0.1:0"] if security else ["tcp/127.0.0.1:0"]
        self.node = Ros2Node("watcher", listen=listen, connect=[endpoint], options=security)
        self.odometry: list[OdometryReading] = []
        self.twists: list[Twist2D] = []
        self._changed = threading.Condition()
        self.node.subscription("/odom", "nav_msgs/msg/Odometry", self._on_odom)
        self.node.subscription("/cmd_vel", "geometry_msgs/msg/Twist", self._on_twist)
        self.cmd_vel = self.node.publisher("/cmd_vel", "geometry_msgs/msg/Twist")

    def _on_odom(self, message: Any, _: Any) -> None:
        with self._changed:
            self.odometry.append(readings.odometry_of(message))
            self._changed.notify_all()

    def _on_twist(self, message: Any, _: Any) -> None:
        with self._changed:
            self.twists.append(readings.twist_of(message))

    def wait_for(self, condition: Callable[[], bool]) -> bool:
        with self._changed:
            return self._changed.wait_for(condition, FAILSAFE_S)

    def latest(self) -> OdometryReading | None:
        with self._changed:
            return self.odometry[-1] if self.odometry else None

    def moved_from(self, start: OdometryReading, metres: float) -> Callable[[], bool]:
        def far() -> bool:
            now = self.odometry[-1] if self.odometry else None
            return now is not None and math.dist((now.pose.x, now.pose.y), (start.pose.x, start.pose.y)) >= metres

        return far

    def assert_standing(self, since: int) -> None:
        """Odometry published after message ``since`` shows the robot standing: no speed, the pose unchanged."""
        with self._changed:
            settled = self._changed.wait_for(lambda: len(self.odometry) >= since + 8, FAILSAFE_S)
            last = self.odometry[since + 3 :]  # a message or two may have left before the stop
        assert settled, "the robot stopped publishing its odometry"
        assert all(abs(o.twist.v) < 1e-6 and abs(o.twist.w) < 1e-6 for o in last), [o.twist for o in last]
        poses = {(round(o.pose.x, 6), round(o.pose.y, 6), round(o.pose.theta, 6)) for o in last}
        assert len(poses) == 1, poses

    def close(self) -> None:
        self.node.close()


def states(trace: Path) -> list[str]:
    events = [json.loads(line) for line in trace.read_text(encoding="utf-8").splitlines()]
    return [f"{e['ev']}:{e.get('key')}={e.get('new')}" for e in events if e["ev"] == "bb_write"]


# -- the file ---------------------------------------------------------------------------------------


def test_the_deployment_is_valid_the_pi_serves_the_robot_and_the_pc_runs_the_patrol() -> None:
    checked = check_deployment(DEPLOYMENT)
    assert checked.ok, [str(p) for p in checked.problems]
    assert checked.deployment is not None and checked.mission is not None
    assert checked.mission_process == "pc" and checked.router == "pi"
    assert checked.interface_hosts() == dict.fromkeys(["drive", "odometry", "battery", "camera"], "pi")
    assert set(checked.skill_hosts().values()) == {"pc"}  # watch_people reads the Pi camera's frames there
    pi = checked.deployment.processes["pi"]
    assert pi.backend == "sim" and pi.topics


def test_topics_without_a_backend_are_a_located_error(tmp_path: Path) -> None:
    path = tmp_path / "d.yaml"
    path.write_text(f"name: d\nmission: {PATROL}\nprocesses:\n  pc: {{mission: true, topics: true}}\n")
    assert [str(p).replace(str(path), "d.yaml") for p in check_deployment(path).problems] == [
        "d.yaml:4:23: error: process 'pc' serves topics but opens no backend (add `backend: sim` or another)"
    ]


# -- the mission, distributed -----------------------------------------------------------------------


def test_botstage_up_runs_the_patrol_as_one_process_does_and_refuses_cmd_vel_meanwhile(tmp_path: Path) -> None:
    port, lines = free_port(), Lines()
    command = [sys.executable, "-m", "botstage.missions.cli", "up", str(DEPLOYMENT), "--port", str(port)]
    command += ["--seed", str(SEED), "--until", str(UNTIL), "--out", str(tmp_path / "two")]
    up = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def relay() -> None:
        assert up.stdout is not None
        for raw in up.stdout:
            process, _, text = raw.rstrip("\n").partition(" | ")
            lines.keep(process.strip() if text else "up", text or raw.rstrip("\n"))

    reader = threading.Thread(target=relay, daemon=True)
    reader.start()
    watcher = None
    try:
        # from when the Pi sees the mission (before, an operator's cmd_vel would drive: nobody else does)
        lines.expect("pi", "mission 'pc' is on the graph: it drives the robot")
        watcher = Watcher(f"tcp/127.0.0.1:{port}")
        operator, refused = readings.twist_message(Twist2D(0.1, 0.0)), threading.Event()
        while not refused.is_set() and up.poll() is None:  # an operator pushes the stick while the mission drives
            watcher.cmd_vel.publish(operator)
            if lines.said("pi", "cmd_vel refused: mission 'pc' drives the robot"):
                refused.set()
            refused.wait(0.1)
        assert up.wait(timeout=FAILSAFE_S * 3) == 0, [x.text for x in lines.lines][-30:]
    finally:
        if watcher is not None:
            watcher.close()
        if up.poll() is None:
            up.send_signal(signal.SIGINT)
            up.wait(timeout=FAILSAFE_S)
        reader.join(timeout=FAILSAFE_S)
    assert lines.said("pi", "cmd_vel refused: mission 'pc' drives the robot")
    assert not lines.said("pi", "runs in real time")  # the mission's ticks alone moved the robot's world
    run(PATROL, seed=SEED, until=UNTIL, out=tmp_path / "one")
    two, one = (json.loads((tmp_path / r / "summary.json").read_text()) for r in ("two", "one"))
    assert (two["outcome"], two["counters"]) == (one["outcome"], one["counters"])
    assert one["counters"]["legs_walked"] >= 1
    written = states(tmp_path / "one" / "trace.jsonl")
    assert "bb_write:person_ahead=True" in written  # the run covers a guest in Bittle's way
    assert states(tmp_path / "two" / "trace.jsonl") == written
    assert (tmp_path / "two" / "trace.jsonl").read_bytes() == (tmp_path / "one" / "trace.jsonl").read_bytes()


# -- teleop over the deployment ---------------------------------------------------------------------


class Pi:
    """The deployment's Pi process alone (``serve process ... pi``), listening on a free loopback port."""

    def __init__(self, out: Path, *backend: str, certs: Path | None = None) -> None:
        self.port = free_port()
        self.endpoint = f"{'tls' if certs else 'tcp'}/127.0.0.1:{self.port}"
        command = process_commands(DEPLOYMENT, self.endpoint, out=out, certs=certs)["pi"] + list(backend)
        self.lines = Lines()
        self.supervisor = Supervisor({"pi": command}, self.lines.keep, cwd=str(ROOT))

    def __enter__(self) -> Pi:
        self.supervisor.start()
        self.lines.expect("pi", "pi ready")
        return self

    def __exit__(self, *_: object) -> None:
        self.supervisor.stop()


@pytest.fixture(scope="module")
def pi(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Pi]:
    with Pi(tmp_path_factory.mktemp("pi")) as served:
        yield served


@pytest.fixture
def watcher(pi: Pi) -> Iterator[Watcher]:
    watching = Watcher(pi.endpoint)
    try:
        yield watching
    finally:
        watching.close()


class Hand:
    """Keys for teleop: ``keys`` one a tick, then nothing held down until ``let_go()`` says so (or the failsafe)."""

    def __init__(self, keys: str, let_go: Callable[[], bool]) -> None:
        self.pending, self.let_go = list(keys), let_go
        self.deadline = time.monotonic() + FAILSAFE_S

    def read(self) -> list[str]:
        if self.pending:
            return [self.pending.pop(0)]
        return ["q"] if self.let_go() or time.monotonic() > self.deadline else []


def walk_and_let_go(endpoint: str, watcher: Watcher, metres: float, security: dict[str, Any] | None = None) -> Any:
    """Teleop in this process walks Bittle (two presses of w: 0.1 m/s) until it has gone ``metres``, then quits."""
    profile, _, pose = robot_place("bittle", "restaurant", "dock")
    clock = WallClock(10.0)
    served = open_served(profile, pose, clock, [endpoint], security=security)
    try:
        assert watcher.wait_for(lambda: bool(watcher.odometry)), "no odometry from the Pi"
        start = watcher.latest()
        assert start is not None
        state = Teleop(profile.base.max_linear, profile.base.max_angular)
        run_teleop(served.devices["drive"], Hand("ww", watcher.moved_from(start, metres)), clock, state)
        assert watcher.moved_from(start, metres)(), "teleop did not walk the robot"
    finally:
        served.close()
    return start


def assert_trip(line: Line, pattern: re.Pattern[str]) -> None:
    """A watchdog trip the robot process said: after a silence longer than its timeout (on its own clock)."""
    match = pattern.search(line.text)
    assert match is not None, line
    assert float(match.group(1)) > WATCHDOG_S, line


def test_teleop_walks_the_served_bittle_and_letting_go_stops_it(pi: Pi, watcher: Watcher) -> None:
    walk_and_let_go(pi.endpoint, watcher, 0.1)
    released = time.monotonic()
    assert watcher.twists and watcher.twists[-1] == Twist2D(0.0, 0.0)  # teleop said stop as it ended
    assert any(t.v > 0.05 for t in watcher.twists)
    assert_trip(pi.lines.expect("pi", ALREADY, after=released), ALREADY)  # the silence after found it standing
    watcher.assert_standing(len(watcher.odometry))


def test_a_killed_teleop_leaves_the_walking_bittle_to_the_robot_s_watchdog(
    pi: Pi, watcher: Watcher, tmp_path: Path
) -> None:
    keys = tmp_path / "keys"
    keys.write_text("ww" + "." * 3000)  # two presses of w, then keys that change nothing: walking on at 0.1 m/s
    assert watcher.wait_for(lambda: bool(watcher.odometry)), "no odometry from the Pi"
    start = watcher.latest()
    assert start is not None
    command = [sys.executable, "-m", "botstage.missions.cli", "teleop", "bittle", "--connect", pi.endpoint]
    with keys.open() as stdin:
        teleop = subprocess.Popen(command, cwd=ROOT, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        assert watcher.wait_for(watcher.moved_from(start, 0.1)), "teleop did not walk the robot"
        killed = time.monotonic()
        teleop.send_signal(signal.SIGKILL)  # nobody sends the zero
        teleop.wait(timeout=FAILSAFE_S)
    finally:
        if teleop.poll() is None:
            teleop.kill()
            teleop.wait()
    assert watcher.twists and watcher.twists[-1].v > 0.05  # the last word was "walk"
    assert_trip(pi.lines.expect("pi", STOPPED, after=killed), STOPPED)
    watcher.assert_standing(len(watcher.odometry))


def test_the_pi_s_process_on_its_own_backend_is_walked_and_stopped_the_same_way(tmp_path: Path) -> None:
    with Pi(tmp_path / "pi", "--backend", "emulator") as emulated:  # the driver on a pty to the emulated NyBoard
        watching = Watcher(emulated.endpoint)
        try:
            walk_and_let_go(emulated.endpoint, watching, 0.05)
            released = time.monotonic()
            assert watching.twists[-1] == Twist2D(0.0, 0.0)
            assert_trip(emulated.lines.expect("pi", ALREADY, after=released), ALREADY)
            watching.assert_standing(len(watching.odometry))
        finally:
            watching.close()
        assert emulated.lines.said("pi", "cmd_vel: the robot runs in real time")


def test_the_patrol_over_the_pi_s_process_on_the_emulated_nyboard_runs_in_real_time(tmp_path: Path) -> None:
    commands = process_commands(DEPLOYMENT, f"tcp/127.0.0.1:{free_port()}", out=tmp_path / "run", until=8.0)
    commands["pi"] += ["--backend", "emulator"]  # the Pi's own backend: the driver and the NyBoard on a pty
    lines = Lines()
    supervisor = Supervisor(commands, lines.keep, cwd=str(ROOT))
    supervisor.start()
    try:
        assert supervisor.wait("pc", FAILSAFE_S) == 0, [x.text for x in lines.lines][-20:]
    finally:
        supervisor.stop()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "time_limit" and summary["counters"]["legs_walked"] >= 1  # a leg in 8 s
    assert "overruns" in summary  # the mission ran on a wall clock, as the robot's board does
    robot = summary["remote"]
    assert robot["distance_m"] > 0.2 and robot["serial"]["tokens_sent"] >= 2 and not robot["serial"]["lines_bad"]
    assert lines.said("pi", "mission 'pc' left after its run ended")  # which stopped the robot itself


def test_a_secured_pi_is_driven_by_a_teleop_with_a_certificate_of_the_deployment_only(tmp_path: Path) -> None:
    make_certificates(tmp_path / "certs", ["pi", "pc", OPERATOR])  # as `botstage certs --deployment` does
    operator = security_options(Credentials.in_folder(tmp_path / "certs" / OPERATOR))  # teleop's identity
    profile, _, pose = robot_place("bittle", "restaurant", "dock")
    with Pi(tmp_path / "pi", certs=tmp_path / "certs") as secured:
        with pytest.raises(ConnectionError, match="no odometry within 3 s"):  # no certificate: no session at all
            open_served(profile, pose, WallClock(10.0), [f"tcp/127.0.0.1:{secured.port}"], ready_timeout=3.0)
        assert not secured.lines.said("pi", "cmd_vel:")  # the robot never heard it
        watching = Watcher(secured.endpoint, operator)
        try:
            walk_and_let_go(secured.endpoint, watching, 0.05, operator)
        finally:
            watching.close()
        assert secured.lines.said("pi", "cmd_vel: the robot runs in real time")


def test_who_drives_a_served_robot_passes_between_the_operator_and_a_mission() -> None:
    """The Pi's topics in this process (``Operator``), a test saying when a mission is on the graph."""
    profile, grid, pose = robot_place("bittle", "restaurant", "10,7,0")
    clock = SimClock(5.0)
    backend = SimBackend(profile, grid, pose, 2, clock)
    node, endpoint = listening_node("pi")
    mission: list[str | None] = [None]
    lines = Lines()
    operator = Operator(
        backend,
        node,
        clock,
        routes(profile),
        held=lambda: mission[0],
        lock=threading.Lock(),
        say=lambda text: lines.keep("pi", text),
        watchdog_s=profile.control.watchdog_s,
    ).start()
    watching = Watcher(endpoint)
    walk = readings.twist_message(Twist2D(0.1, 0.0))

    def push_until(pattern: str, after: float) -> Line:
        """cmd_vel every 0.1 s until the robot process says ``pattern``."""
        pace = threading.Event()
        while not lines.said("pi", pattern) or lines.said("pi", pattern)[-1].at <= after:
            watching.cmd_vel.publish(walk)
            pace.wait(0.1)
        return lines.expect("pi", pattern, after)

    try:
        first = push_until("cmd_vel: the robot runs in real time", 0.0)
        assert watching.wait_for(lambda: len(watching.odometry) >= 3)
        mission[0] = "pc"  # a mission came: it drives
        paused = lines.expect("pi", "the mission drives the robot: real time paused", first.at)
        push_until("cmd_vel refused: mission 'pc' drives the robot", paused.at)
        mission[0] = None  # it left: still again until the next cmd_vel
        again = push_until("cmd_vel: the robot runs in real time", paused.at)
        assert len(lines.said("pi", "runs in real time")) == 2 and again.at > paused.at
        assert operator.summary()["counts"]["cmd_vel_refused"] >= 1
    finally:
        watching.close()
        operator.close()
        backend.close()
        node.close()
