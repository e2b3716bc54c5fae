"""Run a checked mission on the engine and leave its run folder.

The folder holds ``trace.jsonl`` (streamed while the mission runs), ``summary.json``,
``report.html`` and ``transcript.jsonl`` when anyone spoke (all derived from the trace
afterwards), and the run's artefacts.
"""

from __future__ import annotations

import json
import signal
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status

from behaviors.engine import Engine
from behaviors.machine import MachineBehaviour, failure_reason
from behaviors.skill_behaviour import SkillBehaviour
from behaviors.trace import Trace, jsonable
from missions.check import Checked, build_root, check, root_spec_path, start_pose
from missions.gallery.service import fill_counters, run_uploads
from missions.loader import Problem
from missions.services import RobotServices
from missions.transcript import write_transcript
from robots.clock import Clock, SimClock, WallClock
from robots.gridmap import GridMap
from robots.gridmap import load as load_map
from robots.interfaces import Pose2D
from robots.profile import Profile, load_profile, profile_path
from robots.sim.backend import SimBackend, known_maps, map_path
from skills.delivery.inbox import OrderInbox
from skills.files import RunFiles
from skills.registry import Registry

if TYPE_CHECKING:  # the serial backends load pyserial and ptys only when a run asks for them
    from robots.drivers.backend import SerialBackend
    from robots.emulators.backend import EmulatorBackend

BACKENDS = ("sim", "emulator", "hardware")
WALL_CLOCK_FIELDS = ("wall_time_s", "overruns")


class MissionInvalid(Exception):
    def __init__(self, problems: list[Problem]) -> None:
        self.problems = problems
        super().__init__("\n".join(str(p) for p in problems))


class RunError(Exception):
    """The mission is valid but cannot run as asked (for example, no hardware for it)."""


class StopRun(Exception):
    """Raised by a ``before_tick`` hook to end a run early (a scenario's `never` condition held)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass
class RunResult:
    outcome: str
    reason: str
    folder: Path
    summary: dict[str, Any]
    blackboard: dict[str, Any] = field(default_factory=dict)


@dataclass
class Progress:
    """What the live display shows; built on demand, a few times a second at most."""

    mission: str
    sim_time_s: float
    wall_time_s: float
    ticks: int
    state: str
    running: list[str]


ProgressCallback = Callable[[Callable[[], Progress]], None]


def run(
    path: str | Path,
    *,
    backend: str = "sim",
    seed: int | None = None,
    until: float | None = None,
    realtime: bool = False,
    out: Path | None = None,
    progress: ProgressCallback | None = None,
    progress_interval_s: float = 0.1,
    registry: Registry | None = None,
    blackboard: dict[str, Any] | None = None,
    before_tick: Callable[[Engine], None] | None = None,
    port: str | None = None,
) -> RunResult:
    """Check and run a mission.

    Scenario tests pass a ``registry`` with mocks, ``blackboard`` overrides of initial values and
    a ``before_tick`` hook (scripted events, `never` conditions); a hook may raise ``StopRun``.
    The ``emulator`` and ``hardware`` backends run in real time: the first drives the simulated
    robot through its emulated board over a pty, the second the robot on ``port``.
    """
    checked = check(path, registry)
    if not checked.ok:
        raise MissionInvalid(checked.problems)
    mission = checked.mission
    assert mission is not None
    if backend not in BACKENDS:
        raise RunError(f"unknown backend {backend!r}: use sim, emulator or hardware")
    if backend != "sim" and mission.robot is None:
        raise RunError(
            f"mission {mission.name!r} names no robot: there is no hardware to drive "
            "(run it on the simulator: --backend sim)"
        )
    if backend == "hardware" and not port:
        raise RunError("the hardware backend needs the robot's serial port: --port /dev/ttyACM0")
    seed = mission.seed if seed is None else seed
    until = mission.until if until is None else until
    folder = run_folder(mission.name, out)
    clock: Clock = WallClock(mission.rate_hz) if realtime or backend != "sim" else SimClock(mission.rate_hz)
    started = time.perf_counter()
    interrupted = False
    stopped = ""
    with (folder / "trace.jsonl").open("w", encoding="utf-8") as sink:
        sim = _simulator(checked, seed, clock, backend, port)
        if sim is not None and backend != "sim":  # connecting took a while: mission time starts now
            clock = WallClock(mission.rate_hz)
            sim.use_clock(clock)
        services = RobotServices.for_robot(sim.devices, *_map_and_profile(sim), clock) if sim is not None else None
        # the upload skill's outboxes (and a gallery when none is configured): nothing opens unless used
        uploads = run_uploads(folder, clock, seed)
        devices = {**sim.devices, **services.interfaces} if sim is not None and services is not None else {}
        engine = Engine(
            clock=clock,
            seed=seed,
            trace=Trace(clock, sink, keep=False),
            registry=registry,
            interfaces={
                **devices,
                "uploads": uploads,
                "files": RunFiles(folder),
                "orders": OrderInbox(folder / "inbox"),
            },
        )
        try:
            root = build(engine, checked, blackboard)
            engine.set_root(root)
            snapshot = _progress_snapshot(engine, root, mission.name, started)
            try:
                with _sigterm_as_interrupt():
                    _loop(
                        engine,
                        until,
                        progress,
                        snapshot,
                        progress_interval_s,
                        before_tick,
                        _after_tick(
                            services.after_step(sim.step) if sim is not None and services is not None else None,
                            uploads.after_tick,
                        ),
                    )
            except KeyboardInterrupt:
                interrupted = True
                engine.halt("interrupted by the operator")
            except StopRun as stop:
                stopped = stop.reason
                engine.halt(stop.reason)
            outcome, reason = _outcome(engine, root, until, interrupted)
            if stopped:
                outcome, reason = "stopped_by_test", stopped
            final_blackboard = engine.blackboard.snapshot()
            counters = {key: jsonable(engine.blackboard.get(key, None)) for key in mission.counters}
        finally:
            engine.close("mission ended")  # cancels whatever still runs: motors stop
            if services is not None:
                services.close()
            uploads.close()  # uploads in flight get a few seconds; pending photos stay in the outbox
            if sim is not None:
                sim.close()
                sim.write_trajectory(folder / "trajectory.csv")
    upload_summary = uploads.summary() if uploads.used else None
    write_transcript(folder)
    summary = summarise(
        folder,
        mission=mission.name,
        robot=mission.robot,
        backend=backend,
        seed=seed,
        outcome=outcome,
        reason=reason,
        sim_time_s=round(clock.now(), 6),
        wall_time_s=round(time.perf_counter() - started, 3),
        ticks=clock.ticks,
        counters=counters,
        mission_file=str(Path(path).resolve()),
        until=until,
    )
    if blackboard:
        summary["blackboard_overrides"] = jsonable(blackboard)  # what a replay must set again
    if sim is not None:
        summary[backend] = sim.summary()
    if services is not None and services.localizer is not None:
        world = getattr(sim, "world", None)  # a real robot's true pose is unknown
        summary["localization"] = services.summary(world.body.pose if world is not None else None)
    if upload_summary is not None:
        summary["upload"] = upload_summary
        fill_counters(summary["counters"], upload_summary)
    if isinstance(clock, WallClock):
        summary["overruns"] = {"count": clock.overruns.count, "worst_s": round(clock.overruns.worst_s, 4)}
    from missions.report import write_report  # matplotlib and friends load only when reporting

    summary["artefacts"] = sorted({*summary["artefacts"], "report.html"})
    write_report(folder, checked, summary)
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return RunResult(outcome, reason, folder, summary, final_blackboard)


def _simulator(
    checked: Checked, seed: int, clock: Clock, backend: str = "sim", port: str | None = None
) -> SimBackend | EmulatorBackend | SerialBackend | None:
    """The robot of a mission with a robot and a world (simulated, emulated or real); None for
    robot-less missions."""
    mission = checked.mission
    assert mission is not None
    if mission.robot is None:
        return None
    if mission.world is None:
        raise RunError(
            f"mission {mission.name!r} names robot {mission.robot!r} but no world: the simulator needs "
            f"one (`world:` a shipped map: {', '.join(known_maps())}, or a map YAML)"
        )
    profile, _, _ = load_profile(profile_path(mission.robot, checked.path.parent))  # type: ignore[arg-type]
    grid = load_map(map_path(mission.world, checked.path.parent))  # type: ignore[arg-type]
    assert profile is not None
    x, y, theta = start_pose(mission, grid.places)
    try:
        if backend == "emulator":
            from robots.emulators.backend import EmulatorBackend

            return EmulatorBackend(profile, grid, Pose2D(x, y, theta), seed, clock, people=mission.people)
        if backend == "hardware":
            from robots.drivers.backend import SerialBackend

            return SerialBackend(profile, clock, port or "", Pose2D(x, y, theta), grid=grid)
        gatherings = [
            (g.time, tuple(grid.places[g.at][:2]) if isinstance(g.at, str) else (g.at[0], g.at[1]), g.size, g.stay)
            for g in mission.gatherings
        ]
        return SimBackend(
            profile,
            grid,
            Pose2D(x, y, theta),
            seed,
            clock,
            people=mission.people,
            gatherings=gatherings,
            voices=mission.voices.model_dump(),
        )
    except (ValueError, ConnectionError) as exc:
        raise RunError(str(exc)) from None


def _map_and_profile(backend: SimBackend | EmulatorBackend | SerialBackend) -> tuple[GridMap, Profile]:
    world = getattr(backend, "world", None)
    if world is not None:
        return world.grid, world.profile
    return backend.grid, backend.profile  # type: ignore[union-attr]


def build(engine: Engine, checked: Checked, overrides: dict[str, Any] | None = None) -> py_trees.behaviour.Behaviour:
    """Declare the mission's keys, set its initial values and build what runs."""
    mission = checked.mission
    assert mission is not None
    for key, tp in checked.key_types.items():
        engine.blackboard.declare(key, tp)
    for key, value in checked.key_defaults.items():
        engine.blackboard.set(key, value, writer="init")
    for key, value in {**mission.blackboard, **(overrides or {})}.items():
        engine.blackboard.set(key, value, writer="init")
    builder = engine.builder(mission.trees, mission.machines, mission.skill_params)
    return build_root(builder, mission, root_spec_path(mission))


def run_folder(name: str, out: Path | None) -> Path:
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        return out
    base = Path("runs") / f"{name}-{datetime.now().strftime('%Y%m%d-%H%M%S')}"
    folder, n = base, 1
    while folder.exists():
        n += 1
        folder = base.with_name(f"{base.name}-{n}")
    folder.mkdir(parents=True)
    return folder


def _after_tick(*hooks: Callable[[], None] | None) -> Callable[[], None] | None:
    """The hooks that run after each tick, in order (the world moves first, then uploads settle)."""
    present = [hook for hook in hooks if hook is not None]

    def after() -> None:
        for hook in present:
            hook()

    return after if present else None


def _loop(
    engine: Engine,
    until: float | None,
    progress: ProgressCallback | None,
    snapshot: Callable[[], Progress],
    interval_s: float,
    before_tick: Callable[[Engine], None] | None = None,
    after_tick: Callable[[], None] | None = None,
) -> None:
    clock = engine.clock
    next_report = 0.0
    while until is None or clock.now() < until - 1e-9:
        if before_tick is not None:
            before_tick(engine)
        status = engine.tick()
        if after_tick is not None:
            after_tick()  # the world moves over the tick just decided
        if progress is not None:
            now = time.monotonic()
            if now >= next_report:
                next_report = now + interval_s
                progress(snapshot)
        if status in (Status.SUCCESS, Status.FAILURE):
            break
    if progress is not None:
        progress(snapshot)


def _outcome(
    engine: Engine, root: py_trees.behaviour.Behaviour, until: float | None, interrupted: bool
) -> tuple[str, str]:
    if interrupted:
        return "interrupted", "interrupted by the operator"
    if engine.error is not None:
        return "error", engine.error
    outcome = getattr(root, "outcome", None)
    if outcome is not None:
        return outcome.name, outcome.reason
    if root.status in (Status.SUCCESS, Status.FAILURE):
        # a root tree that ended with the machine it runs beside its helpers (a display, a
        # battery watch) reports that machine's outcome: `docked` says more than `success`
        ended = [c.outcome for c in root.children if isinstance(c, MachineBehaviour) and c.outcome is not None]
        if len(ended) == 1:
            return ended[0].name, ended[0].reason
    if root.status is Status.SUCCESS:
        return "success", ""
    if root.status is Status.FAILURE:
        return "failure", failure_reason(root)
    return "time_limit", f"the time limit of {until:g} s of mission time was reached"


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM stops a run as cleanly as Ctrl-C does (skills cancelled, motors stopped)."""

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _progress_snapshot(
    engine: Engine, root: py_trees.behaviour.Behaviour, name: str, started: float
) -> Callable[[], Progress]:
    def snapshot() -> Progress:
        state = root.state if isinstance(root, MachineBehaviour) else ""
        return Progress(
            name, engine.clock.now(), time.perf_counter() - started, engine.clock.ticks, state, running_skills(root)
        )

    return snapshot


def running_skills(node: py_trees.behaviour.Behaviour) -> list[str]:
    """Paths of the skills running now, looking inside machine states too."""
    found: list[str] = []
    stack = [node]
    while stack:
        current = stack.pop()
        if current.status is not Status.RUNNING:
            continue
        if isinstance(current, SkillBehaviour):
            found.append(current.path)
        elif isinstance(current, MachineBehaviour):
            content = current.plan.states.get(current.model.state)
            if content is not None and content.content is not None:
                stack.append(content.content)
        else:
            stack.extend(reversed(current.children))
    return found


def summarise(folder: Path, **fields: Any) -> dict[str, Any]:
    """summary.json's content, from the trace the run left behind."""
    states_visited: list[str] = []
    skill_outcomes: dict[str, Counter[str]] = defaultdict(Counter)
    root_machine = fields["mission"]
    with (folder / "trace.jsonl").open(encoding="utf-8") as trace:
        for line in trace:
            event = json.loads(line)
            kind = event["ev"]
            if kind == "transition" and event["dest"]:
                machine = event["machine"]
                states_visited.append(event["dest"] if machine == root_machine else f"{machine}/{event['dest']}")
            elif kind == "skill_outcome":
                skill_outcomes[event["skill"]][event["outcome"]] += 1
            elif kind == "skill_cancel":
                skill_outcomes[event["skill"]]["cancelled"] += 1
    artefacts = sorted(
        str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and p.name != "summary.json"
    )
    return {
        **{
            k: fields[k]
            for k in ("mission", "robot", "backend", "seed", "outcome", "reason", "sim_time_s", "wall_time_s", "ticks")
        },
        "mission_file": fields["mission_file"],  # what `botstage scenario from-trace` replays against
        "until": fields["until"],
        "states_visited": states_visited,
        "skill_outcomes": {skill: dict(sorted(c.items())) for skill, c in sorted(skill_outcomes.items())},
        "counters": fields["counters"],
        "artefacts": artefacts,
    }
