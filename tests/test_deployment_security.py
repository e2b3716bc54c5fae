"""Secured deployments: mutual TLS for every process and the access policy derived from the file.

The policy is checked rule by rule on the paper's five computers; a secured deployment runs with
real processes (``botstage up --secure``) to the same counters as an unsecured one, so the
default-deny policy closes nothing the deployment needs; a process of the deployment that is not
the mission cannot call another's skills, in a real secured process; and a process with a valid
certificate of the deployment that is neither the mission nor the operator (the gallery's
computer) cannot move the robot through its command topics, while those two can, on real Zenoh
sessions with the certificates ``botstage certs --deployment`` makes. How Zenoh enforces a
policy is tested in tests/test_ros2_security.py.
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

import pytest
import typer
import zenoh
from typer.testing import CliRunner

from botstage.missions.cli.certs import certs as certs_command
from botstage.missions.cli.distributed import free_port
from botstage.missions.deployment import OPERATOR, check_deployment
from botstage.missions.distributed.process import DeploymentError, serve_process
from botstage.missions.distributed.security import (
    SecurityError,
    command_topics,
    credentials,
    deployment_policy,
    secured,
    session_options,
)
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import Twist2D
from botstage.robots.places import robot_place
from botstage.robots.ros2 import readings, types
from botstage.robots.ros2.certs import Credentials, make_certificates
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.robot_server import RobotServer
from botstage.robots.ros2.security import ACCESS_CONTROL, access_control, security_options
from botstage.robots.ros2.service import ServiceError
from botstage.robots.ros2.topics import routes
from botstage.robots.sim.backend import SimBackend
from botstage.skills.registry import Registry
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import Call, Step, TickRequest, request_fields
from botstage.skills.remote.ros2_link import SERVICE_TYPE, SkillTickLink, serve_skill_host, service_name
from tests.test_ros2_security import _ingress_only, wait_matching

ROOT = Path(__file__).resolve().parent.parent
FIVE = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
DEPLOYMENTS = ROOT / "tests" / "deployments"
FAILSAFE_S = 120.0  # a bound for what must happen, never a measure
STRING = "std_msgs/msg/String"


def test_only_the_mission_calls_skills_steps_processes_and_publishes_the_clock() -> None:
    checked = check_deployment(FIVE)
    policy = deployment_policy(checked)
    names = list(checked.deployment.processes)  # type: ignore[union-attr]
    assert list(policy.processes) == [*names, OPERATOR]  # teleop's identity is known, and nothing else
    assert list(policy.forwarders) == ["navigation_computer"]  # the router
    assert policy.publishers["/clock"] == ["navigation_computer"]
    everyone_else = [n for n in [*names, OPERATOR] if n != "navigation_computer"]
    for name in names:
        for service in (f"/{name}/skill_tick", f"/{name}/skills", f"/{name}/lockstep"):
            assert policy.callers[service] == ["navigation_computer"], service
            assert policy.denied(policy.callers[service]) == everyone_else
    # every process here runs the mission or skills: all may call devices (the robot's drive among them),
    # the operator not: it drives through cmd_vel, which the robot's watchdog and the mission's turn guard
    assert policy.callers["/robot_computer/device_call"] == names
    assert policy.denied(policy.callers["/robot_computer/device_call"]) == [OPERATOR]
    assert policy.denied(policy.publishers["/clock"]) == everyone_else


def test_only_the_mission_and_the_operator_publish_the_robots_command_topics() -> None:
    """PeopleBot's cmd_vel, say and display (no pan); its readings stay open to every process."""
    policy = deployment_policy(check_deployment(FIVE))
    commands = {topic: who for topic, who in policy.publishers.items() if topic != "/clock"}
    assert commands == {topic: ["navigation_computer", OPERATOR] for topic in ("/cmd_vel", "/say", "/display")}
    assert policy.denied(commands["/cmd_vel"]) == [
        "robot_computer",
        "kinect_speech_computer",
        "upload_computer",  # the gallery's computer
        "display_computer",
    ]
    rules = {rule["id"]: rule for rule in access_control(policy)["rules"]}
    assert rules["only listed processes publish /cmd_vel"]["key_exprs"] == ["0/cmd_vel/**"]
    assert rules["unlisted processes do not see /cmd_vel"]["messages"] == ["declare_subscriber"]
    assert "/odom" not in policy.publishers and "/image_raw" not in policy.publishers


def test_command_topics_are_named_as_the_robot_process_names_them(tmp_path: Path) -> None:
    """The profile's ``ros2: topics:`` renames (``~`` under the robot process's node), in the file's domain."""
    profile = (ROOT / "robots" / "profiles" / "face_tracker.yaml").read_text()
    assert "  topics: {}" in profile
    profile = profile.replace("  topics: {}", "  topics: {pan: ~/pan_goal}")
    (tmp_path / "tracker.yaml").write_text(profile)
    mission = ROOT / "missions" / "examples" / "face_tracker.yaml"
    text = mission.read_text()
    assert "robot: face_tracker" in text
    (tmp_path / "mission.yaml").write_text(text.replace("robot: face_tracker", "robot: tracker.yaml"))
    (tmp_path / "deployment.yaml").write_text(
        "name: renamed\nmission: mission.yaml\ndomain_id: 7\nprocesses:\n"
        "  desk:\n    backend: sim\n    topics: true\n  brain:\n    mission: true\n"
    )
    checked = check_deployment(tmp_path / "deployment.yaml")
    assert checked.ok, checked.problems
    assert command_topics(checked) == ["/desk/pan_goal"]
    policy = deployment_policy(checked)
    assert policy.publishers["/desk/pan_goal"] == ["brain", OPERATOR]
    assert "7/desk/pan_goal/**" in str(access_control(policy)["rules"])


def test_operator_is_no_process_name(tmp_path: Path) -> None:
    text = (DEPLOYMENTS / "driving_two_processes.yaml").read_text().replace("  robot:", "  operator:")
    (tmp_path / "driving.yaml").write_text((DEPLOYMENTS / "driving.yaml").read_text())
    (tmp_path / "d.yaml").write_text(text)
    checked = check_deployment(tmp_path / "d.yaml")
    assert any("'operator' is taken" in str(problem) for problem in checked.problems), checked.problems


def test_a_process_that_runs_neither_mission_nor_skills_may_not_call_devices(tmp_path: Path) -> None:
    entertainer = FIVE.parent.parent / "examples" / "peoplebot_entertainer.yaml"
    text = FIVE.read_text().replace("mission: ../examples/peoplebot_entertainer.yaml", f"mission: {entertainer}")
    text += "  wall_screen:\n    description: shows the run\n"
    path = tmp_path / "six.yaml"
    path.write_text(text)
    checked = check_deployment(path)
    assert checked.ok, checked.problems
    policy = deployment_policy(checked)
    assert policy.denied(policy.callers["/robot_computer/device_call"]) == ["wall_screen", OPERATOR]


def test_endpoints_switch_to_tls_and_a_given_tcp_one_is_refused() -> None:
    assert secured(["tcp/127.0.0.1:7447", "tls/10.0.0.2:7447"], ["tls/10.0.0.2:7447"]) == [
        "tls/127.0.0.1:7447",
        "tls/10.0.0.2:7447",
    ]
    with pytest.raises(SecurityError, match=r"tcp/10\.0\.0\.2:7447: a secured process speaks only tls/"):
        secured(["tcp/10.0.0.2:7447"], ["tcp/10.0.0.2:7447"])


def test_credentials_are_found_in_either_folder_and_missing_ones_are_named(tmp_path: Path) -> None:
    make_certificates(tmp_path, ["robot_computer"])
    assert credentials(tmp_path, "robot_computer").cert == tmp_path / "robot_computer" / "cert.pem"
    assert credentials(tmp_path / "robot_computer", "robot_computer").cert == tmp_path / "robot_computer" / "cert.pem"
    with pytest.raises(SecurityError, match=r"no TLS credentials for 'upload_computer' in .*botstage certs"):
        credentials(tmp_path, "upload_computer")


def test_serve_process_refuses_a_tcp_endpoint_when_secured(tmp_path: Path) -> None:
    make_certificates(tmp_path / "certs", ["speech"])
    with pytest.raises(DeploymentError, match="speaks only tls/"):
        serve_process(
            DEPLOYMENTS / "listening_three_processes.yaml",
            "speech",
            out=tmp_path / "run",
            connect=["tcp/127.0.0.1:7447"],
            certs=tmp_path / "certs",
        )


def _up(deployment: Path, out: Path, *extra: str) -> dict[str, Any]:
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "up",
        str(deployment),
        "--out",
        str(out),
        "--until",
        "5",
        *extra,
    ]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=FAILSAFE_S)
    assert done.returncode == 0, done.stdout + done.stderr
    return {"stdout": done.stdout, "summary": json.loads((out / "summary.json").read_text())}


def test_a_secured_deployment_runs_as_an_open_one(tmp_path: Path) -> None:
    deployment = DEPLOYMENTS / "driving_two_processes.yaml"
    open_run = _up(deployment, tmp_path / "open")
    secure_run = _up(deployment, tmp_path / "secure", "--secure")
    assert "processes on tls/127.0.0.1:" in secure_run["stdout"]
    for field in ("outcome", "ticks", "sim_time_s", "states_visited", "skill_outcomes", "counters"):
        assert secure_run["summary"][field] == open_run["summary"][field], field
    assert secure_run["summary"]["ticks"] == 50
    for process in ("robot", "mission"):
        key = Credentials.in_folder(tmp_path / "secure" / "certs" / process).key
        assert key.stat().st_mode & 0o777 == 0o600
        assert key.read_text() not in secure_run["stdout"]


def test_a_process_of_the_deployment_that_is_not_the_mission_cannot_call_skills(tmp_path: Path) -> None:
    """``/speech/skill_tick`` under its deployment's policy: the mission calls it, the robot sees it and cannot."""
    certs = tmp_path / "certs"
    make_certificates(certs, ["robot", "mission", "speech"])
    policy = deployment_policy(check_deployment(DEPLOYMENTS / "listening_three_processes.yaml"))
    endpoint = f"tls/127.0.0.1:{free_port()}"

    def node(name: str, **where: Any) -> Ros2Node:
        options = security_options(Credentials.in_folder(certs / name), policy)
        return Ros2Node(name, options=options, **where)

    host = SkillHost(Registry.builtin(), {}, ["wait"])
    try:
        with (
            node("speech", listen=[endpoint], mode="router") as speech,
            node("mission", listen=[], connect=[endpoint]) as mission,
            node("robot", listen=[], connect=[endpoint]) as robot,
        ):
            serve_skill_host(speech, host)
            call = Call("wait", "/drill", {"duration": 0.0}, {})
            request = TickRequest("c1", Step.START, 0.0, 0, 0.1, True, call)
            allowed = SkillTickLink(mission, "speech", timeout=FAILSAFE_S)
            assert allowed.wait_for_remote(FAILSAFE_S)
            assert allowed.tick(request).outcome == "success"
            refused = robot.client(service_name("speech"), SERVICE_TYPE)
            assert refused.wait_for_service(FAILSAFE_S)  # the graph shows the server to every listed process
            message = types.message_class(f"{SERVICE_TYPE}_Request")(**request_fields(request))
            with pytest.raises(ServiceError, match="no server answered"):
                refused.call(message, timeout=FAILSAFE_S)
    finally:
        host.close()


# -- the robot's command topics on real sessions ---------------------------------------------------


@pytest.fixture(scope="module")
def five_certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``botstage certs DIR --deployment FIVE``: the five computers' certificates and the operator's."""
    folder = tmp_path_factory.mktemp("certs")
    app = typer.Typer()
    app.command()(certs_command)
    result = CliRunner().invoke(app, [str(folder), "--deployment", str(FIVE)])
    assert result.exit_code == 0, result.output
    assert "operator: " in result.output
    return folder


class CountingServer(RobotServer):
    """The robot's server, telling a waiting test each command it received (on Zenoh's threads)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.arrived = threading.Condition()  # before the subscriptions: a message may come at once
        super().__init__(*args, **kwargs)

    def _told(self) -> None:
        with self.arrived:
            self.arrived.notify_all()

    def _on_twist(self, message: Any, attachment: Any) -> None:
        super()._on_twist(message, attachment)
        self._told()

    def _on_say(self, message: Any, attachment: Any) -> None:
        super()._on_say(message, attachment)
        self._told()

    def received(self, key: str, count: int) -> bool:
        """Whether ``count`` messages of ``key`` came, waiting for them (failsafe-bounded)."""
        with self.arrived:
            self.arrived.wait_for(lambda: self.counts[key] >= count, FAILSAFE_S)
        return self.counts[key] == count


class SecuredRobot:
    """The five computers' robot process, served as topics (``RobotServer``) under the deployment's
    policy, and the other identities joining it: connected to it, or to the router (the mission's
    computer) as the deployment's processes are. ``shape`` changes every session's options alike."""

    def __init__(self, certs: Path, routed: bool, shape: Callable[[dict[str, Any]], dict[str, Any]]) -> None:
        self.checked, self.certs, self.shape = check_deployment(FIVE), certs, shape
        self.nodes: list[Ros2Node] = []
        self.router: Ros2Node | None = None
        if routed:
            self.router, self.endpoint = self._listening("navigation_computer", mode="router")
            self.robot = self._join("robot_computer")
        else:
            self.robot, self.endpoint = self._listening("robot_computer")
        profile, grid, pose = robot_place("peoplebot", "museum", "hall_centre")
        self.clock = SimClock(10.0)
        self.backend = SimBackend(profile, grid, pose, 0, self.clock)
        self.server = CountingServer(self.backend, self.robot, self.clock, routes(profile), publish_clock=False)
        self.chatter: queue.Queue[str] = queue.Queue()
        self.robot.subscription("/chatter", STRING, lambda message, _: self.chatter.put(message.data))

    def _options(self, who: str) -> dict[str, Any]:
        return self.shape(session_options(self.checked, who, self.certs))

    def _listening(self, who: str, **kwargs: Any) -> tuple[Ros2Node, str]:
        for _ in range(5):
            endpoint = f"tls/127.0.0.1:{free_port()}"
            try:
                node = Ros2Node(who, listen=[endpoint], options=self._options(who), **kwargs)
            except zenoh.ZError as error:
                if "in use" not in str(error):
                    raise
                continue
            self.nodes.append(node)
            return node, endpoint
        raise RuntimeError("no free loopback port after 5 tries")

    def _join(self, who: str) -> Ros2Node:
        """Directly: connected to the robot. Routed: as ``serve process`` (and teleop) do, listening on a
        loopback port of its own and connected to the router, which tells the peers of each other."""
        listen = ["tls/127.0.0.1:0"] if self.router is not None else []
        node = Ros2Node(who, listen=listen, connect=[self.endpoint], options=self._options(who))
        self.nodes.append(node)
        return node

    def join(self, who: str) -> Ros2Node:
        """``who``'s node (the mission's is the router itself when routed)."""
        if self.router is not None and who == "navigation_computer":
            return self.router
        return self._join(who)

    def marker(self, node: Ros2Node, text: str) -> None:
        """``text`` on an open topic, waited for: what ``node`` published before it has arrived by then."""
        publisher = node.publisher("/chatter", STRING)
        wait_matching(node.session, publisher.key)
        publisher.publish(types.message_class(STRING)(data=text))
        assert self.chatter.get(timeout=FAILSAFE_S) == text

    def ticks(self, n: int) -> None:
        """``n`` ticks of the robot's loop: commands applied, the world stepped."""
        for _ in range(n):
            self.server.take_commands()
            self.clock.next_tick()
            self.backend.step()

    def close(self) -> None:
        self.server.close()  # the drive stopped, the backend and the robot's node closed
        for node in reversed(self.nodes):
            if node is not self.robot:
                node.close()


@pytest.fixture
def secured_robot(request: pytest.FixtureRequest, five_certs: Path) -> Iterator[SecuredRobot]:
    routed, shape = request.param
    robot = SecuredRobot(five_certs, routed, shape)
    try:
        yield robot
    finally:
        robot.close()


def _unchanged(options: dict[str, Any]) -> dict[str, Any]:
    return options


def _string(text: str) -> Any:
    return types.message_class(STRING)(data=text)


def _moved(before: Any, after: Any) -> float:
    return math.dist((before.x, before.y), (after.x, after.y))


@pytest.mark.parametrize(
    "secured_robot",
    [(False, _unchanged), (False, _ingress_only), (True, _unchanged), (True, _ingress_only)],
    ids=["direct", "direct, ingress filter alone", "routed", "routed, ingress filter alone"],
    indirect=True,
)
def test_the_gallery_cannot_move_the_robot_the_mission_and_the_operator_can(secured_robot: SecuredRobot) -> None:
    """``upload_computer`` (the gallery) holds a valid certificate of the deployment: its cmd_vel, say and
    display never reach the robot's server; the mission's and the operator's do."""
    robot = secured_robot
    assert ACCESS_CONTROL in robot._options("robot_computer")
    start = robot.backend.true_pose()
    gallery = robot.join("upload_computer")
    gallery.publisher("/cmd_vel", "geometry_msgs/msg/Twist").publish(readings.twist_message(Twist2D(0.5, 0.0)))
    gallery.publisher("/say", STRING).publish(_string("the gallery speaks"))
    gallery.publisher("/display", STRING).publish(_string('{"layout": "Layout_1", "content": {"title": "x"}}'))
    robot.marker(gallery, "after the gallery's commands")
    robot.ticks(3)
    assert not any(robot.server.counts[key] for key in ("cmd_vel", "cmd_vel_rejected", "say", "display"))
    assert _moved(start, robot.backend.true_pose()) == 0.0

    allowed = {who: robot.join(who) for who in ("navigation_computer", OPERATOR)}
    for count, node in enumerate(allowed.values(), start=1):
        drive = node.publisher("/cmd_vel", "geometry_msgs/msg/Twist")
        wait_matching(node.session, drive.key)
        drive.publish(readings.twist_message(Twist2D(0.3, 0.0)))
        assert robot.server.received("cmd_vel", count), (node.name, robot.server.counts)
    before = robot.backend.true_pose()
    robot.ticks(3)
    assert _moved(before, robot.backend.true_pose()) > 0.0  # the operator's 0.3 m/s moves it
    say = allowed[OPERATOR].publisher("/say", STRING)
    wait_matching(allowed[OPERATOR].session, say.key)
    say.publish(_string("the operator speaks"))
    assert robot.server.received("say", 1), robot.server.counts
