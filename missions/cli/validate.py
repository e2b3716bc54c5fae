"""`botstage validate`: missions and deployments checked, never run."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import _stderr, console


def validate(missions: list[Path] = typer.Argument(..., help="mission or deployment files to check")) -> None:
    """Check missions (or deployments, with their mission) without running them; errors as
    file:line:col, exit status 1 if any."""
    from botstage.missions.check import check
    from botstage.missions.deployment import check_deployment, is_deployment

    failed = False
    for path in missions:
        checked = check_deployment(path) if is_deployment(path) else check(path)
        _stderr([str(problem) for problem in checked.problems])
        failed |= not checked.ok
        if checked.ok:
            console.print(f"{path}: ok")
    if failed:
        raise typer.Exit(1)
