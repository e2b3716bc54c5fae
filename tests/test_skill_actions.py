"""Served skills as ROS 2 actions (botstage_msgs/action/SkillCall), called with an action client.

The client is botstage's rcl_action-style ActionClient on its own Zenoh session (loopback): a
goal runs the skill on the serving process's clock and ends SUCCEEDED with its outcome; a cancel
ends it CANCELED after the skill's cleanup; a goal with bad JSON or for another skill is
rejected; the skill actions are in the ROS 2 graph.
"""

from __future__ import annotations

import json
import queue
from collections.abc import Iterator
from typing import Any

import pytest

from botstage.robots.ros2 import types
from botstage.robots.ros2.action import GoalStatus
from botstage.robots.ros2.node import Ros2Node
from botstage.skills.registry import Registry
from botstage.skills.remote.actions import ACTION_TYPE, SkillActions, action_name
from botstage.skills.remote.host import SkillHost
from tests.test_ros2_interop import listening_node

FAILSAFE_S = 60.0
_Goal = types.message_class(f"{ACTION_TYPE}_Goal")


def Goal(**fields: Any) -> Any:
    """A SkillCall goal; the fields not given are empty."""
    return _Goal(**{"skill": "", "inputs_json": "", "params_json": "", "call_id": "", "tick": 0, **fields})


@pytest.fixture
def served() -> Iterator[tuple[Ros2Node, Ros2Node]]:
    server, endpoint = listening_node("kinect_pc")
    host = SkillHost(Registry.builtin(), {}, ["wait", "set"])
    actions = SkillActions(server, host, ["wait", "set"], rate_hz=50.0)
    client = Ros2Node("caller", connect=[endpoint])
    try:
        yield server, client
    finally:
        client.close()
        actions.close()
        host.close()
        server.close()


def call(client: Ros2Node, skill: str, **goal: Any) -> Any:
    action = client.action_client(action_name("kinect_pc", skill), ACTION_TYPE)
    assert action.wait_for_server(FAILSAFE_S)
    return action


def test_a_goal_runs_the_skill_and_ends_with_its_outcome(served: tuple[Ros2Node, Ros2Node]) -> None:
    _, client = served
    feedback: queue.Queue[Any] = queue.Queue()
    handle = call(client, "wait").send_goal(
        Goal(skill="wait", inputs_json=json.dumps({"duration": 0.1})), feedback.put, timeout=FAILSAFE_S
    )
    assert handle.accepted
    ended = handle.result(FAILSAFE_S)
    assert ended.status is GoalStatus.SUCCEEDED
    # The server ticks on its wall clock: how many ticks 0.1 s takes depends on the host's load, so
    # only "more than the start" is certain (a wait never ends on the tick that starts it).
    assert ended.result.outcome == "success" and ended.result.ticks >= 1
    assert feedback.get(timeout=FAILSAFE_S).ticks >= 1


def test_a_cancel_runs_the_cleanup_and_ends_canceled(served: tuple[Ros2Node, Ros2Node]) -> None:
    _, client = served
    feedback: queue.Queue[Any] = queue.Queue()
    handle = call(client, "wait").send_goal(Goal(inputs_json='{"duration": 1000}'), feedback.put, timeout=FAILSAFE_S)
    feedback.get(timeout=FAILSAFE_S)  # it runs
    handle.cancel(FAILSAFE_S)
    ended = handle.result(FAILSAFE_S)
    assert ended.status is GoalStatus.CANCELED and ended.result.outcome == "cancelled"


@pytest.mark.parametrize(
    "goal",
    [
        Goal(inputs_json="{oops"),
        Goal(inputs_json="[1]"),
        Goal(skill="set", inputs_json="{}"),
        Goal(params_json='{"x": 1}'),
    ],
)
def test_bad_goals_are_rejected(served: tuple[Ros2Node, Ros2Node], goal: Any) -> None:
    _, client = served
    assert not call(client, "wait").send_goal(goal, timeout=FAILSAFE_S).accepted


def test_a_skill_that_fails_ends_aborted_with_its_reason(served: tuple[Ros2Node, Ros2Node]) -> None:
    _, client = served
    ended = call(client, "wait").send_goal(Goal(inputs_json='{"duration": -1}'), timeout=FAILSAFE_S).result(FAILSAFE_S)
    assert ended.status is GoalStatus.ABORTED
    assert ended.result.outcome == "failure" and "greater than or equal to 0" in ended.result.reason


def test_the_skill_actions_are_in_the_graph(served: tuple[Ros2Node, Ros2Node]) -> None:
    _, client = served
    services = client.graph().service_names_and_types()
    assert services["/kinect_pc/skills/wait/_action/send_goal"] == ["botstage_msgs/action/SkillCall_SendGoal"]
    assert "/kinect_pc/skills/set/_action/get_result" in services
