"""Secured deployments: mutual TLS for every process and the access policy derived from the file.

The policy is checked rule by rule on the paper's five computers; a secured deployment runs with
real processes (``botstage up --secure``) to the same counters as an unsecured one, so the
default-deny policy closes nothing the deployment needs; a process of the deployment that is not
the mission cannot call another's skills, in a real secured process. How Zenoh enforces a policy
is tested in tests/test_ros2_security.py.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from missions.cli.distributed import free_port
from missions.deployment import check_deployment
from missions.distributed.process import DeploymentError, serve_process
from missions.distributed.security import SecurityError, credentials, deployment_policy, secured
from robots.ros2 import types
from robots.ros2.certs import Credentials, make_certificates
from robots.ros2.node import Ros2Node
from robots.ros2.security import security_options
from robots.ros2.service import ServiceError
from skills.registry import Registry
from skills.remote.host import SkillHost
from skills.remote.protocol import Call, Step, TickRequest, request_fields
from skills.remote.ros2_link import SERVICE_TYPE, SkillTickLink, serve_skill_host, service_name

ROOT = Path(__file__).resolve().parent.parent
FIVE = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
DEPLOYMENTS = ROOT / "tests" / "deployments"
FAILSAFE_S = 120.0  # a bound for what must happen, never a measure


def test_only_the_mission_calls_skills_steps_processes_and_publishes_the_clock() -> None:
    checked = check_deployment(FIVE)
    policy = deployment_policy(checked)
    names = list(checked.deployment.processes)  # type: ignore[union-attr]
    assert list(policy.processes) == names
    assert list(policy.forwarders) == ["navigation_computer"]  # the router
    assert policy.publishers == {"/clock": ["navigation_computer"]}
    for name in names:
        for service in (f"/{name}/skill_tick", f"/{name}/skills", f"/{name}/lockstep"):
            assert policy.callers[service] == ["navigation_computer"], service
            assert policy.denied(policy.callers[service]) == [n for n in names if n != "navigation_computer"]
    # every process here runs the mission or skills: all may call devices (the robot's drive among them)
    assert policy.callers["/robot_computer/device_call"] == names


def test_a_process_that_runs_neither_mission_nor_skills_may_not_call_devices(tmp_path: Path) -> None:
    entertainer = FIVE.parent.parent / "peoplebot_entertainer.yaml"
    text = FIVE.read_text().replace("mission: ../peoplebot_entertainer.yaml", f"mission: {entertainer}")
    text += "  wall_screen:\n    description: shows the run\n"
    path = tmp_path / "six.yaml"
    path.write_text(text)
    checked = check_deployment(path)
    assert checked.ok, checked.problems
    policy = deployment_policy(checked)
    assert policy.denied(policy.callers["/robot_computer/device_call"]) == ["wall_screen"]


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
    command = [sys.executable, "-m", "missions.cli", "up", str(deployment), "--out", str(out), "--until", "5", *extra]
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
