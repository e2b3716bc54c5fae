"""`botstage tree`: a mission's tree drawn, coloured by a recorded run or by coverage."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions import DEFAULT_MISSION
from botstage.missions.cli.common import NON_NEGATIVE, input_file, output_file
from botstage.missions.cli.pictures import FORMAT_HELP, draw


def tree(
    mission: Path = typer.Argument(DEFAULT_MISSION),
    tree_name: str | None = typer.Option(None, "--tree", help="a named tree (default: what the mission runs)"),
    fmt: str = typer.Option("unicode", "--format", "-f", help=FORMAT_HELP),
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
    draw(mission, tree_name, False, fmt, output, trace, at, coverage)
