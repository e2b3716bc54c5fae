"""Groot2's protocol against real runs, over real ZMQ sockets on 127.0.0.1.

The client here is written from BehaviorTree.CPP's ``groot2_protocol.h`` and
``groot2_publisher.cpp`` (headers, status buffer, hooks, transitions) and the MessagePack spec; it
shares no code with ``missions/groot2``. A run is held before its first tick by a gate observer
until the client is set up, so nothing depends on timing.
"""

from __future__ import annotations

import json
import os
import random
import struct
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import zmq

from botstage.behaviors.engine import Engine
from botstage.behaviors.trace import read_jsonl
from botstage.missions.check import build_root, check, root_spec_path
from botstage.missions.groot2.btlog import BtlogError, read_btlog, write_btlog
from botstage.missions.groot2.publisher import Groot2Publisher
from botstage.missions.groot2.tree import GrootTree
from botstage.missions.runner import run
from botstage.robots.clock import SimClock

WAIT_MS = 15_000
MISSION = """\
name: g2demo
seed: 3
rate_hz: 10
until: 30
blackboard:
  greeted: false
  visitors: 2
trees:
  greet:
    sequence:
      - log: {message: "hi"}
      - wait: {duration: 1}
      - set: {key: greeted, value: true}
machine:
  initial: greeting
  outcomes: [done, failed]
  states:
    greeting:
      tree: greet
      transitions: {success: resting, failure: failed}
    resting:
      skill: wait
      inputs: {duration: 2}
      transitions: {success: done, failure: failed}
"""
# (tag, name) in depth-first order: uids 1..8 as BT.CPP numbers them
EXPECTED = [
    ("StateMachine", "g2demo"),
    ("State", "greeting"),
    ("Sequence", "greet"),
    ("log", "log"),
    ("wait", "wait"),
    ("set", "set"),
    ("State", "resting"),
    ("wait", "resting"),
]
IDLE, RUNNING, SUCCESS, FAILURE = 0, 1, 2, 3


# -- a Groot2 client, from the protocol header ---------------------------------------------------


class Client:
    def __init__(self, port: int) -> None:
        self.context = zmq.Context()
        self.req = self.context.socket(zmq.REQ)
        self.req.setsockopt(zmq.LINGER, 0)
        self.req.connect(f"tcp://127.0.0.1:{port}")
        self.sub = self.context.socket(zmq.SUB)
        self.sub.setsockopt(zmq.LINGER, 0)
        self.sub.setsockopt(zmq.SUBSCRIBE, b"")
        self.sub.connect(f"tcp://127.0.0.1:{port + 1}")
        self.tree_id: bytes | None = None

    def ask(self, kind: str, *body: bytes) -> list[bytes]:
        """One request; the reply's parts after its header (or ``[b"error", why]``)."""
        unique = random.getrandbits(32)
        self.req.send_multipart([struct.pack("<BBI", 2, ord(kind), unique), *body])
        assert self.req.poll(WAIT_MS), f"no reply to {kind!r}"
        reply = self.req.recv_multipart()
        if reply[0] == b"error":
            return reply
        assert len(reply[0]) == 22
        protocol, answered, same = struct.unpack("<BBI", reply[0][:6])
        assert (protocol, answered, same) == (2, ord(kind), unique)
        if self.tree_id is None:
            self.tree_id = reply[0][6:]
        assert reply[0][6:] == self.tree_id  # one tree for the publisher's life
        return reply[1:]

    def statuses(self) -> dict[int, int]:
        (buffer,) = self.ask("S")
        assert len(buffer) % 3 == 0
        return {struct.unpack_from("<H", buffer, i)[0]: buffer[i + 2] for i in range(0, len(buffer), 3)}

    def close(self) -> None:
        self.context.destroy(linger=0)


def unpack_msgpack(data: bytes) -> Any:
    value, end = _unpack(data, 0)
    assert end == len(data)
    return value


def _unpack(data: bytes, at: int) -> tuple[Any, int]:
    b = data[at]
    at += 1
    if b <= 0x7F:
        return b, at
    if b >= 0xE0:
        return b - 0x100, at
    if 0xA0 <= b <= 0xBF or b in (0xD9, 0xDA, 0xDB):
        n, at = (b & 0x1F, at) if b <= 0xBF else _length(data, at, {0xD9: 1, 0xDA: 2, 0xDB: 4}[b])
        return data[at : at + n].decode(), at + n
    if 0x90 <= b <= 0x9F or b in (0xDC, 0xDD):
        n, at = (b & 0x0F, at) if b <= 0x9F else _length(data, at, {0xDC: 2, 0xDD: 4}[b])
        items = []
        for _ in range(n):
            item, at = _unpack(data, at)
            items.append(item)
        return items, at
    if 0x80 <= b <= 0x8F or b in (0xDE, 0xDF):
        n, at = (b & 0x0F, at) if b <= 0x8F else _length(data, at, {0xDE: 2, 0xDF: 4}[b])
        found = {}
        for _ in range(n):
            key, at = _unpack(data, at)
            found[key], at = _unpack(data, at)
        return found, at
    fixed = {0xC0: None, 0xC2: False, 0xC3: True}
    if b in fixed:
        return fixed[b], at
    formats = {0xCA: ">f", 0xCB: ">d", 0xCC: ">B", 0xCD: ">H", 0xCE: ">I", 0xCF: ">Q"}
    formats |= {0xD0: ">b", 0xD1: ">h", 0xD2: ">i", 0xD3: ">q"}
    (value,) = struct.unpack_from(formats[b], data, at)
    return value, at + struct.calcsize(formats[b])


def _length(data: bytes, at: int, size: int) -> tuple[int, int]:
    return int.from_bytes(data[at : at + size], "big"), at + size


def hook(uid: int, mode: int = 0, once: bool = False, status: str = "SKIPPED") -> bytes:
    js = {"enabled": True, "uid": uid, "mode": mode, "once": once, "desired_status": status, "position": 0}
    return json.dumps(js).encode()


def tree_of(xml: str) -> list[tuple[int, str, str, str]]:
    """(uid, tag, name, path) of every node, in document order; a node's path is its ancestors'
    names and its own joined by '/', as botstage's trace names nodes (a skill that is a state's
    whole content is named after the state and has the state's path)."""
    root = ET.fromstring(xml)
    assert root.tag == "root" and root.get("BTCPP_format") == "4"
    (tree,) = root.findall("BehaviorTree")
    found: list[tuple[int, str, str, str]] = []

    def walk(element: ET.Element, prefix: str, parent: ET.Element | None) -> None:
        name = str(element.get("name"))
        skill_state = parent is not None and parent.tag == "State" and not len(element) and parent.get("name") == name
        path = prefix if skill_state else f"{prefix}/{name}" if prefix else name
        found.append((int(element.get("_uid", "-1")), element.tag, name, path))
        for child in element:
            walk(child, path, element)

    for top in tree:
        walk(top, "", None)
    return found


# -- a run, held before its first tick until the test lets it go --------------------------------


class Gate:
    """Holds the run before its first tick until ``go``; counts the ticks done."""

    def __init__(self) -> None:
        self.go = threading.Event()
        self.ticks = 0

    def before_tick(self, session: Any) -> None:
        if self.ticks == 0:
            assert self.go.wait(WAIT_MS / 1000), "the test never let the run go"

    def after_tick(self, session: Any) -> None:
        self.ticks += 1


class Run:
    def __init__(self, tmp_path: Path, heartbeat_s: float = 60.0) -> None:
        self.mission = tmp_path / "g2demo.yaml"
        self.mission.write_text(MISSION, encoding="utf-8")
        self.folder = tmp_path / "run"
        self.gate = Gate()
        self.publisher = Groot2Publisher(port=0, heartbeat_s=heartbeat_s)
        self.client = Client(self.publisher.port)
        self.result: Any = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        self.result = run(self.mission, out=self.folder, observers=[self.gate, self.publisher])

    def finish(self) -> Any:
        self.gate.go.set()
        self.thread.join(WAIT_MS / 1000)
        assert not self.thread.is_alive(), "the run did not end"
        self.client.close()
        return self.result


@pytest.fixture
def live(tmp_path: Path):
    started = Run(tmp_path)
    yield started
    started.publisher.close()  # lets a held run go
    started.finish()


def wait_breakpoint(client: Client) -> int:
    assert client.sub.poll(WAIT_MS), "no breakpoint notification"
    header, uid = client.sub.recv_multipart()
    protocol, kind, _ = struct.unpack("<BBI", header)
    assert (protocol, chr(kind)) == (2, "N")
    return int(uid)


# -- tests ------------------------------------------------------------------------------------------


def test_groot2_watches_holds_and_steers_a_running_mission(live: Run) -> None:
    client = live.client
    (xml,) = client.ask("T")
    nodes = tree_of(xml.decode())
    assert [(tag, name) for _, tag, name, _ in nodes] == EXPECTED
    assert [uid for uid, *_ in nodes] == list(range(1, len(EXPECTED) + 1))
    assert ET.fromstring(xml).find("BehaviorTree").get("ID") == "g2demo"
    assert client.statuses() == {uid: IDLE for uid in range(1, 9)}  # nothing ticked yet

    (packed,) = client.ask("B", b"g2demo;nosuchtree")
    board = unpack_msgpack(packed)
    assert list(board) == ["g2demo"] and board["g2demo"]["greeted"] is False and board["g2demo"]["visitors"] == 2

    (started,) = client.ask("r", b"start")
    assert int(started) > 1_600_000_000_000_000  # microseconds since the epoch
    assert client.ask("I", hook(8)) == []  # a breakpoint on the resting state's wait
    assert json.loads(client.ask("D")[0]) == [
        {"enabled": True, "uid": 8, "mode": 0, "once": False, "desired_status": "SKIPPED", "position": 0}
    ]

    live.gate.go.set()
    assert wait_breakpoint(client) == 8
    held_at = live.gate.ticks
    statuses = client.statuses()
    # held inside the tick where state `resting` was entered, before its wait ticked
    assert statuses[1] == RUNNING and statuses[7] == RUNNING and statuses[8] == IDLE
    assert statuses[3] == SUCCESS and statuses[5] == SUCCESS and statuses[2] == SUCCESS  # the run went on to here
    (packed,) = client.ask("B", b"g2demo")
    assert unpack_msgpack(packed)["g2demo"]["greeted"] is True
    (recorded,) = client.ask("t")
    transitions = [
        (int.from_bytes(recorded[i : i + 6], "little"), *struct.unpack_from("<HB", recorded, i + 6))
        for i in range(0, len(recorded), 9)
    ]
    assert [(t, s) for t, uid, s in transitions if uid == 5] == [(0, RUNNING), (1_000_000, SUCCESS)]  # wait 1 s
    assert (1_000_000, 7, RUNNING) in transitions
    assert client.sub.poll(200) == 0 and live.gate.ticks == held_at  # the run holds

    unlock = {"uid": 8, "desired_status": "SUCCESS", "position": 0, "remove_when_done": True}
    assert client.ask("U", json.dumps(unlock).encode()) == []
    result = live.finish()
    assert result.outcome == "done"
    events = read_jsonl(live.folder / "trace.jsonl")
    # replaced: the resting state's wait never ran, so the mission ended 2 s early
    assert not [e for e in events if e["ev"] == "skill_start" and e["node"] == "g2demo/resting"]
    assert result.summary["sim_time_s"] < 2
    notes = [e["message"] for e in events if e["ev"] == "log" and e["node"] == "groot2"]
    assert notes[0] == "breakpoint at g2demo/resting (Groot2 uid 8)"
    assert "ends with SUCCESS without running" in notes[1]


def test_refusals_are_said(live: Run) -> None:
    client = live.client
    live.client.req.send_multipart([b"\x02T"])  # a header of 2 bytes, not 6
    assert client.req.poll(WAIT_MS)
    assert client.req.recv_multipart() == [b"error", b"wrong request header"]
    assert client.ask("B") == [b"error", b"must be 2 parts message"]
    assert client.ask("Z") == [b"error", b"Request not recognized"]
    assert client.ask("I", hook(99)) == [b"error", b"no node with uid 99 (uids are 1 to 8)"]
    assert client.ask("I", b"{nope")[0] == b"error"
    missing = client.ask("I", json.dumps({"uid": 3}).encode())
    assert missing == [b"error", b"hook: missing field 'desired_status'"]
    assert client.ask(
        "U", json.dumps({"uid": 3, "desired_status": "SUCCESS", "position": 0, "remove_when_done": False}).encode()
    ) == [b"error", b"Node ID not found"]
    assert client.ask("r", b"pause")[0] == b"error"
    assert live.finish().outcome == "done"  # a refused request changes nothing


def test_a_lost_groot2_lets_a_held_run_go(tmp_path: Path) -> None:
    """As BT.CPP does: no request for heartbeat_s and every hook is disabled, so the run goes on."""
    held = Run(tmp_path, heartbeat_s=0.5)
    try:
        assert held.client.ask("I", hook(5)) == []
        held.gate.go.set()
        assert wait_breakpoint(held.client) == 5
        held.thread.join(WAIT_MS / 1000)  # Groot2 says nothing more
        assert held.result is not None and held.result.outcome == "done"
        assert held.result.summary["sim_time_s"] > 2.5  # this time every wait ran
    finally:
        held.publisher.close()
        held.finish()


def test_btlog_of_a_run_matches_its_trace(live: Run, tmp_path: Path) -> None:
    (live_xml,) = live.client.ask("T")
    result = live.finish()
    out = write_btlog(result.folder, tmp_path / "g2demo.btlog")
    raw = out.read_bytes()
    assert raw[:19] == b"BTCPP4-FileLogger2\x01"
    size = struct.unpack_from("<i", raw, 19)[0]
    assert raw[23 : 23 + size] == live_xml  # the same tree and uids as the live publisher's
    log = read_btlog(out)
    assert log.xml == live_xml.decode()
    uid_of = {path: uid for uid, tag, _, path in tree_of(log.xml) if tag not in ("State",)}
    state_uid = {path: uid for uid, tag, _, path in tree_of(log.xml) if tag == "State"}
    events = read_jsonl(result.folder / "trace.jsonl")
    codes = {"INVALID": IDLE, "RUNNING": RUNNING, "SUCCESS": SUCCESS, "FAILURE": FAILURE}
    expected = [
        (round(e["t"] * 1e6), uid_of[e["node"]], codes[e["new"]])
        for e in events
        if e["ev"] == "status" and e["node"] in uid_of
    ]
    trees = set(uid_of.values())
    assert [(t.timestamp_us, t.uid, t.status) for t in log.transitions if t.uid in trees] == expected
    assert {uid for _, uid, _ in expected} == trees  # every tree node ran (the last wait, once Groot2 let it)
    entered = [
        (round(e["t"] * 1e6), state_uid[f"g2demo/{e['dest']}"])
        for e in events
        if e["ev"] == "transition" and e["dest"] in ("greeting", "resting")
    ]
    running = [(t.timestamp_us, t.uid) for t in log.transitions if t.uid in state_uid.values() and t.status == RUNNING]
    assert running == entered == [(0, 2), (1_000_000, 7)]
    out.write_bytes(raw[:-4])
    with pytest.raises(BtlogError, match=r"a transition cut short \(5 of 9 bytes\)"):
        read_btlog(out)
    with pytest.raises(BtlogError, match=r"must end in \.btlog"):
        write_btlog(result.folder, tmp_path / "g2demo.log")
    renamed = MISSION.replace(
        "- set: {key: greeted, value: true}", "- set: {key: greeted, value: true}\n        name: mark"
    )
    live.mission.write_text(renamed, encoding="utf-8")
    with pytest.raises(BtlogError, match=r"names node 'g2demo/greeting/greet/set' .* it changed since the run"):
        write_btlog(result.folder, tmp_path)


def test_run_groot2_from_the_command_line(tmp_path: Path) -> None:
    mission = tmp_path / "g2demo.yaml"
    mission.write_text(MISSION.replace("until: 30", "until: 1.5"), encoding="utf-8")
    probe = Groot2Publisher(port=0)  # a free pair of ports, given back
    port = probe.port
    probe.close()
    env = {**os.environ, "COLUMNS": "200"}
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "run",
        str(mission),
        "--groot2",
        "--groot2-port",
        str(port),
    ]
    command += ["--realtime", "--quiet", "--out", str(tmp_path / "run")]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    client = Client(port)
    try:
        (xml,) = client.ask("T")
        assert [(tag, name) for _, tag, name, _ in tree_of(xml.decode())] == EXPECTED
        out, err = process.communicate(timeout=60)
    finally:
        client.close()
        process.kill()
    assert process.returncode == 0, err
    assert f"groot2: 127.0.0.1:{port} (notifications on {port + 1})" in out


def test_a_replace_hook_on_a_state_ends_it_without_running(live: Run) -> None:
    """A hook in "replace" mode (1) holds nothing: the state's tree ends FAILURE at once, so the
    machine takes its failure transition; Groot2 is still told."""
    client = live.client
    post = json.loads(hook(2))
    post["position"] = 1
    assert client.ask("I", json.dumps(post).encode()) == [b"error", b"only PRE hooks (position 0) are supported"]
    assert client.ask("I", hook(2, mode=1, status="FAILURE")) == []
    live.gate.go.set()
    assert wait_breakpoint(client) == 2
    result = live.finish()
    assert result.outcome == "failed"
    events = read_jsonl(live.folder / "trace.jsonl")
    assert not [e for e in events if e["ev"] == "skill_start"]
    (transition,) = [e for e in events if e["ev"] == "transition" and e["source"] == "greeting"]
    assert (transition["dest"], transition["trigger"]) == ("failed", "greeting:failure")


def test_a_nested_machine_is_a_node_of_its_own(tmp_path: Path) -> None:
    """The XML and uids of a machine nested in a state, as ``behaviors/btcpp/export.py`` shapes it."""
    mission = tmp_path / "nested.yaml"
    mission.write_text(
        MISSION.replace(
            "    resting:\n      skill: wait\n      inputs: {duration: 2}\n",
            "    resting:\n      machine:\n        initial: nap\n        outcomes: [rested]\n        states:\n"
            "          nap: {skill: wait, inputs: {duration: 2}, transitions: {success: rested, failure: rested}}\n"
            "      transitions: {rested: done}\n",
        ).replace("      transitions: {success: done, failure: failed}\n", ""),
        encoding="utf-8",
    )
    checked = check(mission)
    assert checked.ok, checked.problems
    spec = checked.mission
    engine = Engine(clock=SimClock(spec.rate_hz), registry=checked.registry, kinds=checked.kinds)
    root = build_root(engine.builder(spec.trees, spec.machines, spec.skill_params), spec, root_spec_path(spec))
    tree = GrootTree(root, spec.name)
    engine.close()
    nodes = tree_of(tree.xml())
    assert [(uid, tag, name) for uid, tag, name, _ in nodes[6:]] == [
        (7, "State", "resting"),
        (8, "StateMachine", "resting"),
        (9, "State", "nap"),
        (10, "wait", "nap"),
    ]
    entered = {"ev": "transition", "machine": "g2demo", "source": "greeting", "dest": "resting/nap"}
    assert list(tree.changes({**entered, "trigger": "greeting:success"})) == [
        (2, SUCCESS),
        (7, RUNNING),
        (8, RUNNING),
        (9, RUNNING),
    ]
    left = {"ev": "transition", "machine": "g2demo", "source": "resting/nap", "dest": "done"}
    assert list(tree.changes({**left, "trigger": "resting/nap:success > resting:rested"})) == [
        (9, SUCCESS),
        (7, IDLE),
        (8, IDLE),
    ]
