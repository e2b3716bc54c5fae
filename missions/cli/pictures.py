"""Verbs that draw a mission: its tree and its state machines."""

from __future__ import annotations

import sys
from pathlib import Path

import typer
from botstage.behaviors.render import FORMATS
from botstage.missions import DEFAULT_MISSION
from botstage.missions.cli.common import NON_NEGATIVE, _fail, _stderr, input_file, os_problem, output_file

_FORMATS = ", ".join(FORMATS[:-1]) + f" or {FORMATS[-1]}"


def _picture(
    mission: Path,
    tree: str | None,
    machine: bool,
    fmt: str,
    output: Path | None,
    trace: Path | None,
    at: int | None,
    coverage: Path | None = None,
) -> None:
    from botstage.missions.pictures import InvalidMission, PictureError, picture

    def note(line: str) -> None:
        _stderr([line])

    if output is None and fmt == "png":  # said before the work, not after it
        raise _fail("error: png is binary: give a file with -o", 2)
    try:
        data = picture(mission, fmt, machine=machine, tree=tree, trace=trace, at=at, coverage=coverage, note=note)
    except InvalidMission as exc:
        raise _fail([str(p) for p in exc.problems]) from None
    except PictureError as exc:
        raise _fail(f"error: {exc}", 2) from None
    if output is None:
        sys.stdout.write(data.decode())
        return
    try:
        output.write_bytes(data)
    except OSError as exc:
        raise _fail(f"error: cannot write the picture: {os_problem(exc)}") from None


def tree(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    tree_name: str | None = typer.Option(None, "--tree", help="a named tree (default: what the mission runs)"),
    fmt: str = typer.Option("unicode", "--format", "-f", help=_FORMATS),
    output: Path | None = typer.Option(
        None, "-o", "--output", help="write to a file instead of stdout", callback=output_file
    ),
    trace: Path | None = typer.Option(
        None, help="colour nodes by their status in this recorded trace.jsonl", callback=input_file
    ),
    at: int | None = typer.Option(
        None, help="with --trace: the tick to show (default: the last)", callback=NON_NEGATIVE
    ),
    coverage: Path | None = typer.Option(
        None, help="draw what this coverage.json says no test reached", callback=input_file
    ),
) -> None:
    """Draw a mission's tree (or what it runs: a machine is drawn with the trees in its states)."""
    _picture(mission, tree_name, False, fmt, output, trace, at, coverage)


def machine(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    fmt: str = typer.Option("ascii", "--format", "-f", help=_FORMATS),
    output: Path | None = typer.Option(
        None, "-o", "--output", help="write to a file instead of stdout", callback=output_file
    ),
    trace: Path | None = typer.Option(
        None, help="colour states and nodes by a recorded trace.jsonl", callback=input_file
    ),
    at: int | None = typer.Option(
        None, help="with --trace: the tick to show (default: the last)", callback=NON_NEGATIVE
    ),
    coverage: Path | None = typer.Option(
        None, help="draw what this coverage.json says no test reached", callback=input_file
    ),
) -> None:
    """Draw a mission's state machines, wherever they sit (a tree's node too), with the trees
    inside their states; a mission without one gets the tree it runs."""
    _picture(mission, None, True, fmt, output, trace, at, coverage)
