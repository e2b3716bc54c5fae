"""A mission's tree or machine drawn as bytes (text, DOT, SVG, PNG...), optionally coloured by a
recorded trace or by what coverage says no test reached: `botstage tree` and `botstage machine`."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

from botstage.behaviors.render import FORMATS, GraphvizMissing, Item, Statuses, group, machines_in, render, statuses_at
from botstage.behaviors.trace import read_jsonl
from botstage.missions.check import Checked, check, describe_part
from botstage.missions.coverage import untested_of
from botstage.missions.loader import Problem


class InvalidMission(Exception):
    """The mission does not check: nothing to draw (its problems, located)."""

    def __init__(self, problems: list[Problem]) -> None:
        super().__init__(f"{len(problems)} problem(s)")
        self.problems = problems


class PictureError(Exception):
    """The request cannot be drawn: a wrong format, tree, trace or coverage file, or no Graphviz."""


def picture(
    mission: Path,
    fmt: str,
    *,
    machine: bool = False,
    tree: str | None = None,
    trace: Path | None = None,
    at: int | None = None,
    coverage: Path | None = None,
    note: Callable[[str], None] = lambda line: None,
) -> bytes:
    """Draw what the mission runs (or its machine, or a named tree) in `fmt`.

    `machine` draws every machine the mission runs, wherever it sits (the root, a tree's node, a
    parallel's child); a mission that runs none gets its named machines, else the tree it runs.
    `trace` colours nodes by their status at tick `at` (default: the last); `coverage` marks what
    no test reached. `note` hears what is drawn instead of what was asked (a machine the mission
    lacks), before any error, so that a caller can show it first.
    """
    if fmt not in FORMATS:
        raise PictureError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    checked = check(mission)
    if not checked.ok:
        raise InvalidMission(list(checked.problems))
    spec = checked.mission
    assert spec is not None
    if tree is not None and tree not in spec.trees:
        names = ", ".join(spec.trees) or "none"
        raise PictureError(f"{mission} has no tree {tree!r} (trees: {names})")
    item = describe_part(checked, ("trees", tree) if tree is not None else None)
    if machine:
        item = machine_picture(checked, item, mission, note)
    statuses = None
    if trace is not None:
        try:
            events = read_jsonl(trace)
            last = events[-1]["tick"] if events else 0
            statuses = statuses_at(events, last if at is None else at)
        except (OSError, ValueError) as exc:
            raise PictureError(f"cannot read trace {trace}: {exc}") from None
        except (KeyError, TypeError, AttributeError):
            raise PictureError(f"cannot read trace {trace}: not a botstage trace (events of a run)") from None
    if coverage is not None:
        try:
            untested, untested_transitions = untested_of(coverage, mission)
        except (OSError, ValueError, KeyError) as exc:
            raise PictureError(f"cannot use coverage {coverage}: {str(exc).strip(chr(34))}") from None
        except (TypeError, AttributeError):
            raise PictureError(f"cannot use coverage {coverage}: not a coverage.json of botstage test") from None
        statuses = statuses or Statuses()
        statuses.untested, statuses.untested_transitions = untested, untested_transitions
    try:
        return render(item, fmt, statuses)
    except GraphvizMissing as exc:
        raise PictureError(str(exc)) from None
    except (RuntimeError, subprocess.TimeoutExpired) as exc:  # Graphviz failed or hung
        raise PictureError(str(exc)) from None


def machine_picture(checked: Checked, runs: Item, mission: Path, note: Callable[[str], None]) -> Item:
    """The machines in what runs (one picture, or a group of them); else the named ones; else the tree."""
    found = machines_in(runs)
    spec = checked.mission
    assert spec is not None
    if not found and spec.machines:
        note(f"note: {mission} runs no machine; drawing the machines it names")
        found = [describe_part(checked, ("machines", name)) for name in spec.machines]
    if not found:
        note(f"note: {mission} has no machine; drawing the tree it runs")
        return runs
    return found[0] if len(found) == 1 else group(f"{len(found)} machines of {spec.name}", found)
