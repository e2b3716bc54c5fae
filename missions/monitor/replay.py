"""A finished run's folder as the monitor shows it: the same views as live, and the run at any
tick (the tree at tick N drawn exactly as ``botstage tree --trace … --at N`` draws it), with the
robot on the run's map where it was at that tick: the true pose and the estimate from the
monitor's ``poses.csv``, or, for a run made without the monitor, the true pose from a simulation's
``trajectory.csv``."""

from __future__ import annotations

import bisect
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from botstage.behaviors.render import Item, render, statuses_at, to_plain
from botstage.behaviors.trace import read_jsonl
from botstage.missions.check import check, describe_part
from botstage.missions.monitor.hub import Hub, type_name
from botstage.missions.monitor.robot_view import POSES_FILE, read_poses
from botstage.robots.gridmap import GridMap, map_path
from botstage.robots.gridmap import load as load_map
from botstage.skills.display import DEFAULT as DEFAULT_LAYOUT
from botstage.skills.display import LAYOUTS

LAYOUT_KEY = "layout"  # the display skill's default key (the report reads the same)


class RunFolderError(Exception):
    """The folder is not a run botstage can show (no trace, no summary, a mission that moved)."""


@dataclass
class RecordedPoses:
    """Where the robot was, by tick (poses.csv) or by mission time (trajectory.csv)."""

    keys: list[float] = field(default_factory=list)  # ticks or times, ascending
    rows: list[tuple[list[float] | None, list[float] | None]] = field(default_factory=list)  # (true, estimate)
    by_tick: bool = True

    def at(self, tick: int, t: float) -> dict[str, Any] | None:
        """The last poses recorded at or before ``tick`` (at ``t``); None before the first."""
        i = bisect.bisect_right(self.keys, tick if self.by_tick else t + 1e-9) - 1
        if i < 0:
            return None
        true_pose, estimate = self.rows[i]
        return {"pose": true_pose, "estimate": estimate}


def recorded_poses(folder: Path) -> RecordedPoses | None:
    """The poses the run folder holds (the monitor's first, a simulation's true path else)."""
    try:
        if (folder / POSES_FILE).is_file():
            rows = read_poses(folder / POSES_FILE)
            return RecordedPoses([tick for tick, _, _ in rows], [(p, e) for _, p, e in rows], by_tick=True)
        if (folder / "trajectory.csv").is_file():
            lines = (folder / "trajectory.csv").read_text(encoding="utf-8").splitlines()[1:]
            cells = [[float(v) for v in line.split(",")] for line in lines if line.count(",") == 3]
            rows = [([round(x, 3), round(y, 3), round(theta, 4)], None) for _, x, y, theta in cells]
            return RecordedPoses([c[0] for c in cells], rows, by_tick=False)
    except (OSError, ValueError):
        return None  # a record that cannot be read: the replay shows no robot rather than fail
    return None


def run_map(mission: Any, relative_to: Path) -> GridMap | None:
    """The map of the run's world (None for a mission without one, or one that cannot load)."""
    world = getattr(mission, "world", None)
    if not world:
        return None
    found = map_path(world, relative_to)
    if found is None:
        return None
    try:
        return load_map(found)
    except (OSError, ValueError):  # MapError is a ValueError
        return None


@dataclass
class RecordedRun:
    folder: Path
    mission: Path
    events: list[dict[str, Any]]
    item: Item
    hub: Hub
    poses: RecordedPoses | None = None

    @property
    def first(self) -> int:
        return self.events[0]["tick"] if self.events else 0

    @property
    def last(self) -> int:
        return self.events[-1]["tick"] if self.events else 0

    def at(self, tick: int) -> dict[str, Any]:
        """Statuses, active states, keys and the tree drawn as text, as they were at ``tick``."""
        statuses = statuses_at(self.events, tick)
        board: dict[str, dict[str, Any]] = {}
        t = 0.0
        for event in self.events:
            if event["tick"] > tick:
                break
            t = event["t"]
            if event["ev"] == "bb_write":
                value = event["new"]
                board[event["key"]] = {
                    "value": value,
                    "type": type_name(value),
                    "writer": event["writer"],
                    "tick": event["tick"],
                }
        return {
            "tick": tick,
            "t": t,
            "statuses": statuses.nodes,
            "states": {machine: f"{machine}/{state}" for machine, state in statuses.states.items()},
            "blackboard": board,
            "text": render(self.item, "unicode", statuses).decode(),
            "robot": self.poses.at(tick, t) if self.poses is not None else None,
        }


def load_run(folder: Path) -> RecordedRun:
    """Read a run folder (``trace.jsonl``, ``summary.json`` and the mission it names)."""
    trace, summary_file = folder / "trace.jsonl", folder / "summary.json"
    for needed in (trace, summary_file):
        if not needed.is_file():
            raise RunFolderError(f"{folder} is not a run folder: it has no {needed.name}")
    try:
        summary = json.loads(summary_file.read_text(encoding="utf-8"))
        mission = Path(summary["mission_file"])
        events = read_jsonl(trace)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RunFolderError(f"cannot read the run in {folder}: {exc}") from None
    checked = check(mission)
    if not checked.ok:
        where = "; ".join(str(p) for p in checked.problems[:3])
        raise RunFolderError(f"the run's mission {mission} does not check any more: {where}")
    item = describe_part(checked)
    hub = Hub()
    hub.info = {
        "mode": "replay",
        "mission": summary.get("mission", mission.stem),
        "robot": summary.get("robot"),
        "simulated": summary.get("backend") == "sim",
        "rate_hz": checked.mission.rate_hz if checked.mission else None,
    }
    hub.structure = to_plain(item)
    hub.folder = folder
    hub.grid = run_map(checked.mission, mission.parent)
    try:
        for event in events:
            hub.apply(event)
            if event["ev"] == "bb_write" and event["key"] == LAYOUT_KEY and event["new"] != event["old"]:
                layout = event["new"] or DEFAULT_LAYOUT  # an empty key: the default expression
                hub.shown(str(layout), {"meaning": LAYOUTS.get(str(layout), "")}, at=(event["tick"], event["t"]))
    except (KeyError, TypeError) as exc:
        raise RunFolderError(f"{trace} is not a botstage trace: {exc}") from None
    hub.set_flags(ended=True, outcome=summary.get("outcome", ""))
    hub.ready.set()
    poses = recorded_poses(folder) if hub.grid is not None else None
    return RecordedRun(folder, mission, events, item, hub, poses)
