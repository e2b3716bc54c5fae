"""What the monitor's pages see of a run, as versioned state shared between the run's thread and
the web server's.

The run's thread writes (``apply`` a trace event, ``set_flags``, ``shown``); pages read a
``snapshot`` once and then ``delta`` since the version they have: every item carries the version
that last changed it, so one page's pace never holds another back and nothing is queued per page.
Memory is bounded whatever the run's length: statuses and keys are as many as the mission has, the
timeline, each key's history and the layouts shown are rings.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from botstage.missions.transcript import ROLES

OPERATOR = "monitor"  # the node name the operator's actions carry in the trace
TIMELINE = 5_000  # entries a page can scroll back through
HISTORY = 200  # writes kept per key
SHOWN = 500  # layouts kept for the /display page
SAID = 500  # lines of the transcript kept
PHOTOS = 200  # photos kept on the page (the run folder has them all)
_TIMELINE_EVENTS = frozenset({"transition", "skill_start", "skill_outcome", "skill_cancel", "error", "log"})


def entry_text(record: Mapping[str, Any]) -> str:
    """One trace event (or an operator's action) as a sentence for the timeline."""
    ev = record["ev"]
    if ev == "transition":
        source = record["source"] or "(start)"
        reason = f" ({record['reason']})" if record.get("reason") else ""
        return f"{record['machine']}: {source} → {record['dest']} on {record['trigger']}{reason}"
    if ev == "skill_start":
        return f"{record['node']}: {record['skill']} started {_short(record.get('inputs'))}"
    if ev == "skill_outcome":
        outputs = f" {_short(record['outputs'])}" if record.get("outputs") else ""
        reason = f": {record['reason']}" if record.get("reason") else ""
        return f"{record['node']}: {record['skill']} → {record['outcome']}{reason}{outputs}"
    if ev == "skill_cancel":
        return f"{record['node']}: {record['skill']} cancelled ({record['reason']})"
    if ev == "error":
        return f"error: {record['reason']}"
    if ev == "log":
        return str(record["message"])
    return str(record.get("text", ev))


def _short(value: Any, limit: int = 160) -> str:
    import json

    text = json.dumps(value, default=str, ensure_ascii=False)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def type_name(value: Any) -> str:
    return "null" if value is None else type(value).__name__


def _newer(ring: deque[tuple[int, dict[str, Any]]], since: int) -> list[dict[str, Any]]:
    """The entries of ``ring`` after version ``since``: versions grow along a ring, so only its
    new end is read (a delta every 50 ms scanned the whole 5,000-entry timeline before)."""
    newer: list[dict[str, Any]] = []
    for version, entry in reversed(ring):
        if version <= since:
            break
        newer.append(entry)
    newer.reverse()
    return newer


@dataclass
class Flags:
    """The run as a whole: where it is, and whether the operator holds it."""

    tick: int = -1  # the last tick that ran (-1: none yet)
    t: float = 0.0
    paused: bool = False
    pause_reason: str = ""
    estopped: bool = False
    ended: bool = False
    outcome: str = ""

    def plain(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class Hub:
    """The monitor's view of one run (thread-safe; see the module's docstring)."""

    info: dict[str, Any] = field(default_factory=dict)
    structure: dict[str, Any] = field(default_factory=dict)
    version: int = 0
    flags: Flags = field(default_factory=Flags)
    statuses: dict[str, tuple[str, int]] = field(default_factory=dict)
    # when each status last changed (wall clock, epoch seconds): what `python -m tests.bench monitor`
    # measures the pages' latency from; never part of the run's own record
    changed_at: dict[str, float] = field(default_factory=dict)
    states: dict[str, tuple[str, int]] = field(default_factory=dict)
    blackboard: dict[str, tuple[dict[str, Any], int]] = field(default_factory=dict)
    history: dict[str, deque[dict[str, Any]]] = field(default_factory=dict)
    timeline: deque[tuple[int, dict[str, Any]]] = field(default_factory=lambda: deque(maxlen=TIMELINE))
    display: deque[tuple[int, dict[str, Any]]] = field(default_factory=lambda: deque(maxlen=SHOWN))
    breakpoints: list[dict[str, Any]] = field(default_factory=list)
    breakpoints_at: int = 0  # the version that last changed them: a delta carries them only then
    robot: tuple[dict[str, Any] | None, int] = (None, 0)  # the map's view of the robot (robot_view.py)
    camera: tuple[bytes, int] = (b"", 0)  # the latest camera frame (JPEG) while teleoperated, its number
    shown_count: int = 0
    grid: Any = None  # the run's map (a GridMap), for the map view
    folder: Any = None  # the run folder (a Path): the photos the page shows are in it
    said: deque[tuple[int, dict[str, Any]]] = field(default_factory=lambda: deque(maxlen=SAID))
    photos: deque[tuple[int, dict[str, Any]]] = field(default_factory=lambda: deque(maxlen=PHOTOS))
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    # set once info and structure are known (the run is built): pages asking earlier wait for it
    ready: threading.Event = field(default_factory=threading.Event, repr=False)

    # -- the run's thread ---------------------------------------------------------------------

    def apply(self, record: Mapping[str, Any]) -> None:
        """One trace event (a dict as the trace's listeners get it)."""
        ev = record["ev"]
        with self.lock:
            self.version += 1
            version = self.version
            if ev == "tick":
                self.flags.tick, self.flags.t = record["tick"], record["t"]
            elif ev == "status":
                self.statuses[record["node"]] = (record["new"], version)
                self.changed_at[record["node"]] = time.time()
            elif ev == "skill_cancel":
                self.statuses[record["node"]] = ("INVALID", version)
            elif ev == "transition":
                self.states[record["machine"]] = (f"{record['machine']}/{record['dest']}", version)
            elif ev == "bb_write":
                self._write(record, version)
            elif ev == "skill_outcome" and record["outputs"]:
                self._outputs(record, version)
            if ev in _TIMELINE_EVENTS:
                self._note(record, version)

    def _write(self, record: Mapping[str, Any], version: int) -> None:
        key, value = record["key"], record["new"]
        self.blackboard[key] = (
            {"value": value, "type": type_name(value), "writer": record["writer"], "tick": record["tick"]},
            version,
        )
        writes = self.history.get(key)
        if writes is None:
            writes = self.history[key] = deque(maxlen=HISTORY)
        writes.append({"tick": record["tick"], "t": record["t"], "value": value, "writer": record["writer"]})

    def _outputs(self, record: Mapping[str, Any], version: int) -> None:
        """Who said what (as the run's transcript takes it), and the photos taken."""
        outputs = record["outputs"]
        for port, who in ROLES.items():
            text = outputs.get(port)
            if isinstance(text, str) and text.strip():
                self.said.append((version, {"tick": record["tick"], "t": record["t"], "who": who, "text": text}))
        photo = outputs.get("photo") if record["skill"] == "photo" else None
        if isinstance(photo, str) and photo:
            self.photos.append((version, {"tick": record["tick"], "t": record["t"], "file": photo}))

    def _note(self, record: Mapping[str, Any], version: int) -> None:
        ev = record["ev"]
        if ev == "log" and record["node"] == OPERATOR:  # the operator's actions, as the trace has them
            ev = "breakpoint" if record["message"].startswith("breakpoint") else "control"
        entry: dict[str, Any] = {
            "tick": record["tick"],
            "t": record["t"],
            "ev": ev,
            "text": entry_text(record),
        }
        if "node" in record:
            entry["node"] = record["node"]
        if "level" in record:
            entry["level"] = record["level"]
        self.timeline.append((version, entry))

    def note(self, ev: str, text: str) -> None:
        """An operator's action or a breakpoint's hit, on the timeline."""
        with self.lock:
            self.version += 1
            flags = self.flags
            self.timeline.append((self.version, {"tick": flags.tick, "t": flags.t, "ev": ev, "text": text}))

    def set_flags(self, **changes: Any) -> None:
        with self.lock:
            for name, value in changes.items():
                setattr(self.flags, name, value)
            self.version += 1

    def shown(self, layout: str, content: Mapping[str, Any], at: tuple[int, float] | None = None) -> None:
        """The robot's Display was told to show ``layout`` (now, or ``at`` a tick and time)."""
        with self.lock:
            self.version += 1
            tick, t = at if at is not None else (self.flags.tick, self.flags.t)
            entry = {"tick": tick, "t": t, "layout": layout, "content": dict(content)}
            self.display.append((self.version, entry))
            self.shown_count += 1

    def set_robot(self, robot: dict[str, Any] | None) -> None:
        with self.lock:
            self.version += 1
            self.robot = (robot, self.version)

    def set_camera(self, jpeg: bytes) -> int:
        with self.lock:
            number = self.camera[1] + 1
            self.camera = (jpeg, number)
            return number

    def set_breakpoints(self, breakpoints: list[dict[str, Any]]) -> None:
        with self.lock:
            self.breakpoints = [dict(b) for b in breakpoints]
            self.version += 1
            self.breakpoints_at = self.version

    # -- the pages ----------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        return self.delta(0)

    def delta(self, since: int, stamps: bool = False) -> dict[str, Any]:
        """Everything that changed after version ``since`` (all of it for 0; the breakpoints and
        the robot only when they changed); ``stamps``: with the wall-clock time each changed status
        changed at."""
        with self.lock:
            if stamps:
                changed = [path for path, (_, v) in self.statuses.items() if v > since]
                extra = {"stamps": {path: self.changed_at.get(path, 0.0) for path in changed}}
            else:
                extra = {}
            return {
                **extra,
                "version": self.version,
                **self.flags.plain(),
                "statuses": {path: status for path, (status, v) in self.statuses.items() if v > since},
                "states": {machine: state for machine, (state, v) in self.states.items() if v > since},
                "blackboard": {key: info for key, (info, v) in self.blackboard.items() if v > since},
                "timeline": _newer(self.timeline, since),
                "display": _newer(self.display, since),
                "said": _newer(self.said, since),
                "photos": _newer(self.photos, since),
                **({"breakpoints": list(self.breakpoints)} if self.breakpoints_at > since or since == 0 else {}),
                **({"robot": self.robot[0]} if self.robot[1] > since or since == 0 else {}),
            }

    def key_history(self, key: str) -> list[dict[str, Any]] | None:
        with self.lock:
            writes = self.history.get(key)
            return None if writes is None else list(writes)

    def current_layout(self) -> dict[str, Any]:
        with self.lock:
            shown = [entry for _, entry in self.display]
            count = self.shown_count
        last = shown[-1] if shown else None
        return {
            "layout": last["layout"] if last else None,
            "content": last["content"] if last else {},
            "count": count,
            "shown": shown,
        }
