"""The `botstage` command line."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import typer
from rich.console import Console
from rich.live import Live
from rich.table import Table

from missions import DEFAULT_MISSION

app = typer.Typer(
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,  # a traceback must never print a secret held in a variable
    help="Orchestrate robots with behaviour trees and hierarchical state machines.",
)
bench_app = typer.Typer(no_args_is_help=True, help="Benchmarks: figures and ratios against a baseline run alongside.")
app.add_typer(bench_app, name="bench")
scenario_app = typer.Typer(no_args_is_help=True, help="Scenario files: make them from recorded runs.")
app.add_typer(scenario_app, name="scenario")
speech_app = typer.Typer(no_args_is_help=True, help="Speech: the listen skill's recogniser on WAV files.")
app.add_typer(speech_app, name="speech")
console = Console()


def _fail(lines: list[str] | str, code: int = 1) -> typer.Exit:
    _stderr([lines] if isinstance(lines, str) else lines)
    return typer.Exit(code)


def _stderr(lines: list[str]) -> None:
    """One line per problem, never wrapped: editors and grep read `file:line:col: error: ...`."""
    sys.stderr.write("".join(line + "\n" for line in lines))
    sys.stderr.flush()


@app.command()
def validate(missions: list[Path] = typer.Argument(..., help="mission files to check")) -> None:
    """Check missions without running them; errors as file:line:col, exit status 1 if any."""
    from missions.check import check

    failed = False
    for path in missions:
        checked = check(path)
        _stderr([str(problem) for problem in checked.problems])
        failed |= not checked.ok
        if checked.ok:
            console.print(f"{path}: ok")
    if failed:
        raise typer.Exit(1)


@app.command()
def schema(
    builtin: bool = typer.Option(False, help="only the built-in skills (as missions/mission.schema.json has)"),
) -> None:
    """Print the JSON Schema of mission files (for editor completion)."""
    from missions.schema import json_schema
    from skills.registry import Registry

    registry = Registry.builtin() if builtin else Registry.default()
    sys.stdout.write(json.dumps(json_schema(registry), indent=2) + "\n")


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


@app.command()
def run(
    mission: Path = typer.Argument(DEFAULT_MISSION, help="mission YAML (default: the PeopleBot entertainer)"),
    backend: str = typer.Option(
        "sim",
        help="sim (the built-in simulator), emulator (the simulated robot through its emulated board) or hardware",
    ),
    port: str | None = typer.Option(None, help="with --backend hardware: the robot's serial port, e.g. /dev/ttyACM0"),
    seed: int | None = typer.Option(None, help="random seed (default: the mission's)"),
    until: float | None = typer.Option(None, help="stop after this many seconds of mission time"),
    realtime: bool = typer.Option(False, help="pace the simulation at wall-clock speed"),
    out: Path | None = typer.Option(None, help="run folder (default: runs/<mission>-<timestamp>/)"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no live display"),
) -> None:
    """Run a mission and write its run folder (trace.jsonl, summary.json, report.html)."""
    from missions.runner import MissionInvalid, RunError
    from missions.runner import run as run_mission

    try:
        if quiet or not console.is_terminal:
            result = run_mission(
                mission, backend=backend, seed=seed, until=until, realtime=realtime, out=out, port=port
            )
        else:
            with Live(console=console, refresh_per_second=8, transient=True) as live:
                result = run_mission(
                    mission,
                    backend=backend,
                    seed=seed,
                    until=until,
                    realtime=realtime,
                    out=out,
                    progress=_live_progress(live),
                    port=port,
                )
    except MissionInvalid as exc:
        raise _fail([str(p) for p in exc.problems]) from None
    except RunError as exc:
        raise _fail(f"error: {exc}", 2) from None
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
    if result.outcome == "interrupted":
        raise typer.Exit(130)


@app.command()
def order(
    table: str = typer.Argument(..., help="the table to serve, e.g. table_3"),
    item: str = typer.Argument(..., help="what to bring, e.g. 'tomato soup'"),
    run_folder: Path | None = typer.Option(None, "--run", help="the run folder (default: the newest running mission)"),
    runs: Path = typer.Option(Path("runs"), help="where to look for running missions"),
) -> None:
    """Give a running delivery mission an order (through its run folder's inbox; see the README)."""
    from missions.orders import find_inbox, post_order
    from skills.delivery.inbox import OrderError

    try:
        inbox = find_inbox(run_folder, runs)
        path = post_order(inbox, table, item)
    except OrderError as exc:
        raise _fail(f"error: {exc}", 2) from None
    except OSError as exc:
        raise _fail(f"error: cannot write the order: {exc}", 2) from None
    console.print(f"order for {table}: {' '.join(item.split())} -> {path}", highlight=False, soft_wrap=True)


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
    from behaviors.engine import Engine
    from behaviors.render import (
        MACHINE_FORMATS,
        TREE_FORMATS,
        GraphvizMissing,
        Statuses,
        describe,
        render,
        statuses_at,
    )
    from behaviors.trace import read_jsonl
    from missions.check import build_root, check, root_spec_path
    from robots.clock import SimClock

    formats = MACHINE_FORMATS if machine else TREE_FORMATS
    if fmt not in formats:
        raise _fail(f"error: unknown format {fmt!r}; use one of {', '.join(formats)}", 2)
    checked = check(mission)
    if not checked.ok:
        raise _fail([str(p) for p in checked.problems])
    spec = checked.mission
    assert spec is not None
    if machine and spec.machine is None:
        _stderr([f"note: {mission} has no machine; drawing the tree it runs"])
        spec_path: tuple[str, ...] = root_spec_path(spec)  # type: ignore[assignment]
    elif machine:
        spec_path = ("machine",)
    elif tree is not None:
        if tree not in spec.trees:
            known = ", ".join(spec.trees) or "none"
            raise _fail(f"error: {mission} has no tree {tree!r} (trees: {known})", 2)
        spec_path = ("trees", tree)
    else:
        spec_path = root_spec_path(spec)  # type: ignore[assignment]
    statuses = None
    if trace is not None:
        try:
            events = read_jsonl(trace)
        except (OSError, ValueError) as exc:
            raise _fail(f"error: cannot read trace {trace}: {exc}", 2) from None
        last = events[-1]["tick"] if events else 0
        statuses = statuses_at(events, last if at is None else at)
    if coverage is not None:
        from missions.coverage import untested_of

        try:
            untested, untested_transitions = untested_of(coverage, mission)
        except (OSError, ValueError, KeyError) as exc:
            raise _fail(f"error: cannot use coverage {coverage}: {str(exc).strip(chr(34))}", 2) from None
        statuses = statuses or Statuses()
        statuses.untested, statuses.untested_transitions = untested, untested_transitions
    engine = Engine(clock=SimClock(spec.rate_hz))
    try:
        root = build_root(engine.builder(spec.trees, spec.machines, spec.skill_params), spec, spec_path)
        try:
            data = render(describe(root), fmt, statuses)
        except GraphvizMissing as exc:
            raise _fail(f"error: {exc}", 2) from None
    finally:
        engine.close()
    if output is None:
        if fmt == "png":
            raise _fail("error: png is binary: give a file with -o", 2)
        sys.stdout.write(data.decode())
    else:
        output.write_bytes(data)


@app.command()
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


@app.command()
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


@app.command("test")
def test_scenarios(
    paths: list[Path] = typer.Argument(None, help="scenario files or folders (default: missions/scenarios)"),
    coverage: bool = typer.Option(False, "--coverage", help="print coverage per mission and write it"),
    coverage_file: Path = typer.Option(Path("coverage.json"), help="where --coverage writes its figures"),
) -> None:
    """Run scenario tests without pytest; a failure prints its readable report and keeps its run
    folder (the report names it). Exit 1 if any fails."""
    import shutil
    import tempfile

    from missions.scenario import load_scenario, run_scenario

    roots = paths or [Path("missions/scenarios")]
    files: list[Path] = []
    for root in roots:
        if root.is_dir():
            files += sorted(p for p in root.rglob("*.y*ml") if p.suffix in (".yaml", ".yml"))
        elif root.exists():
            files.append(root)
        else:
            raise _fail(f"error: {root} does not exist", 2)
    if not files:
        raise _fail(f"error: no scenario files under {', '.join(map(str, roots))}", 2)
    failed = 0
    from missions.coverage import Session

    session = Session()
    for path in files:
        folder = Path(tempfile.mkdtemp(prefix=f"botstage-{path.stem}-"))
        result = run_scenario(load_scenario(path), folder)
        session.add(result)
        if result.passed:
            shutil.rmtree(folder, ignore_errors=True)  # a failure's folder stays: its report names it
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
        from missions.coverage import write

        write(reports, coverage_file)
        console.print(f"coverage written to {coverage_file}", highlight=False, soft_wrap=True)
    console.print(f"{len(files) - failed} passed, {failed} failed", highlight=False)
    if failed:
        raise typer.Exit(1)


@scenario_app.command("from-trace")
def scenario_from_trace(
    trace: Path = typer.Argument(..., help="a recorded run's trace.jsonl (its summary.json beside it)"),
    output: Path = typer.Option(..., "-o", "--output", help="the scenario file to write"),
    mission: Path | None = typer.Option(None, help="the mission (default: the one summary.json names)"),
) -> None:
    """Turn a recorded run into a regression scenario that replays its skill outcomes."""
    from missions.scenario import from_trace

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
    _stderr([f"plugin {problem.entry_point}: {problem.reason}" for problem in registry.problems])


@app.command()
def chat(
    visitor: str = typer.Option("visitor", help="who you are: Maya remembers each visitor apart"),
    alice: bool = typer.Option(True, help="learn the A.L.I.C.E. set python-aiml ships (small talk)"),
    aiml: list[Path] = typer.Option([], help="more AIML files or folders, learnt last (repeatable)"),
    cache_dir: Path | None = typer.Option(None, help="brain cache folder (default: the user cache)"),
    seed: int | None = typer.Option(None, help="seed Maya's random choices (default: a new one each time)"),
) -> None:
    """Chat with Maya in the terminal: the converse skill's kernel and command routing.

    One line is one utterance; a robot command (PHOTO, YES, WHATSUP, CANCEL, CIAO, "take a
    picture"...) is shown as the event the mission would get. `/visitor NAME` lets another
    visitor speak (Maya remembers each apart). `quit` or end of input ends.
    """
    import random

    from rich.markup import escape

    from skills.chat.cache import load_brain
    from skills.chat.chatbot import Chatbot
    from skills.chat.persona import aiml_files

    brain = load_brain(aiml_files(alice, aiml), cache_dir)
    _stderr([str(problem) for problem in brain.problems] + [f"note: {note}" for note in brain.notes])
    if brain.trie.template_count == 0:
        raise _fail("error: no AIML category was learnt", 2)
    how = "loaded from the cache" if brain.origin == "cache" else "learnt and cached" if brain.path else "learnt"
    _stderr([f"Maya: {brain.trie.template_count:,} categories {how} in {brain.seconds:.2f} s"])
    maya = Chatbot(brain.trie, seed=seed if seed is not None else random.randrange(2**32))
    interactive = sys.stdin.isatty()
    while True:
        if interactive:
            sys.stdout.write(f"{visitor}> ")
            sys.stdout.flush()
        line = sys.stdin.readline()
        if not line:  # end of input
            break
        text = line.strip()
        if not text:
            continue
        if text.lower() in ("quit", "exit", "/quit"):
            break
        if text.startswith("/visitor"):
            visitor = text.removeprefix("/visitor").strip() or visitor
            console.print(f"({visitor} speaks now)", highlight=False, markup=False)
            continue
        turn = maya.turn(text, visitor)
        if turn.command is not None:
            console.print(f"[bold]-> {turn.command}[/] (command: the mission's `command` outcome)", highlight=False)
        else:
            console.print(f"[bold]Maya:[/] {escape(turn.reply)}", highlight=False, soft_wrap=True)


@app.command()
def gallery(
    host: str = typer.Option("127.0.0.1", help="address to listen on (loopback by default)"),
    port: int = typer.Option(8765, help="TCP port"),
    folder: Path = typer.Option(Path("gallery"), "--dir", help="where photos and the index are kept"),
    max_mb: float = typer.Option(20.0, help="largest photo accepted, MB (bigger: 413)"),
) -> None:
    """Serve the photo gallery the upload skill sends to: POST /photos, the page at /, JSON at /api/photos.

    With $BOTSTAGE_GALLERY_TOKEN set, uploads need `Authorization: Bearer <token>` (else 401).
    """
    import os

    from missions.gallery.server import is_loopback, serve
    from skills.outbox.settings import TOKEN_ENV

    token = os.environ.get(TOKEN_ENV) or None
    if not is_loopback(host) and token is None:
        _stderr([f"warning: serving on {host} without a token: anyone who can reach it can upload (set {TOKEN_ENV})"])
    if max_mb <= 0:
        raise _fail("error: --max-mb must be positive", 2)
    shown = f"[{host}]" if ":" in host else host
    _stderr(
        [
            f"gallery of {folder.resolve()} at http://{shown}:{port}/ (uploads: POST /photos"
            + (", token required)" if token else ")")
        ]
    )
    try:
        serve(folder, host, port, token=token, max_bytes=int(max_mb * 2**20))
    except OSError as exc:
        raise _fail(f"error: cannot serve on {host}:{port}: {exc.strerror or exc}", 2) from None


def _robot_place(profile_name: str, world: str, start: str):
    """A shipped or given profile, a map, and a start (a place of the map or "x,y,theta")."""
    from robots.gridmap import load as load_map
    from robots.interfaces import Pose2D
    from robots.profile import load_profile, profile_path
    from robots.sim.backend import map_path

    path = profile_path(profile_name)
    profile, problems, _ = load_profile(path) if path is not None else (None, [], None)
    if profile is None:
        raise _fail([str(p) for p in problems] or [f"error: unknown robot {profile_name!r}"], 2)
    where = map_path(world)
    if where is None:
        raise _fail(f"error: unknown world {world!r}", 2)
    grid = load_map(where)
    if start in grid.places:
        return profile, grid, Pose2D(*grid.places[start])
    try:
        x, y, theta = (float(part) for part in start.split(","))
    except ValueError:
        known = ", ".join(sorted(grid.places)) or "none"
        raise _fail(f"error: start {start!r} is neither a place of {world} ({known}) nor x,y,theta", 2) from None
    return profile, grid, Pose2D(x, y, theta)


@app.command()
def emulate(
    board: str = typer.Argument(..., help="the board to emulate: launchpad (Chefbot's Tiva C)"),
    world: str = typer.Option("restaurant", help="the map the simulated robot drives on"),
    start: str = typer.Option("dock", help="a place of the map, or x,y,theta"),
    seed: int = typer.Option(0, help="the simulated world's seed"),
    counter_start: int = typer.Option(0, help="the encoders' first count (near 2147483647 to test wrap-around)"),
) -> None:
    """Play a robot's board on a pseudo-terminal, driving the simulated robot; until Ctrl-C.

    Connect a driver (or `miniterm.py`) to the path it prints. Faults, typed on standard input:
    `garbage N`, `drop N`, `stall left|right|none`, `unplug SECONDS`, `reset`, `status`.
    """
    import threading

    if board != "launchpad":
        raise _fail(f"error: unknown board {board!r}; boards: launchpad", 2)
    from robots.emulators.launchpad import LaunchpadEmulator
    from robots.sim.world import World

    profile, grid, pose = _robot_place("chefbot", world, start)
    emulator = LaunchpadEmulator(World(grid, profile, pose, seed), counter_start=counter_start).start()
    console.print(
        f"Launchpad emulator: connect to {emulator.path} (now {emulator.pty_path}), 115200 8N1", highlight=False
    )
    console.print("Ctrl-C stops; faults: garbage N, drop N, stall left|right|none, unplug SECONDS, reset, status")
    stop = threading.Event()

    def faults() -> None:
        for line in sys.stdin:
            words = line.split()
            try:
                if words[:1] == ["garbage"]:
                    emulator.inject_garbage(int(words[1]))
                elif words[:1] == ["drop"]:
                    emulator.drop_lines(int(words[1]))
                elif words[:1] == ["stall"]:
                    emulator.stall(None if words[1] == "none" else words[1])
                elif words[:1] == ["unplug"]:
                    emulator.disconnect(float(words[1]))
                elif words[:1] == ["reset"]:
                    emulator.board_reset()
                elif words[:1] == ["status"]:
                    pose = emulator.world.body.pose
                    console.print(
                        f"pose {pose.x:.3f} {pose.y:.3f} {pose.theta:+.3f}  motors {emulator.speeds}  "
                        f"{dict(emulator.counters)}",
                        highlight=False,
                    )
                elif words:
                    console.print(f"unknown fault {words[0]!r}", highlight=False)
            except (IndexError, ValueError):
                console.print(f"cannot read {line.strip()!r}", highlight=False)
        stop.wait()  # end of input: keep running until Ctrl-C

    threading.Thread(target=faults, daemon=True).start()
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        emulator.close()


@app.command()
def teleop(
    robot: str = typer.Argument("chefbot", help="the robot's profile"),
    backend: str = typer.Option("sim", help="sim, emulator (the board emulated on a pty) or hardware"),
    port: str | None = typer.Option(None, help="with --backend hardware: the serial port, e.g. /dev/ttyACM0"),
    world: str = typer.Option("restaurant", help="the map (sim and emulator)"),
    start: str = typer.Option("dock", help="a place of the map, or x,y,theta"),
    seed: int = typer.Option(0, help="the simulated world's seed"),
    rate_hz: float = typer.Option(10.0, "--rate", help="commands a second"),
    linear_step: float = typer.Option(0.05, help="m/s a key adds"),
    angular_step: float = typer.Option(0.2, help="rad/s a key adds"),
) -> None:
    """Drive a robot with the keyboard, as the book's keyboard teleop: w/x a/d (or arrows), s stops, q quits."""
    from missions.teleop import HELP, StreamKeys, Teleop, TerminalKeys, run_teleop
    from robots.clock import WallClock

    if backend not in ("sim", "emulator", "hardware"):
        raise _fail(f"error: unknown backend {backend!r}: use sim, emulator or hardware", 2)
    if backend == "hardware" and not port:
        raise _fail("error: the hardware backend needs the robot's serial port: --port /dev/ttyACM0", 2)
    profile, grid, pose = _robot_place(robot, world, start)
    clock = WallClock(rate_hz)
    try:
        if backend == "sim":
            from robots.sim.backend import SimBackend

            robot_backend = SimBackend(profile, grid, pose, seed, clock)
        elif backend == "emulator":
            from robots.emulators.backend import EmulatorBackend

            robot_backend = EmulatorBackend(profile, grid, pose, seed, clock)
        else:
            from robots.drivers.backend import SerialBackend

            robot_backend = SerialBackend(profile, clock, port or "", pose)
    except (ValueError, ConnectionError) as exc:
        raise _fail(f"error: {exc}", 2) from None
    devices = robot_backend.devices
    if "drive" not in devices:
        robot_backend.close()
        raise _fail(f"error: robot {robot!r} has no drive", 2)
    state = Teleop(profile.base.max_linear, profile.base.max_angular, linear_step, angular_step)
    interactive = sys.stdin.isatty() and sys.stdout.isatty()

    def show(line: str) -> None:
        if interactive:
            sys.stdout.write("\r\x1b[K" + line)
            sys.stdout.flush()
        else:
            console.print(line, highlight=False)

    try:
        if interactive:
            with TerminalKeys.opened() as keys:
                console.print(HELP, highlight=False)  # once keys are read one by one: none typed is lost
                run_teleop(
                    devices["drive"],
                    keys,
                    clock,
                    state,
                    step=robot_backend.step,
                    odometry=devices.get("odometry"),
                    show=show,
                )
        else:
            console.print(HELP, highlight=False)
            run_teleop(
                devices["drive"],
                StreamKeys(sys.stdin),
                clock,
                state,
                step=robot_backend.step,
                odometry=devices.get("odometry"),
                show=show,
            )
    except KeyboardInterrupt:
        pass
    finally:
        robot_backend.close()
    if interactive:
        sys.stdout.write("\n")
    console.print("stopped", highlight=False)


def _load_bench(name: str) -> ModuleType:
    root = Path(__file__).resolve().parent.parent / "tests" / "bench"
    path = root / f"bench_{name}.py"
    if not path.exists():
        raise _fail(
            f"error: benchmark {name!r} not found at {path}: benchmarks live in the source checkout's "
            "tests/bench/ (install it with `pip install -e .`)",
            2,
        )
    checkout = str(root.parent.parent)
    if checkout not in sys.path:  # benchmarks use the tests' helpers (tests/navsim.py)
        sys.path.insert(0, checkout)
    spec = importlib.util.spec_from_file_location(f"botstage_bench_{name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@bench_app.command("tick")
def bench_tick(quick: bool = typer.Option(False, help="fewer repeats: a smoke run, not figures to quote")) -> None:
    """Engine tick cost vs plain py_trees, machine trigger cost vs raw transitions, 10,000 sim ticks."""
    results = _load_bench("tick").main(quick=quick)
    over = [r["bench"] for r in results if r.get("ratio", 0) > r.get("target", float("inf"))]
    if over and not quick:
        _stderr([f"over target: {', '.join(over)}"])


@bench_app.command("sim")
def bench_sim(quick: bool = typer.Option(False, help="a shorter run: a smoke test, not figures to quote")) -> None:
    """Simulation speed of the PeopleBot in the museum with 20 people and the laser at 10 Hz."""
    results = _load_bench("sim").main(quick=quick)
    slow = [r["bench"] for r in results if r["speedup_vs_realtime"] < r["target"]]
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("nav")
def bench_nav(quick: bool = typer.Option(False, help="fewer plans: a smoke test, not figures to quote")) -> None:
    """Planning time on a 1000 x 1000-cell map; final pose accuracy (the paper's Table 2); pose drift on a loop."""
    results = _load_bench("nav").main(quick=quick)
    slow = [r["bench"] for r in results if r.get("median_ms", 0) > r.get("target_ms", float("inf"))]
    if slow and not quick:
        _stderr([f"over target: {', '.join(slow)}"])


@bench_app.command("chat")
def bench_chat(quick: bool = typer.Option(False, help="fewer repeats: a smoke test, not figures to quote")) -> None:
    """Maya's brain: learning the AIML against loading the cached brain; reply latency; memory."""
    results = _load_bench("chat").main(quick=quick)
    slow = [r["bench"] for r in results if r.get("ratio", float("inf")) < r.get("target_ratio", 0)]
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("crowd")
def bench_crowd(quick: bool = typer.Option(False, help="fewer trials: a smoke test, not figures to quote")) -> None:
    """Crowd centre-of-mass error against the simulator's truth (the paper's figure); cost per frame."""
    results = _load_bench("crowd").main(quick=quick)
    over = [r["bench"] for r in results if r.get("median_ms", 0) > r.get("target_ms", float("inf"))]
    over += [r["bench"] for r in results if r.get("better_than_paper") is False]
    if over and not quick:
        _stderr([f"target missed: {', '.join(over)}"])


@bench_app.command("upload")
def bench_upload(quick: bool = typer.Option(False, help="fewer photos: a smoke test, not figures to quote")) -> None:
    """Photos through the durable outbox to the local gallery against a plain HTTP POST; the paper's 3.26 MB photo."""
    results = _load_bench("upload").main(quick=quick)
    slow = [r["bench"] for r in results if r.get("ratio", float("inf")) < r.get("target_ratio", 0)]
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("entertainer")
def bench_entertainer(quick: bool = typer.Option(False, help="one seed, 2 minutes: a smoke test")) -> None:
    """The default mission's wall time for 10 simulated minutes (target < 60 s), on several seeds."""
    results = _load_bench("entertainer").main(quick=quick)
    slow = [r for r in results if r.get("bench") == "entertainer_run" and r["target_ratio"] < 1.0]
    if slow and not quick:
        raise typer.Exit(1)


@bench_app.command("serial")
def bench_serial(quick: bool = typer.Option(False, help="smaller buffers, fewer commands: a smoke test")) -> None:
    """Chefbot's Launchpad link: lines parsed per second (parser alone and through a pty), command latency."""
    results = _load_bench("serial").main(quick=quick)
    missed = [r["bench"] for r in results if not r.get("meets_target", True)]
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("delivery")
def bench_delivery(quick: bool = typer.Option(False, help="one seed: a smoke test, not figures to quote")) -> None:
    """Chefbot's delivery mission: time per delivery; final pose error, odometry alone vs EKF vs map."""
    results = _load_bench("delivery").main(quick=quick)
    short = [r["seed"] for r in results if "seed" in r and r["failed"]]
    if short and not quick:
        _stderr([f"orders failed with seeds: {', '.join(map(str, short))}"])


@bench_app.command("speech")
def bench_speech(
    quick: bool = typer.Option(False, help="three voices, one speed, three conditions: a smoke test"),
    tune: bool = typer.Option(False, help="sweep the recogniser's thresholds on the tuning voices instead"),
) -> None:
    """Command recognition rate per word (clean, white and pink noise at 20 and 10 dB), false accepts, RTF."""
    results = _load_bench("speech").main(quick=quick, sweep=tune)
    if not results and not tune:
        raise typer.Exit(1)  # espeak-ng missing: said why
    missed = [
        name
        for r in results
        if r.get("bench") == "speech_commands"
        for name, c in r["conditions"].items()
        if (name.endswith("_10db") and c["overall"] < r["targets"]["overall_10db"])
        or c["false_accepts"] > r["targets"]["false_accepts"]
    ]
    if missed and not quick:
        _stderr([f"under target: {', '.join(missed)}"])


@speech_app.command("recognize")
def speech_recognize(
    files: list[Path] = typer.Argument(..., help="WAV files: 16 kHz mono 16-bit PCM"),
    mode: str = typer.Option("command", help="command (PHOTO, YES, WHATSUP, CANCEL, CIAO) or free (any English)"),
) -> None:
    """Print FILE<TAB>COMMAND per file (`-` when nothing was recognised); in free mode FILE<TAB>TEXT."""
    from skills.speech.recognizer import MODES, shared_recognizer
    from skills.speech.vad import find_utterances
    from skills.speech.wav import WavFormatError, read_wav

    if mode not in MODES:
        raise _fail(f"error: --mode must be one of {', '.join(MODES)}, got {mode!r}", 2)
    recognizer = shared_recognizer()
    failed = False
    for path in files:
        try:
            samples = read_wav(path)
        except (OSError, WavFormatError) as exc:
            _stderr([f"error: {exc}" if isinstance(exc, WavFormatError) else f"error: {path}: {exc.strerror or exc}"])
            failed = True
            continue
        found = "-"
        clipped = 0.0
        for utterance in find_utterances(samples):
            result = recognizer.recognize(utterance.samples, mode)
            clipped = max(clipped, result.clipped)
            if result.accepted:
                found = result.command if mode == "command" else result.text
                break
        if clipped >= 0.01:
            _stderr([f"warning: {path}: {clipped:.0%} of the speech is clipped (recorded too loud)"])
        sys.stdout.write(f"{path}\t{found}\n")
        sys.stdout.flush()
    if failed:
        raise typer.Exit(1)


def main() -> None:  # pragma: no cover - console script entry
    app()


if __name__ == "__main__":  # python -m missions.cli, from a checkout without the console script
    app()
