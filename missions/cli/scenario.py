"""`botstage scenario`: scenario files made from recorded runs."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import _fail, console, input_file, output_file

scenario_app = typer.Typer(no_args_is_help=True, help="Scenario files: make them from recorded runs.")


@scenario_app.command("from-trace")
def scenario_from_trace(
    trace: Path = typer.Argument(
        ..., help="a recorded run's trace.jsonl (its summary.json beside it)", callback=input_file
    ),
    output: Path = typer.Option(..., "-o", "--output", help="the scenario file to write", callback=output_file),
    mission: Path | None = typer.Option(
        None, help="the mission (default: the one summary.json names)", callback=input_file
    ),
) -> None:
    """Turn a recorded run into a regression scenario that replays its skill outcomes."""
    from botstage.missions.scenario import from_trace

    try:
        spec = from_trace(trace, output, mission)
    except (OSError, ValueError, KeyError) as exc:
        raise _fail(f"error: {exc}", 2) from None
    calls = sum(c.get("times", 1) for v in spec["mocks"].values() for c in v)
    console.print(
        f"wrote {output}: {calls} recorded calls of {len(spec['mocks'])} skills, "
        f"{len(spec['expect']['states'])} states expected",
        highlight=False,
        soft_wrap=True,
    )
