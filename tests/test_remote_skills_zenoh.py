"""Remote skills between real processes over Zenoh (ROS 2 services in rmw_zenoh's format).

A skills process (tests/ros2_client/skill_host_process.py) serves the built-in skills; this
process calls them through ``remote_of`` proxies over ``SkillTickLink``: a call runs there, a
SIGKILL of that process fails the running node with ``remote 'NAME' lost`` through the graph
(not a timeout), and a restarted process serves the next call.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from botstage.robots.ros2.node import Ros2Node
from botstage.skills.base import Outcome, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.registry import Registry
from botstage.skills.remote.proxy import remote_of
from botstage.skills.remote.ros2_link import SkillTickLink
from tests.test_remote_skills import Board, Clock
from tests.test_ros2_interop import listening_node

SCRIPT = Path(__file__).resolve().parent / "ros2_client" / "skill_host_process.py"
ROOT = Path(__file__).resolve().parent.parent
FAILSAFE_S = 60.0


def start_host(endpoint: str, name: str) -> subprocess.Popen[str]:
    process = subprocess.Popen(
        [sys.executable, str(SCRIPT), endpoint, name], stdout=subprocess.PIPE, text=True, cwd=ROOT, env=None
    )
    assert process.stdout is not None
    assert process.stdout.readline().strip() == "ready"
    return process


@pytest.fixture
def mission() -> Iterator[tuple[Ros2Node, str]]:
    node, endpoint = listening_node("mission")
    with node:
        yield node, endpoint


def execution(skill_cls: Any) -> tuple[SkillExecution, Clock]:
    clock = Clock()
    ctx = SkillContext(clock, skill_cls.Params(), SkillLogger("/n"), Board(), None, node="/n")  # type: ignore[arg-type]
    return SkillExecution(skill_cls(), ctx), clock


def run_to_end(ex: SkillExecution, clock: Clock, first: Outcome | None, ticks: int = 100) -> Outcome | None:
    outcome = first
    while outcome is None and clock.ticks < ticks:
        clock.next_tick()
        outcome = ex.step()
    return outcome


def test_a_call_runs_in_the_other_process_and_a_killed_one_is_lost_then_back(mission: tuple[Ros2Node, str]) -> None:
    node, endpoint = mission
    link = SkillTickLink(node, "kinect_pc")
    wait_skill = remote_of(Registry.builtin().get("wait"), link)
    host = start_host(endpoint, "kinect_pc")
    try:
        assert link.wait_for_remote(FAILSAFE_S)
        ex, clock = execution(wait_skill)
        outcome = run_to_end(ex, clock, ex.start({"duration": 0.5}))
        assert outcome is not None and outcome.name == "success" and clock.ticks == 5

        ex, clock = execution(wait_skill)
        assert ex.start({"duration": 1000.0}) is None and ex.step() is None  # running over there
        host.kill()
        host.wait(FAILSAFE_S)
        began = time.monotonic()
        outcome = run_to_end(ex, clock, None)
        noticed = time.monotonic() - began
        assert outcome == Outcome("failure", "remote 'kinect_pc' lost"), outcome
        print(f"loss noticed {noticed * 1000:.0f} ms after the kill returned")

        host = start_host(endpoint, "kinect_pc")
        assert link.wait_for_remote(FAILSAFE_S)
        ex, clock = execution(wait_skill)
        assert run_to_end(ex, clock, ex.start({"duration": 0.2})) == Outcome("success")
    finally:
        host.kill()
        host.wait(FAILSAFE_S)
