"""ROS 2 actions as rcl_action lays them out over rmw_zenoh: hashes, endpoints, goals over real Zenoh sessions.

Action hashes are checked against values rosidl generated (example_interfaces/action/Fibonacci of
ROS 2 Kilted, as shipped by micro-ROS in hpmicro/hpm_sdk) and against ros2_pyterfaces.
Goals run between nodes on loopback (127.0.0.1, free ports, no multicast scouting), some in
other processes: an independent peer built on pyzeros calls botstage's services and SkillCall
action, and a botstage skill server is killed (SIGKILL) under a running goal. Waits are on
futures, events and queues with failsafe timeouts.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy
import pytest

from botstage.robots.ros2 import types
from botstage.robots.ros2.action import (
    ActionServer,
    ActionServerLost,
    CancelCode,
    GoalRejected,
    GoalStatus,
    action_endpoints,
    goal_uuid,
)
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.liveliness import EntityKind
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.qos import Durability
from botstage.robots.ros2.service import ServiceUnavailable
from tests.ros2_client.independent_interfaces import independent_hashes
from tests.test_ros2_interop import FAILSAFE_S, ClientProcess, listening_node, pyzeros_codecs  # noqa: F401

FIBONACCI = "example_interfaces/action/Fibonacci"
SKILL_CALL = "botstage_msgs/action/SkillCall"

# RIHS01 digests rosidl generated for example_interfaces/action/Fibonacci (ROS 2 Kilted).
PUBLISHED = {
    "": "9508051da1ea4658de144b09bd0690ff3de52104683d847aed764d2915906f51",
    "_Goal": "226cb437e4355dcd3e914f930382a3b0cc1da81545bd319ed554e95a03255f51",
    "_Result": "fea81394f25aa4502217953f1a021fb750e79c10bbd43f13dd94632da6569649",
    "_Feedback": "2b12e37361da6f408d4c85bc24a18de64333f29082f2ca34b5ee33dc4c8b42a9",
    "_SendGoal": "d1a57fb2a4afe8c21e34fb10db206f16ce6729b28531141472df92277c55b557",
    "_SendGoal_Request": "3d088942b413247db536576f0286768c6be8fcd5d0c9a5d544f359fba090a238",
    "_SendGoal_Response": "d8c07bb3d5b766fe4b43159c9a5222af5214e2fcc29229b991d826166c512be1",
    "_SendGoal_Event": "d5e5b312dbf847307b0e876c2ecc9d80258e95b0d17f8f7bfc581c4a29c83484",
    "_GetResult": "1b0de0d5d29dc955d92f546706568428632771db13ec84c15ec1c1a59f424a57",
    "_GetResult_Request": "c8a4f5e7d13b81286ee1043e2ecd084281cecf1ff06aaa799464f5f15479f003",
    "_GetResult_Response": "6021dc98ab9b4bbe395e48aa4de81ee5f68eb570f88358affcc648146668b24f",
    "_GetResult_Event": "ac4e9cdb954c2e192c9f0753d46f59ab6f0101d5fb5b9542fd8ab2906e40c4d9",
    "_FeedbackMessage": "c1de71afd52e49a89c53d8262366884185bc0a02f78ce051c4e46b0a7fe59bb2",
}
STATUS_ARRAY_DIGEST = "6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e"


@pytest.mark.parametrize(("suffix", "digest"), sorted(PUBLISHED.items()))
def test_fibonacci_hashes_are_those_rosidl_generates(suffix: str, digest: str) -> None:
    assert types.type_hash(f"{FIBONACCI}{suffix}") == f"RIHS01_{digest}"


def test_action_hashes_equal_an_independent_implementation() -> None:
    independent = independent_hashes()
    assert {name for name in independent if name.startswith(SKILL_CALL)} >= {
        SKILL_CALL,
        f"{SKILL_CALL}_SendGoal",
        f"{SKILL_CALL}_GetResult",
        f"{SKILL_CALL}_FeedbackMessage",
    }
    assert {name: types.type_hash(name) for name in independent} == independent


def test_skill_call_is_a_shipped_action_with_its_generated_messages() -> None:
    action = types.action_type(SKILL_CALL)
    assert (
        action.send_goal.name == f"{SKILL_CALL}_SendGoal"
        and action.get_result.request == f"{SKILL_CALL}_GetResult_Request"
    )
    goal = types.message_class(action.goal)(skill="listen", inputs_json="{}", params_json="", call_id="n/1", tick=3)
    assert types.deserialize(types.serialize(goal), action.goal).skill == "listen"
    assert [f for f, _ in types.type_store().fielddefs[action.result][1]] == [
        "outcome",
        "reason",
        "outputs_json",
        "ticks",
    ]
    assert [f for f, _ in types.type_store().fielddefs[action.feedback][1]] == ["ticks", "detail"]
    with pytest.raises(types.UnknownTypeError, match="not an action type"):
        types.action_type(f"{SKILL_CALL}_SendGoal")  # one of the action's services


# -- goals over real sessions -------------------------------------------------------------------


@pytest.fixture
def nodes() -> Iterator[tuple[Ros2Node, Ros2Node]]:
    server, endpoint = listening_node("server", clock=lambda: 1_700_000_000_250_000_000)
    caller = Ros2Node("caller", connect=[endpoint])
    yield server, caller
    caller.close()
    server.close()


def fibonacci_goal(order: int) -> Any:
    return types.message_class(f"{FIBONACCI}_Goal")(order=order)


def sequence(numbers: list[int], part: str = "_Result") -> Any:
    return types.message_class(f"{FIBONACCI}{part}")(sequence=numbers_array(numbers))


def numbers_array(numbers: list[int]) -> Any:
    return numpy.array(numbers, dtype=numpy.int32)


class Fibonacci:
    """A server whose goals run on a thread of their own, as a skill host's would."""

    def __init__(self, node: Ros2Node, name: str = "fibonacci", **options: Any) -> None:
        self.release = threading.Event()
        self.server: ActionServer = node.action_server(
            name, FIBONACCI, on_goal=lambda _, goal: goal.order <= 20, on_accepted=self._start, **options
        )

    def _start(self, goal_id: bytes, goal: Any) -> None:
        threading.Thread(target=self._run, args=(goal_id, goal.order), daemon=True).start()

    def _run(self, goal_id: bytes, order: int) -> None:
        numbers = [0, 1]
        for _ in range(order - 1):
            numbers.append(numbers[-1] + numbers[-2])
            self.server.publish_feedback(goal_id, sequence(numbers, "_Feedback"))
        self.release.wait(FAILSAFE_S)
        self.server.succeed(goal_id, sequence(numbers))


def test_a_goal_is_accepted_reports_feedback_and_succeeds(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    fibonacci = Fibonacci(server_node)
    client = caller.action_client("fibonacci", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    feedback: queue.Queue[list[int]] = queue.Queue()
    handle = client.send_goal(
        fibonacci_goal(5), on_feedback=lambda f: feedback.put(list(f.sequence)), timeout=FAILSAFE_S
    )
    assert handle.accepted and handle.server == server_node.zid
    assert handle.stamp_ns == 1_700_000_000_250_000_000
    assert [feedback.get(timeout=FAILSAFE_S) for _ in range(4)] == [
        [0, 1, 1],
        [0, 1, 1, 2],
        [0, 1, 1, 2, 3],
        [0, 1, 1, 2, 3, 5],
    ]
    assert not handle.done
    fibonacci.release.set()
    ended = handle.result(FAILSAFE_S)
    assert ended.status is GoalStatus.SUCCEEDED and list(ended.result.sequence) == [0, 1, 1, 2, 3, 5]
    assert fibonacci.server.status(handle.goal_id) is GoalStatus.SUCCEEDED
    assert client.goals() == []


def test_the_action_is_three_services_and_two_topics_as_rcl_action_names_them(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    Fibonacci(server_node, "/robot/fibonacci")
    client = caller.action_client("/robot/fibonacci", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    graph = caller.graph()
    at = action_endpoints("/robot/fibonacci")
    services = graph.service_names_and_types()
    assert services == {
        at["send_goal"]: [f"{FIBONACCI}_SendGoal"],
        at["cancel_goal"]: ["action_msgs/srv/CancelGoal"],
        at["get_result"]: [f"{FIBONACCI}_GetResult"],
    }
    assert graph.topic_names_and_types() == {
        at["feedback"]: [f"{FIBONACCI}_FeedbackMessage"],
        at["status"]: ["action_msgs/msg/GoalStatusArray"],
    }
    [send_goal] = graph.endpoints(at["send_goal"], EntityKind.SERVICE)
    assert (send_goal.dds_type, send_goal.type_hash) == (
        "example_interfaces::action::dds_::Fibonacci_SendGoal_",
        f"RIHS01_{PUBLISHED['_SendGoal']}",
    )
    [status] = graph.endpoints(at["status"], EntityKind.PUBLISHER)
    assert status.type_hash == f"RIHS01_{STATUS_ARRAY_DIGEST}"
    assert status.qos is not None and (status.qos.durability, status.qos.depth) == (Durability.TRANSIENT_LOCAL, 1)
    assert {e.kind for e in graph.entities if e.node_name == "caller" and e.topic and e.topic.startswith("/robot")} == {
        EntityKind.CLIENT,
        EntityKind.SUBSCRIPTION,
    }


def test_a_rejected_goal_says_so_and_has_no_result(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    Fibonacci(server_node)
    client = caller.action_client("fibonacci", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    handle = client.send_goal(fibonacci_goal(99), timeout=FAILSAFE_S)
    assert not handle.accepted
    with pytest.raises(GoalRejected, match="/fibonacci: the server rejected the goal"):
        handle.result(FAILSAFE_S)


def test_an_accept_callback_that_raises_rejects_the_goal(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes

    def broken(goal_id: bytes, goal: Any) -> bool:
        raise RuntimeError("no idea")

    server_node.action_server("broken", FIBONACCI, on_goal=broken)
    client = caller.action_client("broken", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    assert not client.send_goal(fibonacci_goal(1), timeout=FAILSAFE_S).accepted


class Holding:
    """A server that keeps every goal running until the test ends it; cancels go through ``allow``."""

    def __init__(self, node: Ros2Node, allow: Callable[[bytes], bool] = lambda _: True, **options: Any) -> None:
        self.cancels: queue.Queue[bytes] = queue.Queue()

        def on_cancel(goal_id: bytes) -> bool:
            self.cancels.put(goal_id)
            return allow(goal_id)

        self.server: ActionServer = node.action_server("hold", FIBONACCI, on_cancel=on_cancel, **options)


def test_a_goal_is_cancelled_through_cancel_goal_and_ends_canceled(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    holding = Holding(server_node)
    client = caller.action_client("hold", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    handle = client.send_goal(fibonacci_goal(3), timeout=FAILSAFE_S)
    answer = handle.cancel(FAILSAFE_S)
    assert answer.return_code == CancelCode.NONE
    assert [bytes(info.goal_id.uuid.tobytes()) for info in answer.goals_canceling] == [handle.goal_id]
    assert holding.cancels.get(timeout=FAILSAFE_S) == handle.goal_id
    assert holding.server.status(handle.goal_id) is GoalStatus.CANCELING
    holding.server.canceled(handle.goal_id, sequence([0, 1]))
    ended = handle.result(FAILSAFE_S)
    assert ended.status is GoalStatus.CANCELED and list(ended.result.sequence) == [0, 1]
    # now it has ended, a cancel names a terminated goal; an id never sent names an unknown one
    assert handle.cancel(FAILSAFE_S).return_code == CancelCode.GOAL_TERMINATED
    CancelRequest = types.message_class("action_msgs/srv/CancelGoal_Request")
    GoalInfo, Time = types.message_class("action_msgs/msg/GoalInfo"), types.message_class("builtin_interfaces/msg/Time")
    stranger = CancelRequest(goal_info=GoalInfo(goal_id=goal_uuid(b"\x07" * 16), stamp=Time(sec=0, nanosec=0)))
    assert client._cancel.call(stranger, timeout=FAILSAFE_S).return_code == CancelCode.UNKNOWN_GOAL_ID


def test_a_refused_cancel_leaves_the_goal_running_and_cancel_all_takes_the_others(
    nodes: tuple[Ros2Node, Ros2Node],
) -> None:
    server_node, caller = nodes
    keep: set[bytes] = set()
    holding = Holding(server_node, allow=lambda goal_id: goal_id not in keep)
    client = caller.action_client("hold", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    kept, first, second = (client.send_goal(fibonacci_goal(n), timeout=FAILSAFE_S) for n in (1, 2, 3))
    keep.add(kept.goal_id)
    assert kept.cancel(FAILSAFE_S).return_code == CancelCode.REJECTED
    assert holding.server.status(kept.goal_id) is GoalStatus.EXECUTING
    CancelRequest = types.message_class("action_msgs/srv/CancelGoal_Request")
    GoalInfo, Time = types.message_class("action_msgs/msg/GoalInfo"), types.message_class("builtin_interfaces/msg/Time")
    everything = CancelRequest(goal_info=GoalInfo(goal_id=goal_uuid(bytes(16)), stamp=Time(sec=0, nanosec=0)))
    answer = client._cancel.call(everything, timeout=FAILSAFE_S)
    assert answer.return_code == CancelCode.NONE
    assert {info.goal_id.uuid.tobytes() for info in answer.goals_canceling} == {first.goal_id, second.goal_id}
    for handle in (first, second):
        holding.server.canceled(handle.goal_id)
        assert handle.result(FAILSAFE_S).status is GoalStatus.CANCELED
    holding.server.abort(kept.goal_id)
    assert kept.result(FAILSAFE_S).status is GoalStatus.ABORTED


def test_the_status_topic_follows_each_goal(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    holding = Holding(server_node)
    statuses: queue.Queue[list[tuple[bytes, int]]] = queue.Queue()

    def on_status(message: Any, _: Attachment) -> None:
        statuses.put([(s.goal_info.goal_id.uuid.tobytes(), s.status) for s in message.status_list])

    client = caller.action_client("hold", FIBONACCI)
    caller.subscription(
        "/hold/_action/status", "action_msgs/msg/GoalStatusArray", on_status, client._status_subscription.qos
    )
    assert client.wait_for_server(FAILSAFE_S)
    handle = client.send_goal(fibonacci_goal(1), timeout=FAILSAFE_S)

    def until_status(wanted: int) -> list[tuple[bytes, int]]:
        while True:
            seen = statuses.get(timeout=FAILSAFE_S)
            if (handle.goal_id, wanted) in seen:
                return seen

    assert until_status(GoalStatus.EXECUTING) == [(handle.goal_id, GoalStatus.EXECUTING)]
    holding.server.succeed(handle.goal_id, sequence([0]))
    assert until_status(GoalStatus.SUCCEEDED) == [(handle.goal_id, GoalStatus.SUCCEEDED)]
    assert handle.result(FAILSAFE_S).status is GoalStatus.SUCCEEDED and handle.status is GoalStatus.SUCCEEDED


def test_results_are_kept_for_a_bounded_number_of_goals(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    holding = Holding(server_node, max_results=1)
    client = caller.action_client("hold", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    older, newer = (client.send_goal(fibonacci_goal(n), timeout=FAILSAFE_S) for n in (1, 2))
    for handle, numbers in ((older, [1]), (newer, [2])):
        holding.server.succeed(handle.goal_id, sequence(numbers))
        assert list(handle.result(FAILSAFE_S).result.sequence) == numbers
    Request = types.message_class(f"{FIBONACCI}_GetResult_Request")
    ask = client._result.call  # asked again later, as any client may
    assert ask(Request(goal_id=goal_uuid(newer.goal_id)), timeout=FAILSAFE_S).status == GoalStatus.SUCCEEDED
    forgotten = ask(Request(goal_id=goal_uuid(older.goal_id)), timeout=FAILSAFE_S)
    assert forgotten.status == GoalStatus.UNKNOWN and list(forgotten.result.sequence) == []
    assert holding.server.status(older.goal_id) is GoalStatus.UNKNOWN


def test_the_server_refuses_what_the_goal_s_state_does_not_allow(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    holding = Holding(server_node)
    client = caller.action_client("hold", FIBONACCI)
    assert client.wait_for_server(FAILSAFE_S)
    handle = client.send_goal(fibonacci_goal(1), timeout=FAILSAFE_S)
    server = holding.server
    with pytest.raises(ValueError, match="only a goal whose cancel was accepted ends CANCELED"):
        server.canceled(handle.goal_id)
    with pytest.raises(TypeError, match="cannot be serialised as example_interfaces/action/Fibonacci_Result"):
        server.succeed(handle.goal_id, sequence([1], "_Feedback"))  # a feedback is not a result
    server.succeed(handle.goal_id)
    with pytest.raises(ValueError, match="already ended SUCCEEDED"):
        server.abort(handle.goal_id)
    with pytest.raises(KeyError, match="no goal"):
        server.publish_feedback(b"\x01" * 16, sequence([1], "_Feedback"))
    assert handle.result(FAILSAFE_S).status is GoalStatus.SUCCEEDED and len(handle.result().result.sequence) == 0


# -- servers that vanish ------------------------------------------------------------------------


def test_a_goal_fails_when_its_server_node_closes_and_the_liveliness_tokens_say_so() -> None:
    server_node, endpoint = listening_node("server")
    caller = Ros2Node("caller", connect=[endpoint])
    try:
        Holding(server_node)
        client = caller.action_client("hold", FIBONACCI)
        assert client.wait_for_server(FAILSAFE_S)
        handle = client.send_goal(fibonacci_goal(1), timeout=FAILSAFE_S)
        departures: queue.Queue[tuple[str, bool]] = queue.Queue()
        client.servers.listen(lambda zid, alive: departures.put((zid, alive)))
        server_zid = server_node.zid
        server_node.close()
        with pytest.raises(ActionServerLost, match=f"/hold: its server \\(Zenoh session {server_zid}\\) left") as lost:
            handle.result(FAILSAFE_S)
        assert lost.value.zid == server_zid
        assert departures.get(timeout=FAILSAFE_S) == (server_zid, False)  # the liveliness token's DELETE
        assert client.servers.left(server_zid)
    finally:
        caller.close()
        server_node.close()


def test_a_goal_fails_when_its_server_process_is_killed() -> None:
    caller, endpoint = listening_node("mission")
    server = ClientProcess("botstage_skill_server.py", endpoint)
    try:
        ready = server.expect("ready")
        assert ready is not None, server.log()
        client = caller.action_client("/skills/hold", SKILL_CALL)
        assert client.wait_for_server(FAILSAFE_S), server.log()
        feedback: queue.Queue[Any] = queue.Queue()
        Goal = types.message_class(f"{SKILL_CALL}_Goal")
        goal = Goal(skill="listen", inputs_json="{}", params_json="", call_id="mission/listen", tick=12)
        handle = client.send_goal(goal, on_feedback=feedback.put, timeout=FAILSAFE_S)
        assert handle.accepted and handle.server == ready["zid"]
        assert feedback.get(timeout=FAILSAFE_S).detail == "holding"  # it is running
        server.process.kill()  # SIGKILL: no goodbye, its tokens go when its connection breaks
        with pytest.raises(ActionServerLost) as lost:
            handle.result(FAILSAFE_S)
        assert lost.value.zid == ready["zid"]
    finally:
        server.process.kill()
        server.process.wait()
        caller.close()


# -- an independent peer ------------------------------------------------------------------------


def add_until_served(client: Any, request: Any) -> Any:
    """Call until the server answers: pyzeros declares its token before its queryable (rmw_zenoh after),
    so a call right after the token appears may find no queryable yet."""
    deadline, pace = time.monotonic() + FAILSAFE_S, threading.Event()
    while True:
        try:
            return client.call(request, timeout=FAILSAFE_S)
        except ServiceUnavailable:
            if time.monotonic() > deadline:
                raise
            pace.wait(0.05)


@pytest.mark.usefixtures("pyzeros_codecs")
def test_an_independent_peer_calls_botstage_services_and_its_skill_call_action_and_serves_one() -> None:
    node, endpoint = listening_node("bs")
    Trigger = types.message_class("std_srvs/srv/Trigger_Response")
    node.service("/bs/trigger", "std_srvs/srv/Trigger", lambda _: Trigger(success=True, message="triggered"))
    Feedback, Result = (types.message_class(f"{SKILL_CALL}{part}") for part in ("_Feedback", "_Result"))
    server: ActionServer

    def run(goal_id: bytes, goal: Any) -> None:
        for tick in (1, 2):
            server.publish_feedback(goal_id, Feedback(ticks=tick, detail=f"tick {tick}"))
        outputs = f'{{"echo": {goal.inputs_json}, "call_id": "{goal.call_id}", "tick": {goal.tick}}}'
        server.succeed(goal_id, Result(outcome="success", reason="", outputs_json=outputs, ticks=2))

    server = node.action_server("/bs/skills/echo", SKILL_CALL, on_accepted=run)
    peer = ClientProcess("pyzeros_services.py", endpoint)
    try:
        ready = peer.expect("ready")
        assert ready is not None, peer.log()
        assert {name: types.type_hash(name) for name in ready["hashes"] if name != "trigger"} == {
            name: digest for name, digest in ready["hashes"].items() if name != "trigger"
        }
        assert ready["hashes"]["trigger"] == types.type_hash("std_srvs/srv/Trigger")
        # botstage calls the peer's server (pyzeros)
        add = node.client("/pz/add_two_ints", "example_interfaces/srv/AddTwoInts")
        assert add.wait_for_service(FAILSAFE_S), peer.log()
        Request = types.message_class("example_interfaces/srv/AddTwoInts_Request")
        assert add_until_served(add, Request(a=40, b=2)).sum == 42
        assert add.servers.zids() == {ready["server_token"].split("/")[2]}
        # the peer lists botstage's servers with their types and hashes
        listed = peer.expect("services")
        assert listed is not None, peer.log()
        assert ["/bs/trigger", "std_srvs::srv::dds_::Trigger_", types.type_hash("std_srvs/srv/Trigger")] in listed[
            "services"
        ]
        assert [
            "/bs/skills/echo/_action/send_goal",
            "botstage_msgs::action::dds_::SkillCall_SendGoal_",
            types.type_hash(f"{SKILL_CALL}_SendGoal"),
        ] in listed["services"]
        # the peer calls botstage's service with pyzeros' client
        assert peer.expect("trigger") == {"event": "trigger", "success": True, "message": "triggered"}, peer.log()
        # and botstage's SkillCall action, rcl_action's way, from pyzeros' clients and subscription
        skill = peer.expect("skill")
        assert skill is not None, peer.log()
        assert skill["accepted"] and skill["status"] == GoalStatus.SUCCEEDED
        assert (skill["outcome"], skill["reason"], skill["ticks"]) == ("success", "", 2)
        assert skill["outputs_json"] == '{"echo": {"text": "hi"}, "call_id": "pz-1", "tick": 7}'
        assert skill["feedback"] == [{"ticks": 1, "detail": "tick 1"}, {"ticks": 2, "detail": "tick 2"}]
    finally:
        exit_code = peer.stop()
        node.close()
    assert exit_code == 0, peer.log()
