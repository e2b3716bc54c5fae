"""`botstage run`: a mission run to its run folder, watched live, by the monitor or by Groot2 on request."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.live import Live
from rich.table import Table

from botstage.missions import DEFAULT_MISSION
from botstage.missions.cli.common import (
    NON_NEGATIVE,
    _fail,
    _stderr,
    console,
    number,
    os_problem,
    output_dir,
)
from botstage.missions.cli.live import HOST_HELP, live_monitor
from botstage.missions.cli.opening import backend_help, backend_options, observer_help, observers
from botstage.robots.backend_registry import DEFAULT
from botstage.robots.limits import MAX_SECONDS

if TYPE_CHECKING:
    from botstage.missions.groot2.publisher import Groot2Publisher

UNTIL = number(gt=0, le=MAX_SECONDS)  # as `until:` in a mission file


def _live_progress(live: Live):
    def show(snapshot) -> None:
        p = snapshot()
        table = Table.grid(padding=(0, 2))
        speed = p.sim_time_s / p.wall_time_s if p.wall_time_s > 0 else 0.0
        table.add_row("mission", p.mission)
        table.add_row(
            "time", f"{p.sim_time_s:.1f} s mission, {p.wall_time_s:.1f} s wall ({speed:.0f}×), {p.ticks} ticks"
        )
        table.add_row("state", p.state or "-")
        table.add_row("running", "\n".join(p.running[:8]) or "-")
        live.update(table)

    return show


# -- Groot2 (missions/groot2) ------------------------------------------------------------------

GROOT2_HOST_HELP = "address Groot2 connects to (default 127.0.0.1; ZMQ has no authentication: see docs/guides/btcpp.md)"
_LOOPBACK = ("127.0.0.1", "localhost", "::1")


def _groot2(host: str, port: int) -> Groot2Publisher:
    """The Groot2 publisher for `run --groot2`, listening before the run starts."""
    from botstage.missions.groot2.publisher import Groot2Error, Groot2Publisher

    if host not in _LOOPBACK:
        _stderr(
            [
                f"warning: Groot2 listens on {host}: its protocol has no authentication, so anyone who can reach "
                f"ports {port} and {port + 1} can watch the run, hold it at breakpoints and change what nodes return"
            ]
        )
    try:
        publisher = Groot2Publisher(port, host)
    except Groot2Error as exc:
        raise _fail(f"error: {exc}", 2) from None
    console.print(f"groot2: {host}:{port} (notifications on {port + 1})", highlight=False, soft_wrap=True)
    return publisher


# -- end Groot2


def run(
    mission: Path = typer.Argument(
        DEFAULT_MISSION, help="mission YAML or BehaviorTree.CPP v4 XML (default: the PeopleBot entertainer)"
    ),
    robot: str | None = typer.Option(None, help="run on this robot profile instead of the mission's (for XML trees)"),
    world: str | None = typer.Option(None, help="in this world (map) instead of the mission's (for XML trees)"),
    backend: str = typer.Option(DEFAULT, help=backend_help()),
    port: str | None = typer.Option(None, help="the robot's serial port, e.g. /dev/ttyACM0 (--backend-opt port=...)"),
    backend_opt: list[str] = typer.Option(
        [], "--backend-opt", metavar="KEY=VALUE", help="a backend option (repeatable); see `botstage backends`"
    ),
    observe: list[str] = typer.Option([], "--observe", metavar="NAME", help=observer_help()),
    seed: int | None = typer.Option(None, help="random seed (default: the mission's)", callback=NON_NEGATIVE),
    until: float | None = typer.Option(
        None, help="stop after this many seconds of mission time (default: the mission's)", callback=UNTIL
    ),
    realtime: bool = typer.Option(False, help="pace the simulation at wall-clock speed"),
    out: Path | None = typer.Option(
        None, help="run folder (default: runs/<mission>-<timestamp>/)", callback=output_dir
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no live display"),
    monitor: bool = typer.Option(False, "--monitor", help="serve the live monitor while the mission runs"),
    monitor_port: int = typer.Option(8470, help="the monitor's port (0: a free one)", min=0, max=65535),
    monitor_host: str = typer.Option("127.0.0.1", help=HOST_HELP),
    paused: bool = typer.Option(False, "--paused", help="with --monitor: hold the run before its first tick"),
    groot2: bool = typer.Option(False, "--groot2", help="let Groot2 attach: its ZMQ protocol while the mission runs"),
    groot2_port: int = typer.Option(1667, help="Groot2's port (its notifications on the next one)", min=1, max=65534),
    groot2_host: str = typer.Option("127.0.0.1", help=GROOT2_HOST_HELP),
    set_values: list[str] = typer.Option(
        [], "--set", metavar="KEY=VALUE", help="an initial blackboard value, VALUE read as YAML (repeatable)"
    ),
) -> None:
    """Run a mission and write its run folder (trace.jsonl, summary.json, report.html).

    With --monitor a web page shows the run live and steers it (pause, breakpoints, forced
    outcomes, e-stop); add --realtime to watch a simulation at the robot's own pace.

    Exit status: 0 success or time limit, 1 nothing ran (invalid mission, a file), 2 usage,
    3 the mission ended in failure, 4 the run stopped on an error, 130 interrupted.
    """
    from botstage.missions.runner import MissionInvalid, RunError

    run_mission = runner_for(robot, world, blackboard_values(set_values))
    warn_unplaced(mission, robot, world)

    given = {
        "backend": backend,
        "seed": seed,
        "until": until,
        "realtime": realtime,
        "out": out,
        "port": port,
        "backend_options": backend_options(backend_opt),
        "observers": observers(observe),
    }
    if paused and not monitor:
        raise _fail("error: --paused holds the run for the monitor: add --monitor", 2)
    watching = live_monitor(monitor_host, monitor_port, paused) if monitor else contextlib.nullcontext()
    groot = _groot2(groot2_host, groot2_port) if groot2 else None  # Groot2 (missions/groot2)
    try:
        with watching as observer, contextlib.closing(groot) if groot else contextlib.nullcontext():
            if groot is not None:
                given["observers"] = [*given["observers"], groot]
            if observer is not None:
                given["observers"] = [*given["observers"], observer]
            if quiet or not console.is_terminal:
                result = run_mission(mission, **given)
            else:
                with Live(console=console, refresh_per_second=8, transient=True) as live:
                    result = run_mission(mission, progress=_live_progress(live), **given)
    except MissionInvalid as exc:
        raise _fail([str(p) for p in exc.problems]) from None
    except RunError as exc:
        raise _fail(exc.lines(), 2) from None
    except OSError as exc:  # the run folder or a file in it cannot be written
        raise _fail(f"error: {os_problem(exc)}") from None
    s = result.summary
    console.print(
        f"[bold]{s['mission']}[/]: outcome [bold]{result.outcome}[/]"
        + (f" ({result.reason})" if result.reason else ""),
        highlight=False,
        soft_wrap=True,
    )
    console.print(
        f"{s['ticks']} ticks, {s['sim_time_s']:g} s mission time in {s['wall_time_s']:g} s wall time; "
        f"report {result.folder / 'report.html'}",
        highlight=False,
        soft_wrap=True,
    )
    for error in s.get("observer_errors", []):
        _stderr([f"warning: observer {error}"])
    if result.exit_status:
        raise typer.Exit(result.exit_status)


def blackboard_values(assignments: list[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` options as initial blackboard values, each VALUE read as YAML
    (``exhibit_a`` a string, ``[2.0, 3.5]`` a list, ``4`` a number); a bad one is a usage error."""
    import yaml

    values: dict[str, Any] = {}
    for text in assignments:
        key, sep, raw = text.partition("=")
        if not sep or not key.strip():
            raise _fail(f"error: --set {text!r}: expected KEY=VALUE, e.g. --set goal=exhibit_a", 2)
        try:
            values[key.strip()] = yaml.safe_load(raw) if raw.strip() else ""
        except yaml.YAMLError as exc:
            raise _fail(f"error: --set {text!r}: the value is not YAML: {exc}", 2) from None
    return values


def runner_for(robot: str | None, world: str | None, values: dict[str, Any] | None = None) -> Callable[..., Any]:
    """How `run` runs a mission file: as it is, or, with ``--robot``/``--world`` (a tree file
    names neither) or ``--set`` values, as a mission with them set: checked first (problems at
    the file's lines), then written to the run folder as mission.yaml and run from there."""
    from botstage.missions.runner import run

    if robot is None and world is None and not values:
        return run

    from botstage.missions.api.mission import Mission
    from botstage.robots.gridmap import known_maps, map_path
    from botstage.robots.profile import known_profiles, profile_path

    # found from the working directory, as paths on a command line are; a bad one is a usage error
    for option, value, find, shipped, noun in (
        ("--robot", robot, profile_path, known_profiles, "robot profile"),
        ("--world", world, map_path, known_maps, "world"),
    ):
        if value is not None and find(value, Path.cwd()) is None:
            raise _fail(f"error: {option}: unknown {noun} {value!r} (shipped: {', '.join(shipped())})", 2)

    def run_placed(path: Path, **options: Any) -> Any:
        mission = Mission.from_yaml(path)
        if robot is not None:
            mission.robot = str(profile_path(robot, Path.cwd()) if robot not in known_profiles() else robot)
        if world is not None:
            mission.world = str(map_path(world, Path.cwd()) if world not in known_maps() else world)
        if values:
            mission.blackboard = {**mission.blackboard, **values}  # --set
        return mission.run(**options)

    return run_placed


def warn_unplaced(path: Path, robot: str | None, world: str | None) -> None:
    """A tree file run without a robot runs its tree alone, on no robot: say so."""
    if path.suffix.lower() == ".xml" and robot is None:
        _stderr([f"note: {path} names no robot; add --robot PROFILE --world MAP to drive one"])
