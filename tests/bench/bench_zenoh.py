"""Distribution benchmarks over Zenoh: botstage's ROS 2 layer against raw eclipse-zenoh, in the
same run, between two real processes on loopback. Run with `python -m tests.bench zenoh`.

The far process (this module run with ``far``; spawned with ``sys.executable``) connects to this
one's node and serves, on that one Zenoh session, both sides of every comparison:

- **skill_call**: a remote skill call round trip, from ``SkillExecution.start`` to the outcome,
  of the built-in ``wait`` with ``duration: 0`` (it ends in its first step), through
  ``remote_of`` and ``SkillTickLink`` to a ``SkillHost`` served by ``serve_skill_host`` (one
  ``SkillTick`` service call, simulated clock as in lockstep). Baseline: a raw ``get`` (same
  target and consolidation as the service client) with a request of the same byte size, to a
  raw queryable that answers at once with a reply of the SkillTick response's byte size; the
  first reply ends the wait. Warmed up first; timed in interleaved blocks. To show where the
  difference goes, the same request is also sent to a SkillTick service that answers at once
  (botstage's service layer alone), and the skill is run in this process (no network). The
  **floor** is the least any ROS 2-format call of these types can cost in Python: the same
  request as rosbags' CDR with rmw_zenoh's attachment, to a raw queryable that reads both and
  answers the SkillTick response's CDR with its attachment from Zenoh's callback, the reply read
  as the client reads it; no botstage service, proxy or host code on either side.
  Targets: p99 <= 5 ms, ratio of medians <= 1.5.
- **stream_scan**, **stream_image**: 181-beam ``sensor_msgs/LaserScan`` at 10 Hz and 640x480
  ``bgr8`` ``sensor_msgs/Image`` at 30 Hz, from a ``Ros2Node`` publisher here to a subscription
  there, with ROS's sensor-data QoS (best effort, depth 5) as a robot process publishes them.
  Latency is the receive time in the subscription's callback (the message decoded) minus the
  header stamp set just before ``publish`` (its CDR serialisation included); both processes read
  the same system clock. Baseline: a raw publisher (best effort, congestion control drop, as the
  botstage publisher) putting bytes of the same size at the same rate, its send time in the
  attachment, and a raw subscriber taking the payload's bytes. Throughput is what arrived over
  the sending window (messages/s, MB/s); target >= 0.8 of raw. **stream_image_flat_out** sends
  the images back to back instead (no target): the most each way carries.
- **entertainer**: ``botstage up missions/deployments/peoplebot_five_computers.yaml`` (five
  processes in lockstep) against ``botstage run missions/examples/peoplebot_entertainer.yaml`` with the
  same seed and ``--until``: each command's wall time, the mission loop's own (its summary's
  ``wall_time_s``), their ratios (target <= 2 for the commands) and whether the counters agree.

Each figure is printed as one JSON line when measured; a table of all of them closes the run.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import random
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from botstage.missions import DEFAULT_MISSION
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import LaserScan
from botstage.robots.ros2 import attachment as attachments
from botstage.robots.ros2 import readings, types
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.topics import SENSOR_DATA
from botstage.skills.base import SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.registry import Registry
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import Call, State, Step, TickReply, TickRequest, reply_fields, request_fields
from botstage.skills.remote.proxy import remote_of
from botstage.skills.remote.ros2_link import SERVICE_TYPE, SkillTickLink, serve_skill_host
from botstage.skills.testing import DictBoard

SOURCE = Path(__file__).resolve().parents[2]  # the checkout: the far side runs `tests.bench` from it
DEPLOYMENT = SOURCE / "missions" / "deployments" / "peoplebot_five_computers.yaml"
FAR = "bench_far"
SKILL, INPUTS = "wait", {"duration": 0.0}  # ends in its first step
RAW_CALL = "bench/raw/call"
FLOOR_CALL = "bench/floor/call"
REQUEST_TYPE, RESPONSE_TYPE = f"{SERVICE_TYPE}_Request", f"{SERVICE_TYPE}_Response"
ECHO = f"/{FAR}/echo"  # SkillTick answered at once, without a skill host
ENDED = TickReply(State.ENDED, "success")  # what the benched call answers
STREAMS: dict[str, tuple[str, str, float]] = {  # kind -> topic, type, rate (Hz)
    "scan": ("bench_scan", "sensor_msgs/msg/LaserScan", 10.0),
    "image": ("bench_image", "sensor_msgs/msg/Image", 30.0),
}
RAW_TOPICS = {"scan": "bench/raw/scan", "image": "bench/raw/image"}
TARGET_CALL_P99_MS = 5.0
TARGET_CALL_RATIO = 1.5  # botstage / raw, medians
TARGET_STREAM_RATIO = 0.8  # botstage / raw throughput
TARGET_DISTRIBUTED_RATIO = 2.0  # five processes / one, wall time
READY_S = 60.0
COLLECT_S = 3.0  # how long the far side waits for the last messages of a window


# -- messages ---------------------------------------------------------------------------------


def scan_template() -> Any:
    """A 181-beam scan (-90..90 degrees, one per degree), as a PeopleBot's SICK laser gives."""
    ranges = np.linspace(0.5, 8.0, 181)
    scan = LaserScan(0.0, -math.pi / 2, math.pi / 180, 0.02, 30.0, ranges)
    return readings.scan_message(scan)


def image_template() -> Any:
    frame = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    return readings.image_message(frame, 0.0)


def stamped(template: Any, ns: int) -> Any:
    """``template`` with its header stamped ``ns`` nanoseconds since the epoch."""
    time_type = types.message_class("builtin_interfaces/msg/Time")
    stamp = time_type(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    return dataclasses.replace(template, header=dataclasses.replace(template.header, stamp=stamp))


def stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def start_request() -> Any:
    """The SkillTick request that starts the benched call, as the proxy builds it."""
    call = Call(SKILL, "/bench", dict(INPUTS), {}, random.Random().getstate())  # a node's generator travels
    request = TickRequest(uuid.uuid4().hex, Step.START, 0.0, 0, 0.1, True, call)
    return types.message_class(f"{SERVICE_TYPE}_Request")(**request_fields(request))


def tick_sizes() -> tuple[int, int]:
    """The CDR bytes of the SkillTick request that starts the benched call, and of its response."""
    response = types.message_class(f"{SERVICE_TYPE}_Response")(**reply_fields(ENDED))
    return len(types.serialize(start_request())), len(types.serialize(response))


# -- the far process --------------------------------------------------------------------------


class Far:
    """The far side: a skill host, a raw queryable, and both kinds of subscriber for each stream."""

    def __init__(self, endpoint: str, reply_bytes: int) -> None:
        self.node = Ros2Node(FAR, connect=[endpoint])
        self.host = SkillHost(Registry.builtin(), {}, [SKILL])
        serve_skill_host(self.node, self.host)
        reply = bytes(reply_bytes)

        def answer(query: zenoh.Query) -> None:
            query.reply(RAW_CALL, reply)
            query.drop()

        response = types.message_class(f"{SERVICE_TYPE}_Response")(**reply_fields(ENDED))
        self.node.service(ECHO, SERVICE_TYPE, lambda _request: response)  # the service layer alone
        session = self.node.session
        self._raw: list[Any] = [
            session.declare_queryable(RAW_CALL, answer, complete=True),
            session.declare_queryable(FLOOR_CALL, floor_answer(response), complete=True),
        ]
        self.records: dict[str, list[tuple[int, int, int]]] = {}
        self._changed = threading.Condition()
        for kind, (topic, type_name, _) in STREAMS.items():
            self.node.subscription(topic, type_name, self._botstage_receiver(kind), SENSOR_DATA)
            self._raw.append(session.declare_subscriber(RAW_TOPICS[kind], self._raw_receiver(f"raw_{kind}")))

    def _record(self, kind: str, sent: int, received: int, serialised: int) -> None:
        with self._changed:
            self.records.setdefault(kind, []).append((sent, received, serialised))
            self._changed.notify_all()

    def _botstage_receiver(self, kind: str) -> Callable[[Any, Any], None]:
        def receive(message: Any, attachment: Any) -> None:
            received = time.time_ns()
            self._record(kind, stamp_ns(message.header.stamp), received, attachment.timestamp_ns)

        return receive

    def _raw_receiver(self, kind: str) -> Callable[[zenoh.Sample], None]:
        def receive(sample: zenoh.Sample) -> None:
            received = time.time_ns()
            sample.payload.to_bytes()  # what a consumer of the bytes does at least
            sent = int.from_bytes(sample.attachment.to_bytes(), "little") if sample.attachment else 0
            self._record(kind, sent, received, sent)

        return receive

    def collect(self, kind: str, count: int) -> list[tuple[int, int, int]]:
        """The records of ``kind`` once ``count`` have arrived (or COLLECT_S passed); cleared."""
        with self._changed:
            self._changed.wait_for(lambda: len(self.records.get(kind, ())) >= count, COLLECT_S)
            return self.records.pop(kind, [])

    def close(self) -> None:
        for declared in self._raw:
            declared.undeclare()
        self.node.close()
        self.host.close()


def floor_answer(response: Any) -> Callable[[zenoh.Query], None]:
    """The floor's server: read the request's attachment and CDR, reply ``response``'s CDR with an attachment."""
    store = types.type_store()

    def answer(query: zenoh.Query) -> None:
        sequence, _, gid = attachments.unpack(query.attachment.to_bytes())  # type: ignore[union-attr]
        store.deserialize_cdr(query.payload.to_bytes(), REQUEST_TYPE)  # type: ignore[union-attr]
        payload = bytes(store.serialize_cdr(response, RESPONSE_TYPE))
        query.reply(FLOOR_CALL, payload, attachment=attachments.pack(sequence, time.time_ns(), gid))
        query.drop()

    return answer


def far_main(endpoint: str, reply_bytes: int) -> None:
    """Serve until stdin closes; ``collect KIND COUNT`` prints that window's records as JSON."""
    far = Far(endpoint, reply_bytes)
    try:
        print("ready", flush=True)
        for line in sys.stdin:
            words = line.split()
            if words[:1] == ["collect"]:
                print(json.dumps(far.collect(words[1], int(words[2]))), flush=True)
            elif words[:1] == ["quit"]:
                break
    finally:
        far.close()


class FarProcess:
    """The far process, from this side: started, asked for records, stopped."""

    def __init__(self, endpoint: str, reply_bytes: int) -> None:
        env = {**os.environ, "PYTHONPATH": str(SOURCE)}
        command = [sys.executable, "-m", "tests.bench.bench_zenoh", "far", endpoint, str(reply_bytes)]
        self.process = subprocess.Popen(
            command, cwd=SOURCE, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        line = self._line()
        if line != "ready":
            self.stop()
            raise RuntimeError(f"the far process did not start: {line!r}")

    def _line(self) -> str:
        assert self.process.stdout is not None
        return self.process.stdout.readline().strip()

    def collect(self, kind: str, count: int) -> list[tuple[int, int, int]]:
        assert self.process.stdin is not None
        self.process.stdin.write(f"collect {kind} {count}\n")
        self.process.stdin.flush()
        return [tuple(r) for r in json.loads(self._line())]

    def stop(self) -> None:
        try:
            if self.process.stdin is not None and self.process.poll() is None:
                self.process.stdin.write("quit\n")
                self.process.stdin.close()
            self.process.wait(30)
        except (OSError, subprocess.TimeoutExpired):
            self.process.kill()
            self.process.wait(30)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def listening_node(name: str) -> tuple[Ros2Node, str]:
    """A node listening on a free loopback port, and that endpoint."""
    for _ in range(5):
        endpoint = f"tcp/127.0.0.1:{_free_port()}"
        try:
            return Ros2Node(name, listen=[endpoint]), endpoint
        except zenoh.ZError as error:  # taken between the probe and the bind
            if "in use" not in str(error):
                raise
    raise RuntimeError("no free loopback port after 5 tries")


# -- figures ----------------------------------------------------------------------------------


def _ms(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)) * 1e3, 3)


def _ratio(a: float, b: float) -> float | None:
    return round(a / b, 2) if b else None


# -- 1. a remote skill call -------------------------------------------------------------------


def _execution(skill: Any, clock: SimClock) -> SkillExecution:
    ctx = SkillContext(clock, skill.Params(), SkillLogger("/bench"), DictBoard(), None, node="/bench")  # type: ignore[arg-type]
    return SkillExecution(skill(), ctx)


def _start_seconds(skill: Any, clock: SimClock) -> float:
    """One call from start to outcome (the skill ends in its first step)."""
    execution = _execution(skill, clock)
    began = time.perf_counter()
    outcome = execution.start(INPUTS)
    took = time.perf_counter() - began
    if outcome is None or outcome.name != "success":
        raise RuntimeError(f"the benched call did not succeed at once: {outcome}")
    return took


def _raw_call_seconds(session: zenoh.Session, request: bytes) -> float:
    began = time.perf_counter()
    replies = session.get(
        RAW_CALL,
        payload=request,
        target=zenoh.QueryTarget.ALL_COMPLETE,
        consolidation=zenoh.ConsolidationMode.NONE,
    )
    reply = replies.recv()
    took = time.perf_counter() - began
    if reply.ok is None:
        raise RuntimeError("the raw queryable replied an error")
    reply.ok.payload.to_bytes()
    return took


def _floor_call_seconds(session: zenoh.Session, request: Any, gid: bytes, sequence: list[int]) -> float:
    """The floor: rosbags' CDR and rmw_zenoh's attachment both ways around a raw get."""
    store = types.type_store()
    began = time.perf_counter()
    sequence[0] += 1
    replies = session.get(
        FLOOR_CALL,
        payload=bytes(store.serialize_cdr(request, REQUEST_TYPE)),
        attachment=attachments.pack(sequence[0], time.time_ns(), gid),
        target=zenoh.QueryTarget.ALL_COMPLETE,
        consolidation=zenoh.ConsolidationMode.NONE,
    )
    sample = replies.recv().ok
    if sample is None or sample.attachment is None:
        raise RuntimeError("the floor's queryable replied an error")
    if attachments.unpack(sample.attachment.to_bytes())[0] != sequence[0]:
        raise RuntimeError("the floor's reply answers another call")
    store.deserialize_cdr(sample.payload.to_bytes(), RESPONSE_TYPE)
    return time.perf_counter() - began


def _service_call_seconds(client: Any, request: Any) -> float:
    began = time.perf_counter()
    client.call(request, READY_S)
    return time.perf_counter() - began


def bench_skill_call(node: Ros2Node, calls: int, request_bytes: int, response_bytes: int) -> dict[str, Any]:
    link = SkillTickLink(node, FAR)
    echo = node.client(ECHO, SERVICE_TYPE)
    try:
        if not (link.wait_for_remote(READY_S) and echo.wait_for_service(READY_S)):
            raise RuntimeError(f"the far process did not serve its skills within {READY_S:g} s")
        real = Registry.builtin().get(SKILL)
        remote = remote_of(real, link)
        clock = SimClock(10.0)
        raw_request, echo_request = bytes(request_bytes), start_request()
        gid, floor_sequence = os.urandom(attachments.GID_SIZE), [0]
        ways: dict[str, Callable[[], float]] = {
            "botstage": lambda: _start_seconds(remote, clock),
            "raw": lambda: _raw_call_seconds(node.session, raw_request),
            "floor": lambda: _floor_call_seconds(node.session, echo_request, gid, floor_sequence),
            "service": lambda: _service_call_seconds(echo, echo_request),
            "local": lambda: _start_seconds(real, clock),
        }
        samples: dict[str, list[float]] = {way: [] for way in ways}
        for measure in ways.values():  # warm up: connections, caches, the host's first call
            for _ in range(max(10, calls // 10)):
                measure()
        block = max(1, min(50, calls // 10))
        while len(samples["botstage"]) < calls:  # interleaved blocks: drift hits all alike
            for way, measure in ways.items():
                samples[way] += [measure() for _ in range(min(block, calls - len(samples[way])))]
    finally:
        echo.close()
        link.close()
    bot, raw = samples["botstage"], samples["raw"]
    p99 = _ms(bot, 99)
    ratio = _ratio(statistics.median(bot), statistics.median(raw))
    return {
        "bench": "skill_call",
        "skill": f"{SKILL} {json.dumps(INPUTS)}",
        "calls": calls,
        "request_bytes": request_bytes,
        "response_bytes": response_bytes,
        "botstage_p50_ms": _ms(bot, 50),
        "botstage_p99_ms": p99,
        "raw_p50_ms": _ms(raw, 50),
        "raw_p99_ms": _ms(raw, 99),
        "ratio_p50": ratio,
        # where the difference goes: the same bytes through a ROS 2 service answered at once
        # (the service layer alone), and the skill run in this process (no network); the floor
        # is rosbags' CDR and the attachment both ways around a raw get (no botstage code)
        "floor_p50_ms": _ms(samples["floor"], 50),
        "floor_p99_ms": _ms(samples["floor"], 99),
        "floor_ratio_p50": _ratio(statistics.median(samples["floor"]), statistics.median(raw)),
        "service_p50_ms": _ms(samples["service"], 50),
        "service_p99_ms": _ms(samples["service"], 99),
        "local_p50_ms": _ms(samples["local"], 50),
        "target_p99_ms": TARGET_CALL_P99_MS,
        "target_ratio": TARGET_CALL_RATIO,
        "meets_target": p99 <= TARGET_CALL_P99_MS and ratio <= TARGET_CALL_RATIO,
    }


# -- 2. streams -------------------------------------------------------------------------------


class Sender:
    """One stream's two senders: botstage's publisher and a raw one, the same bytes per message."""

    def __init__(self, node: Ros2Node, kind: str) -> None:
        topic, type_name, self.rate = STREAMS[kind]
        self.kind = kind
        self.template = scan_template() if kind == "scan" else image_template()
        self.bytes = len(types.serialize(self.template))
        self.publisher = node.publisher(topic, type_name, SENSOR_DATA)
        self.raw = node.session.declare_publisher(
            RAW_TOPICS[kind],
            reliability=zenoh.Reliability.BEST_EFFORT,
            congestion_control=zenoh.CongestionControl.DROP,
        )
        self.payload = bytes(self.bytes)

    def send(self, way: str) -> int:
        """One message; the time it was sent (ns since the epoch)."""
        now = time.time_ns()
        if way == "botstage":
            self.publisher.publish(stamped(self.template, now))
        else:
            self.raw.put(self.payload, attachment=now.to_bytes(8, "little"))
        return now

    def close(self) -> None:
        self.raw.undeclare()
        self.publisher.close()


def _paced(send: Callable[[], int], count: int, rate: float | None) -> list[int]:
    """Send ``count`` messages at ``rate`` Hz (None: back to back); their send times."""
    period = 1.0 / rate if rate else 0.0
    began = time.perf_counter()
    sent = []
    for i in range(count):
        wait = began + i * period - time.perf_counter()
        if wait > 0:
            time.sleep(wait)  # a bench pacing its sender, not a test waiting for something
        sent.append(send())
    return sent


@dataclasses.dataclass
class Window:
    """What one way delivered in one window: (sent, received, sent after serialising) ns per message."""

    sent: int
    records: list[tuple[int, int, int]]
    seconds: float


def _window(sender: Sender, far: FarProcess, way: str, count: int, rate: float | None) -> Window:
    kind = sender.kind if way == "botstage" else f"raw_{sender.kind}"
    warm = max(3, count // 10)
    _paced(lambda: sender.send(way), warm, rate)
    far.collect(kind, warm)  # the warm-up's, dropped
    sent = _paced(lambda: sender.send(way), count, rate)
    records = [r for r in far.collect(kind, count) if r[0] >= sent[0]]
    last = max((r[1] for r in records), default=sent[-1])
    # paced: the sending window (count periods); flat out: first send to last receipt
    return Window(count, records, count / rate if rate else (last - sent[0]) / 1e9)


def _delivered(windows: list[Window], size: int) -> dict[str, Any]:
    """Latency percentiles over every message of the windows, and what arrived per second."""
    records = [r for w in windows for r in w.records]
    seconds = sum(w.seconds for w in windows)
    latencies = [(r[1] - r[0]) / 1e9 for r in records]
    after_serialise = [(r[1] - r[2]) / 1e9 for r in records]
    return {
        "sent": sum(w.sent for w in windows),
        "received": len(records),
        "latency_p50_ms": _ms(latencies, 50) if records else None,
        "latency_p99_ms": _ms(latencies, 99) if records else None,
        "after_serialise_p50_ms": _ms(after_serialise, 50) if records else None,
        "msgs_per_s": round(len(records) / seconds, 1) if seconds > 0 else 0.0,
        "mb_per_s": round(len(records) * size / seconds / 1e6, 2) if seconds > 0 else 0.0,
    }


def bench_stream(
    node: Ros2Node, far: FarProcess, kind: str, count: int, rounds: int, flat_out: bool = False
) -> dict[str, Any]:
    """``count`` messages per window each way, ``rounds`` windows each (ABBA order)."""
    sender = Sender(node, kind)
    rate = None if flat_out else sender.rate
    windows: dict[str, list[Window]] = {"botstage": [], "raw": []}
    try:
        for r in range(rounds):
            for way in ("botstage", "raw") if r % 2 == 0 else ("raw", "botstage"):
                windows[way].append(_window(sender, far, way, count, rate))
    finally:
        sender.close()
    bot, raw = (_delivered(windows[way], sender.bytes) for way in ("botstage", "raw"))
    ratio = _ratio(bot["msgs_per_s"], raw["msgs_per_s"])
    result = {
        "bench": f"stream_{kind}" + ("_flat_out" if flat_out else ""),
        "type": STREAMS[kind][1],
        "bytes": sender.bytes,
        "rate_hz": "flat out" if flat_out else sender.rate,
        "messages": count,
        "rounds": rounds,
        "botstage": bot,
        "raw": raw,
        "throughput_ratio": ratio,
        "latency_p50_ratio": _ratio(bot["latency_p50_ms"] or 0.0, raw["latency_p50_ms"] or 0.0),
    }
    if not flat_out:
        result["target_ratio"] = TARGET_STREAM_RATIO
        result["meets_target"] = ratio >= TARGET_STREAM_RATIO
    return result


# -- 3. the entertainer, five processes against one -------------------------------------------


def _timed_command(arguments: list[str], folder: Path) -> tuple[float, dict[str, Any]]:
    """Run ``botstage ARGUMENTS --out FOLDER``; its wall time and the run's summary."""
    env = {**os.environ, "PYTHONPATH": str(SOURCE)}
    command = [sys.executable, "-m", "botstage.missions.cli", *arguments, "--out", str(folder)]
    log = folder.with_suffix(".log")
    with log.open("wb") as output:
        began = time.perf_counter()
        done = subprocess.run(command, cwd=SOURCE, env=env, stdout=output, stderr=subprocess.STDOUT, check=False)
        took = time.perf_counter() - began
    if done.returncode != 0:
        tail = log.read_text(errors="replace")[-2000:]
        raise RuntimeError(f"`botstage {' '.join(arguments)}` exited {done.returncode}:\n{tail}")
    return took, json.loads((folder / "summary.json").read_text(encoding="utf-8"))


def bench_entertainer(seed: int, until: float | None) -> dict[str, Any]:
    common = ["--seed", str(seed), *(["--until", f"{until:g}"] if until is not None else [])]
    with tempfile.TemporaryDirectory(prefix="botstage-bench-zenoh-") as tmp:
        one_s, one = _timed_command(["run", str(DEFAULT_MISSION), *common, "--quiet"], Path(tmp) / "one")
        five_s, five = _timed_command(["up", str(DEPLOYMENT), *common], Path(tmp) / "five")
    ratio = _ratio(five_s, one_s)
    return {
        "bench": "entertainer",
        "seed": seed,
        "mission_s": one["sim_time_s"],
        "one_process_s": round(one_s, 2),
        "five_processes_s": round(five_s, 2),
        "ratio": ratio,
        "mission_loop_one_s": one["wall_time_s"],
        "mission_loop_five_s": five["wall_time_s"],
        "mission_loop_ratio": _ratio(five["wall_time_s"], one["wall_time_s"]),
        "counters_identical": five["counters"] == one["counters"],
        "target_ratio": TARGET_DISTRIBUTED_RATIO,
        "meets_target": ratio <= TARGET_DISTRIBUTED_RATIO,
    }


# -- the run ----------------------------------------------------------------------------------


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches that missed their target."""
    return [r["bench"] for r in results if not r.get("meets_target", True)]


def _mark(result: dict[str, Any]) -> str:
    return "" if result.get("meets_target", True) else "  MISSED"


def table(results: list[dict[str, Any]]) -> str:
    """The figures side by side, one line per comparison; MISSED where a target is."""
    lines = [f"{'bench':<24} {'botstage':>34} {'raw zenoh':>34} {'ratio':>7}  target"]
    for r in results:
        name = r["bench"]
        if name == "skill_call":
            bot = f"p50 {r['botstage_p50_ms']:.3f} / p99 {r['botstage_p99_ms']:.3f} ms"
            raw = f"p50 {r['raw_p50_ms']:.3f} / p99 {r['raw_p99_ms']:.3f} ms"
            target = f"ratio <= {TARGET_CALL_RATIO:g}, p99 <= {TARGET_CALL_P99_MS:g} ms"
            lines.append(f"{name:<24} {bot:>34} {raw:>34} {r['ratio_p50']:>6.2f}x  {target}{_mark(r)}")
            floor = f"p50 {r['floor_p50_ms']:.3f} / p99 {r['floor_p99_ms']:.3f} ms"
            lines.append(f"{'  floor: CDR + attachment':<24} {floor:>34} {'':>34} {r['floor_ratio_p50']:>6.2f}x")
            service = f"p50 {r['service_p50_ms']:.3f} / p99 {r['service_p99_ms']:.3f} ms"
            lines.append(f"{'  of which service call':<24} {service:>34}")
            lines.append(f"{'  skill in-process':<24} {'p50 ' + format(r['local_p50_ms'], '.3f') + ' ms':>34}")
        elif name.startswith("stream_"):
            for what, key, unit in (("latency p50/p99", "latency", "ms"), ("throughput", "msgs_per_s", "")):
                cells = []
                for side in (r["botstage"], r["raw"]):
                    if key == "latency":
                        cells.append(f"{side['latency_p50_ms']:.2f} / {side['latency_p99_ms']:.2f} {unit}")
                    else:
                        cells.append(f"{side['msgs_per_s']:g} msg/s, {side['mb_per_s']:g} MB/s")
                label = f"{name} {what}" if what == "throughput" else f"{name}"
                if key == "latency":
                    ratio, target = f"{r['latency_p50_ratio']:>6.2f}x", "(p50)"
                else:
                    ratio = f"{r['throughput_ratio']:>6.2f}x"
                    target = f">= {TARGET_STREAM_RATIO:g}{_mark(r)}" if "target_ratio" in r else "(none)"
                lines.append(f"{label:<24} {cells[0]:>34} {cells[1]:>34} {ratio}  {target}")
        elif name == "entertainer":
            five = f"five processes {r['five_processes_s']:.1f} s (loop {r['mission_loop_five_s']:.1f})"
            one = f"one process {r['one_process_s']:.1f} s (loop {r['mission_loop_one_s']:.1f})"
            target = f"<= {TARGET_DISTRIBUTED_RATIO:g}{_mark(r)}"
            lines.append(f"{name:<24} {five:>34} {one:>34} {r['ratio']:>6.2f}x  {target}")
            same = "identical" if r["counters_identical"] else "DIFFERENT"
            lines.append(f"{'':<24} seed {r['seed']}, {r['mission_s']:g} s of mission time; counters {same}")
    return "\n".join(lines)


BENCH_NAMES = ("skill_call", "stream_scan", "stream_image", "entertainer")  # what ``--only`` picks


def selected(only: list[str] | None) -> list[str]:
    """The benches ``only`` names (each item one name or a comma list), all when none; ValueError for an unknown one."""
    if not only:
        return list(BENCH_NAMES)
    names = {name.strip() for item in only for name in item.split(",") if name.strip()}
    unknown = sorted(names - set(BENCH_NAMES))
    if unknown:
        raise ValueError(f"unknown bench {', '.join(unknown)}: choose from {', '.join(BENCH_NAMES)}")
    return [name for name in BENCH_NAMES if name in names]


def main(
    quick: bool = False,
    calls: int | None = None,
    seconds: float | None = None,
    seed: int = 1,
    until: float | None = None,
    only: list[str] | None = None,
) -> list[dict[str, Any]]:
    """Run the benches ``only`` names (all by default; stream_image includes its flat-out run)."""
    chosen = selected(only)
    calls = calls or (200 if quick else 2000)
    seconds = seconds or (2.0 if quick else 10.0)
    rounds = 1 if quick else 2
    if quick and until is None:
        until = 30.0
    request_bytes, response_bytes = tick_sizes()
    results: list[dict[str, Any]] = []

    def report(result: dict[str, Any]) -> None:
        results.append(result)
        print(json.dumps(result), flush=True)

    if set(chosen) & {"skill_call", "stream_scan", "stream_image"}:
        node, endpoint = listening_node("bench_near")
        with node:
            far = FarProcess(endpoint, response_bytes)
            try:
                if "skill_call" in chosen:
                    report(bench_skill_call(node, calls, request_bytes, response_bytes))
                for kind, (_, _, rate) in STREAMS.items():
                    if f"stream_{kind}" in chosen:
                        report(bench_stream(node, far, kind, max(3, round(seconds * rate)), rounds))
                if "stream_image" in chosen:
                    report(bench_stream(node, far, "image", max(3, round(seconds * 30)), rounds, flat_out=True))
            finally:
                far.stop()
    if "entertainer" in chosen:
        report(bench_entertainer(seed, until))
    print(table(results), flush=True)
    return results


if __name__ == "__main__":
    if sys.argv[1:2] == ["far"]:
        far_main(sys.argv[2], int(sys.argv[3]))
    else:
        main(quick="--quick" in sys.argv)
