"""An independent ROS 2-over-Zenoh client (pyzeros, not botstage's code) for tests/test_ros2_interop.py.

Run in its own process: ``python pyzeros_probe.py ENDPOINT NODE_FQN``; ``--warmup`` instead
only builds pyzeros' compiled codecs (cydr compiles them with Cython on first use, into
``$CYDR_CACHE_DIR``), so the exchange itself does not wait for a compiler. It connects to ENDPOINT
(loopback, multicast scouting off), joins the graph as node ``/probe``, and reports on stdout, one
JSON object a line:

- ``graph``: the nodes and the topics (name, DDS type, hash, kind) of the live liveliness tokens,
  parsed here without botstage's code, once NODE_FQN appears with a topic (or the deadline passes);
- ``ready``: its publisher's liveliness token, once it subscribes to ``/cmd_vel`` (Twist) and
  publishes ``/scan`` (LaserScan);
- ``twist``: the first Twist received on ``/cmd_vel``.

It publishes a LaserScan on ``/scan`` every 50 ms until a line ``stop`` (or the end of input) on
stdin, or its own failsafe deadline, then leaves the graph and exits 0.
"""

from __future__ import annotations

import asyncio
import json
import sys
import threading
import time

import asyncio_for_robotics as afor
import pyzeros
import zenoh
from pyzeros.builtin_msgs import Attachment
from ros2_pyterfaces.cyclone.all_msgs import Header, LaserScan, Time, Twist

FAILSAFE_S = 90.0
PERIOD_S = 0.05


def emit(event: str, **fields: object) -> None:
    print(json.dumps({"event": event, **fields}), flush=True)


def open_session(endpoint: str) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"]))
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(config)


def read_graph(session: zenoh.Session) -> tuple[list[str], list[list[str]]]:
    """Nodes and topics of domain 0, from the tokens' chunks as rmw_zenoh's design.md lays them out."""
    nodes, topics = set(), set()
    for reply in session.liveliness().get("@ros2_lv/0/**", timeout=2.0):
        if reply.ok is None:
            continue
        chunks = str(reply.ok.key_expr).split("/")
        namespace, node = chunks[7].replace("%", "/"), chunks[8]
        nodes.add(("" if namespace == "/" else namespace) + "/" + node)
        if chunks[5] in ("MP", "MS") and len(chunks) >= 13:
            topics.add((chunks[9].replace("%", "/"), chunks[10], chunks[11], chunks[5]))
    return sorted(nodes), [list(t) for t in sorted(topics)]


def wait_for_node(session: zenoh.Session, node_fqn: str, deadline: float) -> None:
    """Wait until ``node_fqn`` shows with a topic (a liveliness subscriber wakes us), then list the graph."""
    seen: set[str] = set()
    appeared = threading.Event()

    def on_token(sample: zenoh.Sample) -> None:
        seen.add(str(sample.key_expr))
        chunks = str(sample.key_expr).split("/")
        if len(chunks) < 13:
            return
        namespace = "" if chunks[7] == "%" else chunks[7].replace("%", "/")
        if f"{namespace}/{chunks[8]}" == node_fqn:
            appeared.set()

    watcher = session.liveliness().declare_subscriber("@ros2_lv/0/**", on_token, history=True)
    appeared.wait(max(0.0, deadline - time.monotonic()))
    watcher.undeclare()
    nodes, topics = read_graph(session)
    emit(
        "graph",
        nodes=nodes,
        topics=topics,
        hashes={"twist": Twist.hash_rihs01(), "scan": LaserScan.hash_rihs01()},
    )


def watch_stdin(stop: threading.Event) -> None:
    for line in sys.stdin:
        if line.strip() == "stop":
            break
    stop.set()


def a_scan() -> LaserScan:
    return LaserScan(
        header=Header(stamp=Time(sec=7, nanosec=250), frame_id="laser"),
        angle_min=-1.0,
        angle_max=1.0,
        angle_increment=0.5,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=10.0,
        ranges=[1.5, 2.0, 2.5, 3.0, 3.5],
        intensities=[],
    )


@afor.scoped
async def exchange(stop: threading.Event, deadline: float) -> None:
    sub = pyzeros.Sub(Twist, "/cmd_vel")
    pub = pyzeros.Pub(LaserScan, "/scan")
    emit("ready", pub_token=pub.token_keyexpr)

    async def publish_scans() -> None:
        while not stop.is_set() and time.monotonic() < deadline:
            pub.publish(a_scan())
            await asyncio.sleep(PERIOD_S)

    publishing = asyncio.create_task(publish_scans())

    async def first_twist() -> Twist:
        async for twist in sub.listen_reliable():
            return twist
        raise RuntimeError("the subscription ended")

    try:
        twist = await asyncio.wait_for(first_twist(), timeout=max(0.0, deadline - time.monotonic()))
        emit("twist", linear=[twist.linear.x, twist.linear.y, twist.linear.z], angular=[twist.angular.z])
    except TimeoutError:
        emit("no_twist")
    await publishing


def warm_up() -> int:
    """Serialise what pyzeros serialises with cydr (the attachment), so its codec is built and cached."""
    attachment = Attachment()
    assert Attachment.deserialize(attachment.serialize()).gid_length == 16
    assert LaserScan.deserialize(a_scan().serialize()).header.frame_id == "laser"
    return 0


def main() -> int:
    if sys.argv[1:] == ["--warmup"]:
        return warm_up()
    endpoint, node_fqn = sys.argv[1], sys.argv[2]
    deadline = time.monotonic() + FAILSAFE_S
    stop = threading.Event()
    threading.Thread(target=watch_stdin, args=(stop,), daemon=True).start()
    session = open_session(endpoint)
    try:
        with pyzeros.auto_context(node="probe", zenoh_session=session):
            wait_for_node(session, node_fqn, deadline)
            asyncio.run(exchange(stop, deadline))
    finally:
        session.close()
    emit("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
