"""`botstage test`: scenario files run without pytest, with coverage on request."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from botstage.missions.cli.common import _fail, _stderr, console, input_paths, os_problem, output_file


def test_scenarios(
    paths: list[Path] = typer.Argument(
        None, help="scenario files or folders (default: missions/scenarios)", callback=input_paths
    ),
    coverage: bool = typer.Option(False, "--coverage", help="print coverage per mission and write it"),
    coverage_file: Path = typer.Option(Path("coverage.json"), help="where --coverage writes its figures"),
) -> None:
    """Run scenario tests without pytest; a failure prints its readable report and keeps its run
    folder (the report names it). Exit 1 if any fails."""
    from botstage.missions.coverage import Session, write
    from botstage.missions.scenario_suite import SuiteError, run_suite, scenario_files

    if coverage:  # checked before the suite runs, not after
        try:
            output_file(coverage_file)
        except typer.BadParameter as exc:
            raise _fail(f"error: --coverage-file: {exc.message}", 2) from None
    roots = paths or [Path("missions/scenarios")]
    try:
        files = scenario_files(roots)
    except SuiteError as exc:
        raise _fail(f"error: {exc}", 2) from None
    failed = 0
    session = Session()
    for path, result in run_suite(files):
        session.add(result)
        if result.passed:
            console.print(f"[green]PASS[/] {path}", highlight=False, soft_wrap=True)
        else:
            failed += 1
            console.print(f"[red]FAIL[/] {path}", highlight=False, soft_wrap=True)
            _stderr([result.report(), ""])
    if coverage:
        reports = session.reports()
        table = Table("mission", "runs", "nodes", "states", "transitions")
        for report in reports:
            f = report.figures()
            table.add_row(
                report.mission,
                str(f["runs"]),
                *(
                    f"{f[k]['percent']:g}% ({f[k]['covered']}/{f[k]['total']})"
                    for k in ("nodes", "states", "transitions")
                ),
            )
        console.print(table)
        for report in reports:
            for kind, items in zip(("node", "state", "transition"), report.untested(), strict=True):
                for name in items:
                    console.print(f"  untested {kind}: {name}", highlight=False, soft_wrap=True)
        try:
            write(reports, coverage_file)
        except OSError as exc:
            raise _fail(f"error: cannot write coverage: {os_problem(exc)}") from None
        console.print(f"coverage written to {coverage_file}", highlight=False, soft_wrap=True)
    console.print(f"{len(files) - failed} passed, {failed} failed", highlight=False)
    if failed:
        raise typer.Exit(1)
