"""botstage's ROS 2 node against an independent ROS 2-over-Zenoh client, another botstage process, itself.

The independent client is pyzeros (tests/ros2_client/pyzeros_probe.py, its own process): it must
list botstage's node and topics from liveliness, receive geometry_msgs/Twist on /cmd_vel, and
publish a sensor_msgs/LaserScan on /scan that botstage decodes with its attachment. Everything is on
loopback (127.0.0.1, free ports, no multicast scouting). Waits are on events and queues, each
with a failsafe timeout; a loop that publishes until the other side answers paces itself on an
event, it never sleeps to decide an assertion.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import zenoh

from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment, encode, entity_gid
from botstage.robots.ros2.graph import Graph
from botstage.robots.ros2.liveliness import EntityKind, parse_token
from botstage.robots.ros2.node import DEFAULT_LISTEN, Ros2Node, SubscriptionStats, session_config
from botstage.robots.ros2.qos import Durability, QoS

ROOT = Path(__file__).resolve().parent.parent
CLIENTS = Path(__file__).resolve().parent / "ros2_client"
FAILSAFE_S = 60.0  # generous: a loaded 2-core machine; nothing here waits this long when it works
PERIOD_S = 0.05
# pyzeros' codecs are compiled by cydr (Cython, ~30 s of one core) on first use: into a cache
# kept across runs, outside the work tree, and before any exchange starts its clocks.
CYDR_CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "botstage" / "cydr"
BUILD_BUDGET_S = 900.0


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def listening_node(name: str, **kwargs: Any) -> tuple[Ros2Node, str]:
    """A node listening on a free loopback port, and that endpoint (another port if one was taken meanwhile)."""
    for _ in range(5):
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        try:
            return Ros2Node(name, listen=[endpoint], **kwargs), endpoint
        except zenoh.ZError as error:
            if "in use" not in str(error):
                raise
    raise RuntimeError("no free loopback port after 5 tries")


def until(condition: Callable[[], bool], timeout: float = FAILSAFE_S) -> bool:
    """Poll ``condition`` on a short event-paced period until it holds or the failsafe passes."""
    deadline, pace = time.monotonic() + timeout, threading.Event()
    while not condition():
        if time.monotonic() > deadline:
            return False
        pace.wait(PERIOD_S)
    return True


def publish_until(publish: Callable[[], object], done: threading.Event) -> threading.Thread:
    """Publish every PERIOD_S on a thread until ``done`` is set (or the failsafe passes)."""

    def loop() -> None:
        deadline = time.monotonic() + FAILSAFE_S
        while not done.is_set() and time.monotonic() < deadline:
            publish()
            done.wait(PERIOD_S)

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    return thread


class ClientProcess:
    """A helper script in its own process: JSON events from its stdout, ``stop`` on its stdin."""

    def __init__(self, script: str, *args: str) -> None:
        env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH_", "ROS_"))}
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        env["CYDR_CACHE_DIR"] = str(CYDR_CACHE)
        self.process = subprocess.Popen(
            [sys.executable, str(CLIENTS / script), *args],
            cwd=ROOT,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        self.stderr: list[str] = []
        threading.Thread(target=self._read_events, daemon=True).start()
        threading.Thread(target=lambda: self.stderr.extend(self.process.stderr), daemon=True).start()

    def _read_events(self) -> None:
        for line in self.process.stdout:
            try:
                self.events.put(json.loads(line))
            except json.JSONDecodeError:
                self.stderr.append(f"(stdout) {line}")

    def expect(self, event: str, timeout: float = FAILSAFE_S) -> dict[str, Any] | None:
        """The next event named ``event`` (others before it are skipped), or None after the failsafe."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                received = self.events.get(timeout=left)
            except queue.Empty:
                break
            if received.get("event") == event:
                return received
        return None

    def stop(self) -> int | None:
        """Ask it to leave, and its exit code (None, after killing it, if it does not exit in time)."""
        try:
            self.process.stdin.write("stop\n")
            self.process.stdin.close()
        except (BrokenPipeError, OSError):
            pass
        try:
            return self.process.wait(timeout=FAILSAFE_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            return None

    def log(self) -> str:
        return "".join(self.stderr)[-4000:]


# -- the independent client ----------------------------------------------------------------------


@dataclass
class Exchange:
    """What botstage and the pyzeros client saw of each other in one run."""

    client_graph: dict[str, Any] | None = None
    client_ready: dict[str, Any] | None = None
    client_twist: dict[str, Any] | None = None
    scans: list[tuple[Any, Attachment]] = field(default_factory=list)
    botstage_graph: Graph | None = None
    twists_sent: int = 0
    exit_code: int | None = None
    client_log: str = ""


TWIST = {"linear": (0.5, 0.0, 0.0), "angular_z": -0.25}


def twist_message() -> Any:
    Twist, Vector3 = types.message_class("geometry_msgs/msg/Twist"), types.message_class("geometry_msgs/msg/Vector3")
    x, y, z = TWIST["linear"]
    return Twist(linear=Vector3(x=x, y=y, z=z), angular=Vector3(x=0.0, y=0.0, z=TWIST["angular_z"]))


@pytest.fixture(scope="session")
def pyzeros_codecs() -> None:
    """pyzeros' compiled codecs, built once (a build step with its own budget, not part of any exchange)."""
    CYDR_CACHE.mkdir(parents=True, exist_ok=True)
    warm_up = ClientProcess("pyzeros_probe.py", "--warmup")
    try:
        code = warm_up.process.wait(timeout=BUILD_BUDGET_S)
    except subprocess.TimeoutExpired:
        code = warm_up.stop()
    assert code == 0, f"pyzeros' codecs did not build:\n{warm_up.log()}"


@pytest.fixture(scope="module")
def exchange(pyzeros_codecs: None) -> Iterator[Exchange]:
    """botstage's node (cmd_vel out, scan in) and the pyzeros probe in its own process, run once."""
    seen = Exchange()
    scans: queue.Queue[tuple[Any, Attachment]] = queue.Queue()
    node, endpoint = listening_node("botstage")
    client: ClientProcess | None = None
    done = threading.Event()
    try:
        cmd_vel = node.publisher("cmd_vel", "geometry_msgs/msg/Twist")
        node.subscription("scan", "sensor_msgs/msg/LaserScan", lambda m, a: scans.put((m, a)))
        client = ClientProcess("pyzeros_probe.py", endpoint, node.fqn)
        seen.client_graph = client.expect("graph")
        seen.client_ready = client.expect("ready")
        publish_until(lambda: cmd_vel.publish(twist_message()), done)
        seen.client_twist = client.expect("twist")
        with contextlib.suppress(queue.Empty):
            seen.scans.append(scans.get(timeout=FAILSAFE_S))

        def probe_in_graph() -> bool:
            seen.botstage_graph = node.graph()
            return "/probe" in seen.botstage_graph.node_names() and bool(
                seen.botstage_graph.endpoints("/scan", EntityKind.PUBLISHER)
            )

        until(probe_in_graph)
        done.set()
        seen.twists_sent = cmd_vel.sequence
    finally:
        done.set()
        if client is not None:
            seen.exit_code = client.stop()
            seen.client_log = client.log()
        node.close()
    yield seen


def test_the_independent_client_lists_botstage_node_and_topics_with_types(exchange: Exchange) -> None:
    graph = exchange.client_graph
    assert graph is not None, f"no graph from the client:\n{exchange.client_log}"
    assert "/botstage" in graph["nodes"]
    assert [
        "/cmd_vel",
        "geometry_msgs::msg::dds_::Twist_",
        types.type_hash("geometry_msgs/msg/Twist"),
        "MP",
    ] in graph["topics"]
    assert [
        "/scan",
        "sensor_msgs::msg::dds_::LaserScan_",
        types.type_hash("sensor_msgs/msg/LaserScan"),
        "MS",
    ] in graph["topics"]
    # the client's own type definitions hash to what botstage advertises
    assert graph["hashes"] == {
        "twist": types.type_hash("geometry_msgs/msg/Twist"),
        "scan": types.type_hash("sensor_msgs/msg/LaserScan"),
    }


def test_the_independent_client_receives_cmd_vel_as_a_twist(exchange: Exchange) -> None:
    twist = exchange.client_twist
    assert twist is not None, f"the client got no Twist ({exchange.twists_sent} sent):\n{exchange.client_log}"
    assert twist["linear"] == list(TWIST["linear"])
    assert twist["angular"] == [TWIST["angular_z"]]


def test_botstage_decodes_the_scan_the_client_publishes_with_its_attachment(exchange: Exchange) -> None:
    assert exchange.scans, f"botstage got no scan:\n{exchange.client_log}"
    scan, attachment = exchange.scans[0]
    assert scan.header.frame_id == "laser"
    assert (scan.header.stamp.sec, scan.header.stamp.nanosec) == (7, 250)
    assert list(scan.ranges) == [1.5, 2.0, 2.5, 3.0, 3.5]
    assert (scan.angle_min, scan.angle_max, scan.range_max) == (-1.0, 1.0, 10.0)
    assert len(scan.intensities) == 0
    # the attachment's GID is rmw_zenoh's: XXH3-128 of the publisher's token, which botstage's graph holds
    assert exchange.client_ready is not None
    token = exchange.client_ready["pub_token"]
    assert attachment.gid == entity_gid(token)
    assert attachment.sequence >= 0 and attachment.timestamp_ns > 0
    assert exchange.botstage_graph is not None
    publishers = exchange.botstage_graph.endpoints("/scan", EntityKind.PUBLISHER)
    assert [(p.node_fqn, p.dds_type, p.type_hash) for p in publishers] == [
        ("/probe", "sensor_msgs::msg::dds_::LaserScan_", types.type_hash("sensor_msgs/msg/LaserScan"))
    ]
    assert parse_token(token) == publishers[0]


def test_the_independent_client_leaves_cleanly(exchange: Exchange) -> None:
    assert exchange.exit_code == 0, exchange.client_log


# -- botstage to botstage, across processes ------------------------------------------------------


def test_two_botstage_processes_exchange_messages_both_ways() -> None:
    echoes: queue.Queue[tuple[Any, Attachment]] = queue.Queue()
    node, endpoint = listening_node("botstage")
    done = threading.Event()
    echo = ClientProcess("botstage_echo.py", endpoint)
    try:
        node.subscription("/echo", "std_msgs/msg/String", lambda m, a: echoes.put((m, a)))
        chatter = node.publisher("/chatter", "std_msgs/msg/String", QoS.sensor_data())
        ready = echo.expect("ready")
        assert ready is not None, echo.log()
        String = types.message_class("std_msgs/msg/String")
        publish_until(lambda: chatter.publish(String(data="hello")), done)
        try:
            message, attachment = echoes.get(timeout=FAILSAFE_S)
        except queue.Empty:
            pytest.fail(f"no echo came back:\n{echo.log()}")
        done.set()
        sequence = int(message.data.rsplit("#", 1)[1])
        assert message.data == f"echo: hello #{sequence}" and 1 <= sequence <= chatter.sequence
        assert attachment.gid == entity_gid(ready["pub_token"]) and attachment.sequence >= 1

        def echo_listed() -> bool:
            graph = node.graph()
            return graph.topic_names_and_types() == {
                "/chatter": ["std_msgs/msg/String"],
                "/echo": ["std_msgs/msg/String"],
            } and graph.node_names() == ["/botstage", "/echo"]

        assert until(echo_listed), node.graph()
    finally:
        done.set()
        exit_code = echo.stop()
        node.close()
    assert exit_code == 0, echo.log()


# -- one node, in-process ------------------------------------------------------------------------


@pytest.fixture
def node_and_endpoint() -> Iterator[tuple[Ros2Node, str]]:
    node, endpoint = listening_node("botstage", clock=lambda: 1_700_000_000_000_000_123)
    yield node, endpoint
    node.close()


def test_a_subscription_drops_and_counts_what_it_cannot_use_and_survives_its_callback(
    node_and_endpoint: tuple[Ros2Node, str],
) -> None:
    node, endpoint = node_and_endpoint
    delivered: queue.Queue[str] = queue.Queue()

    def callback(message: Any, attachment: Attachment) -> None:
        if message.data == "boom":
            raise RuntimeError("a bug in the callback")
        delivered.put(message.data)

    subscription = node.subscription("/chatter", "std_msgs/msg/String", callback)
    String = types.message_class("std_msgs/msg/String")
    good = encode(Attachment(1, 5, bytes(16)))
    with zenoh.open(session_config(connect=[endpoint])) as raw:

        def put(payload: bytes, attachment: bytes | None = good) -> None:
            raw.put(subscription.key, payload, attachment=attachment)

        def string(data: str) -> bytes:
            return types.serialize(String(data=data))

        stop = threading.Event()
        warming = publish_until(lambda: put(string("warm-up")), stop)
        try:
            assert delivered.get(timeout=FAILSAFE_S) == "warm-up"
        finally:
            stop.set()
            warming.join(FAILSAFE_S)
        # one session, one key: these arrive in the order they are put, the marker last
        put(string("no attachment"), None)
        put(string("short attachment"), b"\x01\x02\x03")
        put(b"\x00\x01\x00\x00\x07")  # a String's length, and nothing after it
        put(b"\x00\x07\x00\x00" + bytes(8))  # XCDR2, not the plain CDR of ROS 2
        put(string("boom"))
        put(string("marker"))
        items: list[str] = []
        while "marker" not in items:
            items.append(delivered.get(timeout=FAILSAFE_S))
    assert set(items[:-1]) <= {"warm-up"}
    assert subscription.stats == SubscriptionStats(
        received=len(items) + 2,  # the first warm-up, the later ones and the marker, "boom"
        no_attachment=1,
        bad_attachment=1,
        bad_cdr=2,
        callback_errors=1,
    )


def test_publications_carry_sequence_from_one_and_the_node_clock(node_and_endpoint: tuple[Ros2Node, str]) -> None:
    node, _ = node_and_endpoint
    received: queue.Queue[Attachment] = queue.Queue()
    publisher = node.publisher("/counter", "std_msgs/msg/String")
    node.subscription("/counter", "std_msgs/msg/String", lambda m, a: received.put(a))  # local delivery
    String = types.message_class("std_msgs/msg/String")
    sent = [publisher.publish(String(data=str(i))) for i in range(3)]
    assert [a.sequence for a in sent] == [1, 2, 3]
    assert {a.timestamp_ns for a in sent} == {1_700_000_000_000_000_123}
    assert {a.gid for a in sent} == {entity_gid(publisher.token)}
    assert [received.get(timeout=FAILSAFE_S) for _ in range(3)] == sent


def test_closing_a_publisher_while_other_threads_publish_is_clean(node_and_endpoint: tuple[Ros2Node, str]) -> None:
    """Zenoh refuses to undeclare a publisher during a put: close waits for the put in flight."""
    node, _ = node_and_endpoint
    publisher = node.publisher("/busy", "std_msgs/msg/String", QoS.sensor_data())
    node.subscription("/busy", "std_msgs/msg/String", lambda m, a: None)  # puts then deliver, taking time
    message = types.message_class("std_msgs/msg/String")(data="x" * 10_000)
    outcomes: list[str] = []

    def hammer() -> None:
        try:
            while True:
                publisher.publish(message)
        except RuntimeError as error:
            outcomes.append(str(error))

    threads = [threading.Thread(target=hammer) for _ in range(3)]
    for thread in threads:
        thread.start()
    assert until(lambda: publisher.sequence >= 200)
    publisher.close()
    for thread in threads:
        thread.join(FAILSAFE_S)
    assert outcomes == ["publisher on /busy is closed"] * 3


def test_a_late_transient_local_subscription_gets_the_latched_message(
    node_and_endpoint: tuple[Ros2Node, str],
) -> None:
    node, endpoint = node_and_endpoint
    latched = QoS(durability=Durability.TRANSIENT_LOCAL, depth=1)
    String = types.message_class("std_msgs/msg/String")
    node.publisher("/map_name", "std_msgs/msg/String", latched).publish(String(data="museum"))
    got: queue.Queue[str] = queue.Queue()
    with Ros2Node("late", connect=[endpoint]) as late:
        late.subscription("/map_name", "std_msgs/msg/String", lambda m, a: got.put(m.data), latched)
        assert got.get(timeout=FAILSAFE_S) == "museum"


def test_the_graph_forgets_a_closed_node_and_closed_entities(node_and_endpoint: tuple[Ros2Node, str]) -> None:
    node, endpoint = node_and_endpoint
    other = Ros2Node("other", "/robot1", connect=[endpoint])
    publisher = other.publisher("odom", "nav_msgs/msg/Odometry", QoS.sensor_data())
    other.subscription("cmd_vel", "geometry_msgs/msg/Twist", lambda m, a: None)
    assert until(
        lambda: (
            node.graph().topic_names_and_types()
            == {"/robot1/cmd_vel": ["geometry_msgs/msg/Twist"], "/robot1/odom": ["nav_msgs/msg/Odometry"]}
        )
    ), node.graph()
    (odom,) = node.graph().endpoints("/robot1/odom", EntityKind.PUBLISHER)
    assert odom.qos == QoS.sensor_data() and odom.node_fqn == "/robot1/other"
    publisher.close()
    assert until(lambda: "/robot1/odom" not in node.graph().topic_names_and_types()), node.graph()
    other.close()
    assert until(lambda: node.graph().node_names() == ["/botstage"]), node.graph()


def test_a_router_node_stands_in_for_rmw_zenohd() -> None:
    """Two peers that only know the router find each other through it and exchange messages."""
    router, endpoint = listening_node("router", mode="router")
    got: queue.Queue[str] = queue.Queue()
    done = threading.Event()
    try:
        with Ros2Node("talker", connect=[endpoint]) as talker, Ros2Node("listener", connect=[endpoint]) as listener:
            listener.subscription("/chatter", "std_msgs/msg/String", lambda m, a: got.put(m.data))
            chatter = talker.publisher("/chatter", "std_msgs/msg/String")
            String = types.message_class("std_msgs/msg/String")
            publish_until(lambda: chatter.publish(String(data="via the router")), done)
            assert got.get(timeout=FAILSAFE_S) == "via the router"
            done.set()
            assert until(lambda: {"/talker", "/listener", "/router"} <= set(talker.graph().node_names()))
    finally:
        done.set()
        router.close()


def test_sessions_listen_on_loopback_only_and_never_scout_by_multicast() -> None:
    config = session_config()
    assert json.loads(config.get_json("listen/endpoints")) == [DEFAULT_LISTEN] == ["tcp/127.0.0.1:0"]
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("mode")) == "peer"
    with pytest.raises(ValueError, match="'peer' or 'router'"):
        session_config(mode="client")  # type: ignore[arg-type]


# -- botstage's own types, as an independent implementation sees them ----------------------------


def test_botstage_types_hash_and_serialise_alike_in_an_independent_implementation() -> None:
    """ros2_pyterfaces (pyzeros' types) computes RIHS01 and CDR itself: it must agree on botstage_msgs."""
    from ros2_pyterfaces.cyclone.geometry_msgs.msg import Point
    from ros2_pyterfaces.cyclone.std_msgs.msg import Header

    from tests.ros2_client.independent_types import AudioChunk, PeopleTracks, PersonTrack

    for independent in (PersonTrack, PeopleTracks, AudioChunk):
        assert independent.hash_rihs01() == types.type_hash(independent.get_type_name())
    tracks = PeopleTracks(
        header=Header(frame_id="kinect"),
        range_min=0.5,
        range_max=4.0,
        people=[PersonTrack(id=3, position=Point(x=1.0, y=-0.5, z=0.0))],
    )
    ours = types.deserialize(bytes(tracks.serialize()), "botstage_msgs/msg/PeopleTracks")
    assert [(p.id, p.position.x, p.position.y) for p in ours.people] == [(3, 1.0, -0.5)]
    assert types.serialize(ours) == bytes(tracks.serialize())
    audio = AudioChunk(header=Header(frame_id="mic"), sample_rate=16000, samples=[1, -2, 32767, -32768])
    back = types.deserialize(bytes(audio.serialize()), "botstage_msgs/msg/AudioChunk")
    assert back.samples.tolist() == [1, -2, 32767, -32768] and types.serialize(back) == bytes(audio.serialize())
