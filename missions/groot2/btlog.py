"""A finished run as a Groot2 .btlog file, in BT.CPP's ``FileLogger2`` format
(``loggers/bt_file_logger_v2.cpp``), so Groot2 replays it; and a reader of that format.

The format, little-endian throughout::

    "BTCPP4-FileLogger2"   18 bytes
    protocol               uint8, 1
    N                      int32: the length of the XML
    XML                    N bytes: the tree with _uid attributes (WriteTreeToXML with metadata)
    first timestamp        int64: microseconds since the epoch
    transitions            9 bytes each: timestamp (the low 6 bytes of a uint64, microseconds
                           since the first timestamp), node uid (uint16), new status (uint8:
                           0 IDLE, 1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED)

The tree is rebuilt from the mission the run's summary.json names, so its uids are those the
live publisher gave (``missions/groot2/tree.py``); transitions are the trace's status changes and
the machines' state changes, stamped with mission time. The first timestamp is the run's start,
read from its folder's name (``runs/<mission>-YYYYmmdd-HHMMSS``, local time), else 0.
"""

from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from botstage.behaviors.engine import Engine
from botstage.behaviors.trace import read_jsonl
from botstage.missions.check import build_root, check, root_spec_path
from botstage.missions.groot2.protocol import pack_transition
from botstage.missions.groot2.tree import GrootTree
from botstage.robots.clock import SimClock

MAGIC = b"BTCPP4-FileLogger2"
PROTOCOL = 1
TRANSITION_SIZE = 9
_STARTED = re.compile(r"-(\d{8}-\d{6})(?:-\d+)?$")


class BtlogError(Exception):
    """A run folder that cannot become a .btlog, or a file that is not one; the text says where."""


@dataclass(frozen=True)
class Transition:
    timestamp_us: int  # since the file's first timestamp
    uid: int
    status: int


@dataclass(frozen=True)
class Btlog:
    xml: str
    first_timestamp_us: int
    transitions: list[Transition]


def write_btlog(run_folder: Path, out: Path) -> Path:
    """Write the run in ``run_folder`` as a .btlog at ``out`` (a folder: ``<run folder name>.btlog``
    in it); returns the file written."""
    run_folder = Path(run_folder)
    out = Path(out)
    if out.is_dir():
        out = out / f"{run_folder.resolve().name}.btlog"
    if out.suffix != ".btlog":
        raise BtlogError(f"{out}: a Groot2 log's name must end in .btlog (BT.CPP refuses any other)")
    tree, events = _recorded(run_folder)
    data = bytearray(MAGIC)
    data.append(PROTOCOL)
    xml = tree.xml().encode("utf-8")
    data += struct.pack("<i", len(xml)) + xml
    data += struct.pack("<q", _started_us(run_folder))
    for event in events:
        if event["ev"] == "status" and event["node"] not in tree.by_path:
            raise BtlogError(
                f"{run_folder}: its trace names node {event['node']!r} (tick {event['tick']}), which the mission "
                "has not any more: it changed since the run"
            )
        for uid, status in tree.changes(event):
            data += pack_transition(round(event["t"] * 1e6), uid, status)
    try:
        out.write_bytes(bytes(data))
    except OSError as exc:
        raise BtlogError(f"{out}: cannot write: {exc.strerror or exc}") from None
    return out


def read_btlog(path: Path) -> Btlog:
    """Read a .btlog file (ours or BT.CPP's ``FileLogger2``'s)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise BtlogError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if not data.startswith(MAGIC):
        raise BtlogError(f"{path}: not a .btlog file (it does not start with {MAGIC.decode()!r})")
    at = len(MAGIC)
    if len(data) < at + 5:
        raise BtlogError(f"{path}: cut short in its header (byte {len(data)})")
    if data[at] != PROTOCOL:
        raise BtlogError(f"{path}: byte {at}: protocol {data[at]}, only {PROTOCOL} is known")
    (size,) = struct.unpack_from("<i", data, at + 1)
    at += 5
    if size < 0 or len(data) < at + size + 8:
        raise BtlogError(f"{path}: byte {at - 4}: the XML's length {size} runs past the end of the file")
    try:
        xml = data[at : at + size].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BtlogError(f"{path}: byte {at + exc.start}: the XML is not UTF-8") from None
    at += size
    (first,) = struct.unpack_from("<q", data, at)
    at += 8
    body = len(data) - at
    if body % TRANSITION_SIZE:
        raise BtlogError(
            f"{path}: byte {at + body - body % TRANSITION_SIZE}: a transition cut short "
            f"({body % TRANSITION_SIZE} of {TRANSITION_SIZE} bytes)"
        )
    transitions = []
    for offset in range(at, len(data), TRANSITION_SIZE):
        stamp = int.from_bytes(data[offset : offset + 6], "little")
        uid, status = struct.unpack_from("<HB", data, offset + 6)
        transitions.append(Transition(stamp, uid, status))
    return Btlog(xml, first, transitions)


def _recorded(folder: Path) -> tuple[GrootTree, list[dict]]:
    trace, summary_file = folder / "trace.jsonl", folder / "summary.json"
    for needed in (trace, summary_file):
        if not needed.is_file():
            raise BtlogError(f"{folder} is not a run folder: it has no {needed.name}")
    try:
        mission = Path(json.loads(summary_file.read_text(encoding="utf-8"))["mission_file"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise BtlogError(f"{summary_file}: cannot read the mission it ran: {exc}") from None
    try:
        events = read_jsonl(trace)
    except (OSError, ValueError) as exc:
        raise BtlogError(f"{trace}: not a botstage trace: {exc}") from None
    checked = check(mission)
    if not checked.ok or checked.mission is None:
        where = "; ".join(str(problem) for problem in checked.problems[:3])
        raise BtlogError(f"the run's mission {mission} does not check any more: {where}")
    spec = checked.mission
    engine = Engine(clock=SimClock(spec.rate_hz), registry=checked.registry, kinds=checked.kinds)
    try:
        root = build_root(engine.builder(spec.trees, spec.machines, spec.skill_params), spec, root_spec_path(spec))
        return GrootTree(root, spec.name), events
    finally:
        engine.close()


def _started_us(folder: Path) -> int:
    found = _STARTED.search(folder.resolve().name)
    if found is None:
        return 0
    return round(datetime.strptime(found.group(1), "%Y%m%d-%H%M%S").timestamp() * 1e6)
