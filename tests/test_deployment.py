"""Deployment files: checked whole, before anything starts, every problem at its place."""

from __future__ import annotations

from pathlib import Path

import pytest

from botstage.missions.deployment import check_deployment

ROOT = Path(__file__).resolve().parent.parent
FIVE = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
MISSION = ROOT / "missions" / "examples" / "peoplebot_entertainer.yaml"

BASE = f"""name: d
mission: {MISSION}
processes:
  robot: {{backend: sim, interfaces: [drive, odometry, laser, battery, people, camera, microphone, speaker, display]}}
  brain: {{mission: true}}
  ears: {{skills: [listen, detect_crowd]}}
"""


def problems(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "d.yaml"
    path.write_text(text)
    return [str(p).replace(str(path), "d.yaml") for p in check_deployment(path).problems]


def test_the_papers_five_computers_deployment_is_valid_and_places_every_skill() -> None:
    checked = check_deployment(FIVE)
    assert checked.ok, [str(p) for p in checked.problems]
    assert checked.mission_process == checked.router == "navigation_computer"
    hosts = checked.skill_hosts()
    assert hosts["detect_crowd"] == hosts["listen"] == "kinect_speech_computer"
    assert hosts["upload"] == "upload_computer" and hosts["display"] == "display_computer"
    assert set(hosts) == set(checked.mission.skills_used)  # every skill the mission calls has a home
    assert checked.interface_hosts()["drive"] == "robot_computer"


def test_a_minimal_deployment_runs_the_rest_in_the_missions_process(tmp_path: Path) -> None:
    path = tmp_path / "d.yaml"
    path.write_text(BASE)
    checked = check_deployment(path)
    assert checked.ok, checked.problems
    assert checked.skill_hosts()["listen"] == "ears" and checked.skill_hosts()["wander"] == "brain"


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            ("  ears: {skills: [listen, detect_crowd]}", "  ears: {skills: [listen, detect_crowd], connect: [brian]}"),
            "d.yaml:6:52: error: unknown process 'brian' (did you mean 'brain'?)",
        ),
        (("name: d\n", "name: d\nrouter: nobody\n"), "d.yaml:2:1: error: unknown process 'nobody'"),
        (
            ("  brain: {mission: true}", "  brain: {mission: true, skills: [wander]}"),
            "d.yaml:5:26: error: skill 'approach' is served nowhere (the mission calls it at ",
        ),
        (
            ("  ears: {skills: [listen, detect_crowd]}", "  ears: {skills: [listen, detect_crowd, listen]}"),
            "d.yaml:6:41: error: skill 'listen' is served twice: by 'ears' (d.yaml:6:19) and 'ears'",
        ),
        (
            ("  ears: {skills: [listen, detect_crowd]}", "  ears: {skills: [lisen]}"),
            "d.yaml:6:19: error: unknown skill 'lisen' (did you mean 'listen'?)",
        ),
        (
            ("  brain: {mission: true}", "  brain: {mission: true}\n  eyes: {backend: emulator, interfaces: [camera]}"),
            "d.yaml:6:42: error: interface 'camera' is served twice: by 'robot' (",
        ),
        (
            ("  brain: {mission: true}", "  brain: {mission: true}\n  eyes: {interfaces: [sonar]}"),
            "error: robot 'peoplebot' has no interface 'sonar'",
        ),
        (
            ("  brain: {mission: true}", "  brain: {mission: true}\n  eyes: {interfaces: [camra]}"),
            "d.yaml:6:23: error: process 'eyes' serves 'camra' but opens no backend",
        ),
        (
            ("  brain: {mission: true}", "  brain: {mission: true}\n  world2: {backend: sim}"),
            "d.yaml:6:12: error: the simulator is one world: it runs in one process, already 'robot'",
        ),
        (("  brain: {mission: true}", "  brain: {mission: false}"), "d.yaml:3:1: error: no process runs the mission"),
        (
            ("  ears: {skills", "  ears: {mission: true, skills"),
            "error: the mission runs in one process, already 'brain'",
        ),
        (("  brain:", "  brain-2:"), "error: process name 'brain-2' is not a ROS node name"),
        (
            ("  brain: {mission: true}", "  brain: {mission: true, listen: [tcp/127.0.0.1]}"),
            "error: 'tcp/127.0.0.1' is not a Zenoh endpoint (like tcp/127.0.0.1:7447)",
        ),
        (
            ("name: d\n", "name: d\ndomain_id: 300\n"),
            "d.yaml:2:1: error: domain_id: input should be less than or equal to 232",
        ),
        (("name: d\n", "name: d\nprocess: {}\n"), "d.yaml:2:1: error: unknown key 'process'"),
    ],
)
def test_problems_are_located(tmp_path: Path, change: tuple[str, str], expected: str) -> None:
    old, new = change
    assert old in BASE
    found = problems(tmp_path, BASE.replace(old, new, 1))
    assert any(expected in p for p in found), found


def test_the_missions_own_problems_come_with_its_locations(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text("name: m\ntrees:\n  main: {wiat: {duration: 1}}\n")
    found = problems(tmp_path, "name: d\nmission: m.yaml\nprocesses:\n  one: {mission: true}\n")
    assert found[0] == "d.yaml:2:1: error: the mission 'm.yaml' has 1 problem(s), below"
    assert f"{mission}:3:10: error: unknown node or skill 'wiat'" in found[1]


def test_a_file_that_is_not_a_deployment_is_a_located_error(tmp_path: Path) -> None:
    assert problems(tmp_path, "- a list\n") == ["d.yaml:1:1: error: expected a mapping at the top of the file"]
    assert problems(tmp_path, "name: d\n")[0].startswith("d.yaml:1:1: error: mission: field required")
