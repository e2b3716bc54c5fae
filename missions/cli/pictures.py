"""Verbs that draw a mission: its tree and its state machine."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from missions import DEFAULT_MISSION
from missions.cli.common import _fail, _stderr


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
    from missions.pictures import InvalidMission, PictureError, picture

    def note(line: str) -> None:
        _stderr([line])

    try:
        data = picture(mission, fmt, machine=machine, tree=tree, trace=trace, at=at, coverage=coverage, note=note)
    except InvalidMission as exc:
        raise _fail([str(p) for p in exc.problems]) from None
    except PictureError as exc:
        raise _fail(f"error: {exc}", 2) from None
    if output is None:
        if fmt == "png":
            raise _fail("error: png is binary: give a file with -o", 2)
        sys.stdout.write(data.decode())
    else:
        output.write_bytes(data)


def tree(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    tree_name: str | None = typer.Option(None, "--tree", help="a named tree (default: what the mission runs)"),
    fmt: str = typer.Option("unicode", "--format", "-f", help="ascii, unicode, dot, svg, png, mermaid or json"),
    output: Path | None = typer.Option(None, "-o", "--output", help="write to a file instead of stdout"),
    trace: Path | None = typer.Option(None, help="colour nodes by their status in this recorded trace.jsonl"),
    at: int | None = typer.Option(None, help="with --trace: the tick to show (default: the last)"),
    coverage: Path | None = typer.Option(None, help="draw what this coverage.json says no test reached"),
) -> None:
    """Draw a mission's tree (or what it runs: a machine is drawn with the trees in its states)."""
    _picture(mission, tree_name, False, fmt, output, trace, at, coverage)


def machine(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    fmt: str = typer.Option("ascii", "--format", "-f", help="ascii, dot, svg, png or mermaid"),
    output: Path | None = typer.Option(None, "-o", "--output", help="write to a file instead of stdout"),
    trace: Path | None = typer.Option(None, help="colour states and nodes by a recorded trace.jsonl"),
    at: int | None = typer.Option(None, help="with --trace: the tick to show (default: the last)"),
    coverage: Path | None = typer.Option(None, help="draw what this coverage.json says no test reached"),
) -> None:
    """Draw a mission's state machine, with the trees inside its states."""
    _picture(mission, None, True, fmt, output, trace, at, coverage)
