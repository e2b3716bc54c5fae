"""Coverage of a mission by a test session: which nodes were ticked and with which outcomes,
which states were entered and which transitions and preemptions were taken.

The universe comes from the mission as it is built (the same description the pictures use);
what was covered comes from the traces of the session's runs, summed per mission.
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from botstage.behaviors.render import Item
from botstage.missions.check import check, describe_part
from botstage.missions.loader import display_name


def _walk(item: Item) -> Iterator[Item]:
    yield item
    for child in item.children:
        yield from _walk(child)


def _machines(item: Item) -> Iterator[Item]:
    return (i for i in _walk(item) if i.kind == "machine" and i.initial)


@dataclass
class Universe:
    """Everything a mission could do: node paths, state paths, transitions ("state:outcome")."""

    nodes: list[str] = field(default_factory=list)
    states: list[str] = field(default_factory=list)
    transitions: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, mission: Path) -> Universe:
        checked = check(mission)
        spec = checked.mission
        if spec is None or not checked.ok:
            raise ValueError(f"{mission} is not a valid mission")
        item = describe_part(checked)
        universe = cls()
        for it in _walk(item):
            if it.kind == "state":
                universe.states.append(it.path)
                universe.transitions += [f"{it.path}:{outcome}" for outcome, _, _ in it.transitions]
            elif it.kind not in ("machine", "outcome"):
                universe.nodes.append(it.path)
        for machine in _machines(item):
            universe.transitions += [f"{machine.machine}/preempt:{cond}" for cond, _ in machine.preemptions]
        universe.transitions = list(dict.fromkeys(universe.transitions))
        return universe


@dataclass
class Covered:
    """What runs did: per node its outcomes (a skill's outcome names, other nodes' final
    statuses), states entered and transitions taken, with counts."""

    nodes: dict[str, Counter[str]] = field(default_factory=lambda: defaultdict(Counter))
    states: Counter[str] = field(default_factory=Counter)
    transitions: Counter[str] = field(default_factory=Counter)
    runs: int = 0
    _skills: set[str] = field(default_factory=set)

    def add_trace(self, events: Iterable[Mapping[str, Any]]) -> None:
        self.runs += 1
        for event in events:
            kind = event["ev"]
            if kind == "skill_start":
                self._skills.add(event["node"])
            elif kind == "skill_outcome":
                self.nodes[event["node"]][event["outcome"]] += 1
            elif kind == "status":
                counts = self.nodes[event["node"]]  # ticked, whatever it did
                if event["new"] in ("SUCCESS", "FAILURE") and event["node"] not in self._skills:
                    counts[event["new"]] += 1  # how composites and decorators finished
            elif kind == "transition" and event["dest"]:
                machine = event["machine"]
                parts = event["dest"].split("/")
                for depth in range(1, len(parts) + 1):  # entering a/b enters a too
                    self.states[f"{machine}/{'/'.join(parts[:depth])}"] += 1
                trigger = event["trigger"]
                if trigger.startswith("preempt "):
                    self.transitions[f"{machine}/preempt:{trigger[len('preempt ') :].strip(chr(39))}"] += 1
                elif ":" in trigger:
                    self.transitions[f"{machine}/{trigger.split(' > ')[0]}"] += 1
                    for step in trigger.split(" > ")[1:]:  # outcomes a resolved chain passed through
                        self.transitions[f"{machine}/{step}"] += 1


@dataclass
class Report:
    mission: str
    universe: Universe
    covered: Covered

    def untested(self) -> tuple[list[str], list[str], list[str]]:
        nodes = [n for n in self.universe.nodes if n not in self.covered.nodes]
        states = [s for s in self.universe.states if s not in self.covered.states]
        transitions = [t for t in self.universe.transitions if t not in self.covered.transitions]
        return nodes, states, transitions

    def figures(self) -> dict[str, Any]:
        nodes, states, transitions = self.untested()

        def share(total: int, missing: int) -> dict[str, Any]:
            return {
                "covered": total - missing,
                "total": total,
                "percent": round(100 * (total - missing) / total, 1) if total else 100.0,
            }

        return {
            "runs": self.covered.runs,
            "nodes": share(len(self.universe.nodes), len(nodes)),
            "states": share(len(self.universe.states), len(states)),
            "transitions": share(len(self.universe.transitions), len(transitions)),
        }

    def to_json(self) -> dict[str, Any]:
        nodes, states, transitions = self.untested()
        return {
            **self.figures(),
            "untested": {"nodes": nodes, "states": states, "transitions": transitions},
            "node_outcomes": {
                n: dict(sorted(self.covered.nodes[n].items())) for n in self.universe.nodes if n in self.covered.nodes
            },
            "states_entered": {s: self.covered.states[s] for s in self.universe.states if s in self.covered.states},
            "transitions_taken": {
                t: self.covered.transitions[t] for t in self.universe.transitions if t in self.covered.transitions
            },
        }


class Session:
    """Coverage summed over the scenario runs of a test session, per mission file."""

    def __init__(self) -> None:
        self.covered: dict[Path, Covered] = {}

    def add(self, result: Any) -> None:  # a missions.scenario.Result
        if result.scenario.spec is None or not result.events:
            return
        mission = result.scenario.mission_path
        self.covered.setdefault(mission, Covered()).add_trace(result.events)

    def reports(self) -> list[Report]:
        return [Report(display_name(m), Universe.of(m), c) for m, c in sorted(self.covered.items())]


def write(reports: Iterable[Report], path: Path) -> None:
    path.write_text(json.dumps({r.mission: r.to_json() for r in reports}, indent=2) + "\n", encoding="utf-8")


def untested_of(coverage_file: Path, mission: Path) -> tuple[set[str], set[str]]:
    """The untested nodes and states, and the untested transitions, of a mission in coverage.json."""
    data = json.loads(coverage_file.read_text(encoding="utf-8"))
    found = [k for k in data if Path(k).resolve() == mission.resolve()]
    if not found:
        known = ", ".join(data) or "none"
        raise KeyError(f"{coverage_file} has no coverage of {mission} (it covers: {known})")
    untested = data[found[0]]["untested"]
    return set(untested["nodes"]) | set(untested["states"]), set(untested["transitions"])
