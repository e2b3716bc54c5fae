"""`botstage machine`: a mission's state machines drawn, with the trees in their states."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions import DEFAULT_MISSION
from botstage.missions.cli.common import NON_NEGATIVE, input_file, output_file
from botstage.missions.cli.pictures import FORMAT_HELP, draw


def machine(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    fmt: str = typer.Option("ascii", "--format", "-f", help=FORMAT_HELP),
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
    draw(mission, None, True, fmt, output, trace, at, coverage)
