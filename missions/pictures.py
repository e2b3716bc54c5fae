"""A mission's tree or machine drawn as bytes (text, DOT, SVG, PNG...), optionally coloured by a
recorded trace or by what coverage says no test reached: `botstage tree` and `botstage machine`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from behaviors.render import (
    MACHINE_FORMATS,
    TREE_FORMATS,
    GraphvizMissing,
    Statuses,
    render,
    statuses_at,
)
from behaviors.trace import read_jsonl
from missions.check import check, describe_part, root_spec_path
from missions.coverage import untested_of
from missions.loader import Problem


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

    `trace` colours nodes by their status at tick `at` (default: the last); `coverage` marks what
    no test reached. `note` hears what is drawn instead of what was asked (a machine the mission
    lacks), before any error, so that a caller can show it first.
    """
    known = MACHINE_FORMATS if machine else TREE_FORMATS
    if fmt not in known:
        raise PictureError(f"unknown format {fmt!r}; use one of {', '.join(known)}")
    checked = check(mission)
    if not checked.ok:
        raise InvalidMission(list(checked.problems))
    spec = checked.mission
    assert spec is not None
    if machine and spec.machine is None:
        note(f"note: {mission} has no machine; drawing the tree it runs")
        spec_path: tuple[str, ...] = root_spec_path(spec)  # type: ignore[assignment]
    elif machine:
        spec_path = ("machine",)
    elif tree is not None:
        if tree not in spec.trees:
            names = ", ".join(spec.trees) or "none"
            raise PictureError(f"{mission} has no tree {tree!r} (trees: {names})")
        spec_path = ("trees", tree)
    else:
        spec_path = root_spec_path(spec)  # type: ignore[assignment]
    statuses = None
    if trace is not None:
        try:
            events = read_jsonl(trace)
        except (OSError, ValueError) as exc:
            raise PictureError(f"cannot read trace {trace}: {exc}") from None
        last = events[-1]["tick"] if events else 0
        statuses = statuses_at(events, last if at is None else at)
    if coverage is not None:
        try:
            untested, untested_transitions = untested_of(coverage, mission)
        except (OSError, ValueError, KeyError) as exc:
            raise PictureError(f"cannot use coverage {coverage}: {str(exc).strip(chr(34))}") from None
        statuses = statuses or Statuses()
        statuses.untested, statuses.untested_transitions = untested, untested_transitions
    try:
        return render(describe_part(checked, spec_path), fmt, statuses)
    except GraphvizMissing as exc:
        raise PictureError(str(exc)) from None
