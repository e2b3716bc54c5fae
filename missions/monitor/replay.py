"""A finished run's folder as the monitor shows it: the same views as live, and the run at any
tick (the tree at tick N drawn exactly as ``botstage tree --trace … --at N`` draws it)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from behaviors.render import Item, render, statuses_at, to_plain
from behaviors.trace import read_jsonl
from missions.check import check, describe_part
from missions.monitor.hub import Hub, type_name
from skills.display import DEFAULT as DEFAULT_LAYOUT
from skills.display import LAYOUTS

LAYOUT_KEY = "layout"  # the display skill's default key (the report reads the same)


class RunFolderError(Exception):
    """The folder is not a run botstage can show (no trace, no summary, a mission that moved)."""


@dataclass
class RecordedRun:
    folder: Path
    mission: Path
    events: list[dict[str, Any]]
    item: Item
    hub: Hub

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
    return RecordedRun(folder, mission, events, item, hub)
