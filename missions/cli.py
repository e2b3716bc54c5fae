"""The `botstage` command line."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from missions import DEFAULT_MISSION

app = typer.Typer(
    no_args_is_help=True,
    add_completion=False,
    help="Orchestrate robots with behaviour trees and hierarchical state machines.",
)
bench_app = typer.Typer(no_args_is_help=True, help="Benchmarks: figures and ratios against a baseline run alongside.")
app.add_typer(bench_app, name="bench")
console = Console()
errors = Console(stderr=True)


@app.command()
def run(
    mission: Path = typer.Argument(DEFAULT_MISSION, help="mission YAML (default: the hello mission)"),
    seed: int | None = typer.Option(None, help="random seed (default: the mission's)"),
    until: float | None = typer.Option(None, help="stop after this many seconds of mission time"),
    realtime: bool = typer.Option(False, help="pace the simulation at wall-clock speed"),
    out: Path | None = typer.Option(None, help="run folder (default: runs/<mission>-<timestamp>/)"),
) -> None:
    """Run a mission on the simulated clock and write its run folder."""
    from missions.runner import MissionError
    from missions.runner import run as run_mission

    try:
        result = run_mission(mission, seed=seed, until=until, realtime=realtime, out=out)
    except MissionError as exc:
        for line in str(exc).splitlines():
            errors.print(line, markup=False, highlight=False)
        raise typer.Exit(1) from None
    s = result.summary
    console.print(
        f"[bold]{s['mission']}[/]: outcome [bold]{result.outcome}[/]" + (f" ({result.reason})" if result.reason else "")
    )
    console.print(
        f"{s['ticks']} ticks, {s['sim_time_s']:g} s mission time in {s['wall_time_s']:g} s wall time; "
        f"run folder {result.folder}"
    )


@app.command()
def skills() -> None:
    """List the skills the registry finds (built-in and plugins) with their contracts."""
    from skills.registry import Registry

    registry = Registry.default()
    table = Table("skill", "inputs", "outputs", "outcomes", "from")
    for name in registry:
        info = registry.get(name).describe()
        table.add_row(
            name,
            ", ".join(info["inputs"]) or "-",
            ", ".join(info["outputs"]) or "-",
            ", ".join(info["outcomes"]),
            registry.origin(name),
        )
    console.print(table)
    for problem in registry.problems:
        errors.print(f"plugin {problem.entry_point}: {problem.reason}", markup=False)


def _load_bench(name: str):
    root = Path(__file__).resolve().parent.parent / "tests" / "bench"
    path = root / f"bench_{name}.py"
    if not path.exists():
        errors.print(
            f"benchmark {name!r} not found at {path}: benchmarks live in the source checkout's "
            "tests/bench/ (install it with `pip install -e .`)"
        )
        raise typer.Exit(2)
    spec = importlib.util.spec_from_file_location(f"botstage_bench_{name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@bench_app.command("tick")
def bench_tick(quick: bool = typer.Option(False, help="fewer repeats: a smoke run, not figures to quote")) -> None:
    """Engine tick cost vs plain py_trees, and machine trigger cost vs raw transitions."""
    results = _load_bench("tick").main(quick=quick)
    failed = [r["bench"] for r in results if r.get("ratio", 0) > r.get("target", float("inf"))]
    if failed and not quick:
        errors.print(f"over target: {', '.join(failed)}")
    _ = json  # figures are printed as JSON lines by the benchmark itself


def main() -> None:  # pragma: no cover - console script entry
    app()
