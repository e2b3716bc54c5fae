"""ROS 2 services in rmw_zenoh's wire format: type hashes, keys and tokens, calls over real Zenoh sessions.

Hashes are checked against values rosidl generated (ROS 2 Kilted's generated
``*__description.c`` files for std_srvs, example_interfaces and action_msgs, as shipped by
micro-ROS in hpmicro/hpm_sdk; rmw_zenoh's design.md for AddTwoInts) and against ros2_pyterfaces,
an independent implementation. Calls run between two nodes on loopback (127.0.0.1, free ports, no
multicast scouting); the wire format is also checked from raw eclipse-zenoh, without botstage's
client or server. Waits are on futures, events and queues with failsafe timeouts.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import zenoh
from ros2_pyterfaces.cyclone.std_srvs.srv import Empty, SetBool, Trigger

from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment, decode, encode
from botstage.robots.ros2.liveliness import EntityKind, parse_token
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.qos import History, QoS
from botstage.robots.ros2.service import (
    PendingRequest,
    ServiceError,
    ServiceTimeout,
    ServiceUnavailable,
    is_zenoh_timeout,
)
from tests.ros2_client.independent_interfaces import AddTwoInts, Measure, Measure_Request, Thing
from tests.test_ros2_interop import FAILSAFE_S, listening_node, until

ADD = "example_interfaces/srv/AddTwoInts"

# RIHS01 digests rosidl generated (ROS 2 Kilted, identical in Jazzy for these definitions).
PUBLISHED = {
    "example_interfaces/srv/AddTwoInts": "e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a",
    "std_srvs/srv/Empty": "5888399dedec5ccc85ea6451949fd2c9f97bfdf963f9a588821639fcd31b5d19",
    "std_srvs/srv/Trigger": "eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f",
    "std_srvs/srv/SetBool": "abe9e4bb6b41b40e6789712c00ec8871923e089af3f667a79992a428cff2da0a",
    "action_msgs/srv/CancelGoal": "573d8b0a534451d7bc2ac8c5ffde8ac14b8593b7001175d0cd6516dcbeb8689a",
    "action_msgs/srv/CancelGoal_Request": "3d3c84653c1f96918086887e1dcb236faec88b81a5b14fd4cf4840065bcdf8af",
    "action_msgs/srv/CancelGoal_Response": "35e682cf3f510e83c70a82a4aac888496dedee56773bf9d8e5e0aa81f9e1c960",
    "action_msgs/srv/CancelGoal_Event": "178f81615ce6be41ad328211d7a56b08b00e73f41f0b8aec256b2f3ff97a5e7e",
    "service_msgs/msg/ServiceEventInfo": "41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45",
    "std_msgs/msg/Char": "3ad2d04dd29ba19d04b16659afa3ccaedd691914b02a64e82e252f2fa6a586a9",
}


@pytest.mark.parametrize(("type_name", "digest"), sorted(PUBLISHED.items()))
def test_hashes_are_those_rosidl_generates(type_name: str, digest: str) -> None:
    assert types.type_hash(type_name) == f"RIHS01_{digest}"


@pytest.mark.parametrize("independent", [AddTwoInts, Empty, Trigger, SetBool], ids=lambda s: s.get_type_name())
def test_service_hashes_equal_an_independent_implementation(independent: Any) -> None:
    name = independent.get_type_name()
    assert types.type_hash(name) == independent.hash_rihs01()
    assert types.type_hash(f"{name}_Request") == independent.Request.hash_rihs01()
    assert types.type_hash(f"{name}_Response") == independent.Response.hash_rihs01()
    assert types.type_hash(f"{name}_Event") == independent.Event.hash_rihs01()


def test_message_hashes_equal_rosbags_except_where_rosbags_hashes_char_as_char() -> None:
    store = types.type_store()
    differ = {name for name in store.types if "/msg/" in name and types.type_hash(name) != store.hash_rihs01(name)}
    # rosidl hashes a .msg char as uint8; rosbags as char: only types with a char field differ
    assert {"std_msgs/msg/Char", "service_msgs/msg/ServiceEventInfo"} <= differ
    for name in differ:
        assert "char" in str(store.fielddefs[name]) or any(
            dependency in str(store.fielddefs[name]) for dependency in differ - {name}
        ), name


def test_a_service_is_a_file_away(tmp_path: Path) -> None:
    (tmp_path / "my_msgs" / "msg").mkdir(parents=True)
    (tmp_path / "my_msgs" / "srv").mkdir()
    (tmp_path / "my_msgs" / "msg" / "Thing.msg").write_text("int32 size\n", encoding="utf-8")
    (tmp_path / "my_msgs" / "srv" / "Measure.srv").write_text(
        "# how big is it\nThing thing\nstring<=8 unit\n---\nfloat64[3] sizes\nbool ok\n", encoding="utf-8"
    )
    interfaces = types.load_interfaces(tmp_path)
    assert interfaces.services == {"my_msgs/srv/Measure"}

    assert interfaces.type_hash("my_msgs/srv/Measure") == Measure.hash_rihs01()
    Request = interfaces.store.types["my_msgs/srv/Measure_Request"]
    OwnThing = interfaces.store.types["my_msgs/msg/Thing"]
    request = Request(thing=OwnThing(size=3), unit="m")
    payload = bytes(interfaces.store.serialize_cdr(request, "my_msgs/srv/Measure_Request"))
    assert payload == bytes(Measure_Request(thing=Thing(size=3), unit="m").serialize())


@pytest.mark.parametrize(
    ("text", "says"),
    [("int32 a\n", "0 '---' separators"), ("int32 a\n---\n---\n", "2 '---' separators"), ("int3 a\n---\n", "Demo")],
)
def test_a_broken_srv_file_is_named_in_the_error(tmp_path: Path, text: str, says: str) -> None:
    (tmp_path / "my_msgs" / "srv").mkdir(parents=True)
    (tmp_path / "my_msgs" / "srv" / "Demo.srv").write_text(text, encoding="utf-8")
    with pytest.raises(types.DefinitionError, match=f"my_msgs/srv/Demo.*{says}|{says}"):
        types.load_interfaces(tmp_path)


def test_a_service_type_is_not_a_message_type() -> None:
    assert types.service_type(ADD).request == f"{ADD}_Request"
    with pytest.raises(types.UnknownTypeError, match="not a service type"):
        types.service_type("std_msgs/msg/String")
    with pytest.raises(types.UnknownTypeError, match=r"unknown service type 'std_srvs/srv/Trigerr'.*did you mean"):
        types.service_type("std_srvs/srv/Trigerr")
    with pytest.raises(types.UnknownTypeError, match="unknown message type"):
        types.message_class("std_srvs/srv/Trigger")  # a service has no instances: its request and response do


# -- calls over real sessions -------------------------------------------------------------------


@pytest.fixture
def nodes() -> Iterator[tuple[Ros2Node, Ros2Node]]:
    """A server node listening on loopback and a caller node connected to it."""
    server, endpoint = listening_node("server", clock=lambda: 1_700_000_000_000_000_042)
    caller = Ros2Node("caller", connect=[endpoint])
    yield server, caller
    caller.close()
    server.close()


def add(request: Any) -> Any:
    return types.message_class(f"{ADD}_Response")(sum=request.a + request.b)


def add_request(a: int, b: int) -> Any:
    return types.message_class(f"{ADD}_Request")(a=a, b=b)


class Held:
    """A handler that adds, but holds each request until released: ``entered`` once one is held,
    ``order`` the ``a`` of each in the order handled."""

    def __init__(self) -> None:
        self.entered, self.release = threading.Event(), threading.Event()
        self.order: list[int] = []

    def __call__(self, request: Any) -> Any:
        self.order.append(request.a)
        self.entered.set()
        self.release.wait(FAILSAFE_S)
        return add(request)


def test_a_call_goes_round_trip_and_the_graph_lists_both_ends(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    threads: list[str] = []

    def handler(request: Any) -> Any:
        threads.append(threading.current_thread().name)
        return add(request)

    server = server_node.service("add_two_ints", ADD, handler)
    client = caller.client("/add_two_ints", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    assert client.call(add_request(2, 40), timeout=FAILSAFE_S).sum == 42
    assert client.call_async(add_request(-5, 3)).result(FAILSAFE_S).sum == -2
    assert threads == ["service /add_two_ints"] * 2  # the server's own thread, never Zenoh's
    key = f"0/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/RIHS01_{PUBLISHED[ADD]}"
    assert server.key == client.key == key  # rmw_zenoh's design.md example, with domain 0
    assert parse_token(server.token).kind is EntityKind.SERVICE and parse_token(client.token).kind is EntityKind.CLIENT
    tail = f"/%add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/RIHS01_{PUBLISHED[ADD]}/::,10:,:,:,,"
    assert server.token.endswith(tail) and client.token.endswith(tail)
    graph = caller.graph()
    assert graph.service_names_and_types() == {"/add_two_ints": [ADD]}
    assert [e.node_fqn for e in graph.endpoints("/add_two_ints", EntityKind.SERVICE)] == ["/server"]
    assert client.servers.zids() == {server_node.zid}
    assert server.stats.received == 2


def test_the_server_answers_rmw_zenoh_s_wire_format(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    """A raw Zenoh query, as rmw_zenoh's client sends it: the reply echoes sequence number and GID."""
    server_node, caller = nodes
    server = server_node.service("add_two_ints", ADD, add)
    assert caller.client("add_two_ints", ADD).wait_for_service(FAILSAFE_S)
    gid = bytes(range(16))
    replies = list(
        caller.session.get(
            server.key,
            payload=types.serialize(add_request(20, 22)),
            attachment=encode(Attachment(41, 123, gid)),
            target=zenoh.QueryTarget.ALL_COMPLETE,
            consolidation=zenoh.ConsolidationMode.NONE,
            timeout=FAILSAFE_S,
        )
    )
    assert len(replies) == 1 and replies[0].ok is not None
    sample = replies[0].ok
    assert str(sample.key_expr) == server.key
    answer = decode(sample.attachment.to_bytes())
    assert (answer.sequence, answer.gid, answer.timestamp_ns) == (41, gid, 1_700_000_000_000_000_042)
    assert sample.payload.to_bytes()[:4] == b"\x00\x01\x00\x00"
    assert types.deserialize(sample.payload.to_bytes(), f"{ADD}_Response").sum == 42


def test_the_client_sends_rmw_zenoh_s_wire_format_and_matches_replies_by_sequence(
    nodes: tuple[Ros2Node, Ros2Node],
) -> None:
    """A raw queryable sees the request; a reply for another sequence number is not taken for it."""
    server_node, caller = nodes
    client = caller.client("add_two_ints", ADD)
    seen: queue.Queue[tuple[Attachment, Any]] = queue.Queue()

    def answer(query: zenoh.Query) -> None:
        sent = decode(query.attachment.to_bytes())
        request = types.deserialize(query.payload.to_bytes(), f"{ADD}_Request")
        seen.put((sent, request))
        response = types.serialize(add(request))
        if request.a == 0:  # first a reply for a call that is not this one, then the right one
            query.reply(query.key_expr, response, attachment=encode(Attachment(sent.sequence + 7, 1, sent.gid)))
        query.reply(query.key_expr, response, attachment=encode(Attachment(sent.sequence, 1, sent.gid)))
        query.drop()

    queryable = server_node.session.declare_queryable(client.key, answer, complete=True)
    querier = caller.session.declare_querier(client.key, target=zenoh.QueryTarget.ALL_COMPLETE)
    try:
        assert until(lambda: querier.matching_status.matching)  # the raw queryable has no token to wait for
        assert client.call(add_request(0, 5), timeout=FAILSAFE_S).sum == 5
        assert client.call(add_request(1, 5), timeout=FAILSAFE_S).sum == 6
    finally:
        querier.undeclare()
        queryable.undeclare()
    first, second = seen.get_nowait(), seen.get_nowait()
    assert (first[0].sequence, second[0].sequence) == (1, 2)  # rmw_zenoh counts from 1
    assert first[0].gid == second[0].gid == client.gid
    assert client.unmatched_replies == 1


def test_a_call_without_a_server_fails_at_once_rather_than_waiting(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    _, caller = nodes
    client = caller.client("nobody_home", ADD)
    assert not client.wait_for_service(0.0)
    with pytest.raises(ServiceUnavailable, match=r"/nobody_home .*no server answered"):
        client.call(add_request(1, 2), timeout=FAILSAFE_S)  # ends when Zenoh ends the query, not at the timeout


def test_a_slow_server_times_the_call_out_and_the_late_answer_is_dropped(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    slow = Held()
    entered, release = slow.entered, slow.release
    server_node.service("slow", ADD, slow)
    client = caller.client("slow", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    with pytest.raises(ServiceTimeout, match=r"/slow: no response within 0\.05 s") as timed_out:
        client.call(add_request(1, 1), timeout=0.05)
    assert isinstance(timed_out.value, TimeoutError)
    assert entered.wait(FAILSAFE_S)
    release.set()
    assert client.call(add_request(2, 2), timeout=FAILSAFE_S).sum == 4  # the late answer was not taken for this one


def test_zenohs_own_timeout_is_told_from_a_servers_error_whoever_sends_it() -> None:
    """Under load the server's session can send Zenoh's "Timeout" before the caller's, naming itself."""

    def reply(payload: bytes | None, replier: object) -> Any:
        err = None if payload is None else SimpleNamespace(payload=zenoh.ZBytes(payload))
        return SimpleNamespace(err=err, replier_id=replier)

    server = SimpleNamespace(zid="205d8bbfe15fc42c0fef2c67ba2edc70")
    assert is_zenoh_timeout(reply(b"Timeout", None))  # the caller's own session
    assert is_zenoh_timeout(reply(b"Timeout", server))  # the server's session, first under load
    assert not is_zenoh_timeout(reply(b"service /slow: the handler raised TimeoutError: db", server))
    assert not is_zenoh_timeout(reply(None, server))  # an answer


def test_a_raising_handler_answers_an_error_and_the_server_goes_on(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes

    def picky(request: Any) -> Any:
        if request.a < 0:
            raise ValueError("negative numbers are not welcome")
        return add(request)

    server = server_node.service("picky", ADD, picky)
    client = caller.client("picky", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    with pytest.raises(ServiceError, match="the handler raised ValueError: negative numbers are not welcome"):
        client.call(add_request(-1, 1), timeout=FAILSAFE_S)
    assert client.call(add_request(1, 1), timeout=FAILSAFE_S).sum == 2
    assert (server.stats.received, server.stats.handler_errors) == (2, 1)


def test_a_request_the_server_cannot_read_gets_an_error_reply(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    server = server_node.service("add_two_ints", ADD, add)
    assert caller.client("add_two_ints", ADD).wait_for_service(FAILSAFE_S)
    cases = [
        {"payload": types.serialize(add_request(1, 2))},  # no attachment
        {"payload": b"\x00\x01\x00\x00\x01", "attachment": encode(Attachment(1, 1, bytes(16)))},  # not an AddTwoInts
    ]
    errors = []
    for options in cases:
        for reply in caller.session.get(server.key, timeout=FAILSAFE_S, **options):
            errors.append(reply.err.payload.to_bytes().decode() if reply.err is not None else "ok?")
    assert len(errors) == 2 and all("bad request" in e for e in errors), errors
    assert "no attachment" in errors[0] and "not a example_interfaces/srv/AddTwoInts_Request" in errors[1]
    assert server.stats.bad_requests == 2 and server.stats.received == 0


def test_a_deferred_server_answers_later_from_any_thread_and_only_once(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    taken: queue.Queue[PendingRequest] = queue.Queue()
    server_node.service("later", ADD, taken.put, deferred=True)
    client = caller.client("later", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    call = client.call_async(add_request(3, 4))
    pending = taken.get(timeout=FAILSAFE_S)
    assert pending.client.gid == client.gid and pending.client.sequence == call.sequence == 1
    assert not call.done()
    assert pending.reply(add(pending.request))
    assert not pending.reply(add(pending.request)) and not pending.fail("too late")
    assert call.result(FAILSAFE_S).sum == 7
    assert call.replier == server_node.zid


def test_a_full_keep_last_queue_drops_the_oldest_request(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    blocking = Held()
    entered, release = blocking.entered, blocking.release
    server = server_node.service("narrow", ADD, blocking, QoS(depth=1))
    server_node.service("probe", ADD, add)
    client, probe = caller.client("narrow", ADD), caller.client("probe", ADD)
    assert client.wait_for_service(FAILSAFE_S) and probe.wait_for_service(FAILSAFE_S)
    first = client.call_async(add_request(1, 0))
    assert entered.wait(FAILSAFE_S)  # the first is being handled: nothing waits
    second, third = client.call_async(add_request(2, 0)), client.call_async(add_request(3, 0))
    # one link delivers in order: once the probe is answered, the second and third wait at the server
    assert probe.call(add_request(0, 0), FAILSAFE_S).sum == 0
    assert not second.done()  # told when the server's thread is free, not as it arrives
    release.set()
    with pytest.raises(ServiceError, match="request dropped, the server's queue of 1 is full"):
        second.result(FAILSAFE_S)
    assert (first.result(FAILSAFE_S).sum, third.result(FAILSAFE_S).sum) == (1, 3)
    assert server.stats.dropped == 1 and server.stats.received == 3


def test_keep_all_answers_every_waiting_request_in_arrival_order(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    blocking = Held()
    entered, release, order = blocking.entered, blocking.release, blocking.order
    server = server_node.service("wide", ADD, blocking, QoS(history=History.KEEP_ALL))
    client = caller.client("wide", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    calls = [client.call_async(add_request(1, 0))]
    assert entered.wait(FAILSAFE_S)
    calls += [client.call_async(add_request(a, 0)) for a in range(2, 6)]
    release.set()
    assert [call.result(FAILSAFE_S).sum for call in calls] == [1, 2, 3, 4, 5]
    assert order == [1, 2, 3, 4, 5] and server.stats.dropped == 0


def test_closing_a_busy_server_ends_its_waiting_requests_unanswered_and_stops_its_thread(
    nodes: tuple[Ros2Node, Ros2Node],
) -> None:
    server_node, caller = nodes
    blocking = Held()
    entered, release = blocking.entered, blocking.release
    server = server_node.service("closing", ADD, blocking)
    server_node.service("probe", ADD, add)
    client, probe = caller.client("closing", ADD), caller.client("probe", ADD)
    assert client.wait_for_service(FAILSAFE_S) and probe.wait_for_service(FAILSAFE_S)
    first = client.call_async(add_request(1, 0))
    assert entered.wait(FAILSAFE_S)
    second = client.call_async(add_request(2, 0))
    assert probe.call(add_request(0, 0), FAILSAFE_S).sum == 0  # the second waits at the server
    closing = threading.Thread(target=server.close)
    closing.start()
    assert until(lambda: server.closed)
    release.set()  # close() waits for the running handler; its answer is not sent
    closing.join(FAILSAFE_S)
    assert not closing.is_alive() and not server._thread.is_alive()
    for call in (first, second):
        with pytest.raises(ServiceUnavailable):
            call.result(FAILSAFE_S)
    assert server.stats.received == 1  # the second was never taken


def test_wait_for_service_follows_servers_coming_and_going(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    client = caller.client("coming", ADD)
    changes: queue.Queue[tuple[str, bool]] = queue.Queue()
    client.servers.listen(lambda zid, alive: changes.put((zid, alive)))
    assert not client.wait_for_service(0.05)
    server = server_node.service("coming", ADD, add)
    assert client.wait_for_service(FAILSAFE_S)
    assert changes.get(timeout=FAILSAFE_S) == (server_node.zid, True)
    server.close()
    assert changes.get(timeout=FAILSAFE_S) == (server_node.zid, False)
    assert client.servers.zids() == frozenset() and client.servers.left(server_node.zid)
    with pytest.raises(ServiceUnavailable):
        client.call(add_request(1, 1), timeout=FAILSAFE_S)


def test_closing_ends_calls_in_flight_on_both_sides(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    server_node, caller = nodes
    taken: queue.Queue[PendingRequest] = queue.Queue()
    server = server_node.service("held", ADD, taken.put, deferred=True)
    client = caller.client("held", ADD)
    assert client.wait_for_service(FAILSAFE_S)
    held = client.call_async(add_request(1, 1))
    pending = taken.get(timeout=FAILSAFE_S)
    server.close()
    assert not pending.reply(add(pending.request))  # a closed server sends nothing
    pending.drop()
    with pytest.raises(ServiceUnavailable):
        held.result(FAILSAFE_S)
    second = caller.client("held", ADD)
    server_node.service("held", ADD, taken.put, deferred=True)
    assert second.wait_for_service(FAILSAFE_S)
    waiting = second.call_async(add_request(2, 2))
    taken.get(timeout=FAILSAFE_S)
    second.close()
    with pytest.raises(ServiceError, match="client of /held closed"):
        waiting.result(FAILSAFE_S)
    with pytest.raises(RuntimeError, match="closed"):
        second.call_async(add_request(3, 3))
