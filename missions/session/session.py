"""A run of a mission, as a session with explicit phases.

``check`` (the mission, the backend's name and options: before anything moves) -> ``open_backend``
(the run folder, the clock, the robot) -> ``open_services`` (uploads, files, orders, localisation:
the interfaces skills get beyond the devices) -> ``build`` (the engine and what the mission runs)
-> ``loop`` (tick, step the world, after-tick work, until the mission ends, its time is up or
someone stops it) -> ``shut_down`` (skills cancelled, services closed, the robot stopped) ->
``write_results`` (every observer's ``finished``: summary, backend results, transcript, report).

What consumes the run (summary, transcript, report, a live display, plugins) is an observer
(``missions/session/observer.py``); what a run provides to skills is a service
(``missions/session/service.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import IO, Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.engine import Engine
from botstage.behaviors.kinds import NodeKinds
from botstage.behaviors.render import describe
from botstage.behaviors.trace import Trace, jsonable
from botstage.missions.check import Checked, build_root, check, check_loaded, root_spec_path, start_pose
from botstage.missions.loader import Loaded
from botstage.missions.schema import Mission
from botstage.missions.session.ending import SigtermLatch, outcome
from botstage.missions.session.errors import MissionInvalid, RunError, StopRun
from botstage.missions.session.observer import Hooks
from botstage.missions.session.observers import (
    BackendObserver,
    BeforeTickHook,
    ClockObserver,
    ReportObserver,
    TranscriptObserver,
)
from botstage.missions.session.plugins import PluginError, PluginRegistry, service_registry
from botstage.missions.session.result import RunResult
from botstage.missions.session.summary import SummaryFileObserver, SummaryObserver
from botstage.robots.backend import Backend, BackendError, BackendKind, BackendOptions, OpenRequest, ScriptedWalk
from botstage.robots.backend_options import OptionSources, resolve
from botstage.robots.backend_registry import DEFAULT, BackendRegistry, open_kind
from botstage.robots.clock import Clock, SimClock, WallClock
from botstage.robots.gridmap import GridMap, known_maps
from botstage.robots.interfaces import Pose2D
from botstage.robots.located_yaml import Locations, Problem
from botstage.robots.profile import Profile
from botstage.robots.suggest import did_you_mean
from botstage.skills.registry import Registry

DONE = (Status.SUCCESS, Status.FAILURE)


class RunSession:
    """One run of one mission; ``run()`` goes through the phases in order and returns the result."""

    def __init__(
        self,
        path: str | Path,
        *,
        backend: str = DEFAULT,
        seed: int | None = None,
        until: float | None = None,
        realtime: bool = False,
        out: Path | None = None,
        registry: Registry | None = None,
        kinds: NodeKinds | None = None,
        blackboard: dict[str, Any] | None = None,
        before_tick: Callable[[Engine], None] | None = None,
        backend_options: Mapping[str, Any] | None = None,
        port: str | None = None,
        observers: Sequence[object] = (),
        backends: BackendRegistry | None = None,
        services: PluginRegistry | None = None,
        loaded: Loaded | None = None,
        record: Callable[[Path], Path] | None = None,
    ) -> None:
        """``path``: the mission file; or, with ``loaded`` (a mission in memory: the Python API's,
        a file's with values set on the command line), where that mission comes from, and
        ``record(run_folder)`` keeps it in the run folder for replays, returning the file it wrote
        (the summary names it). Either way the mission is checked once and run as checked."""
        self.path = Path(path)
        self.loaded = loaded
        self.record = record
        self.mission_file = self.path
        self.backend_name = backend
        self.realtime = realtime
        self.out = out
        self._sigterm = SigtermLatch()  # SIGTERM ends the run cleanly from the moment it opens anything
        self.registry = registry
        self.kinds = kinds
        self.overrides = blackboard
        self.given = OptionSources(backend_options or {}, port=port)
        self.backends = backends if backends is not None else BackendRegistry.default()
        services = services if services is not None else service_registry()
        try:
            self.services = [services.create(name) for name in services]
        except PluginError as exc:
            raise RunError(str(exc)) from exc
        builtin = [services.origin(name) == "builtin" for name in services]
        self.hooks = self._hooks(before_tick, observers, builtin)
        self._seed, self._until = seed, until
        # set by the phases, in order
        self.checked: Checked
        self.kind: BackendKind
        self.options: BackendOptions
        self.seed: int
        self.until: float | None
        self.folder: Path
        self.clock: Clock
        self.started_at = time.perf_counter()
        self.backend: Backend | None = None
        self.interfaces: dict[str, Any] = {}
        self.trace: Trace | None = None
        self.engine: Engine | None = None
        self.root: py_trees.behaviour.Behaviour | None = None
        self.status = Status.INVALID
        self.outcome, self.reason = "", ""
        self.counters: dict[str, Any] = {}
        self.final_blackboard: dict[str, Any] = {}
        self._robot: tuple[Profile, Locations, GridMap, Pose2D] | None = None
        self._sink: IO[str] | None = None
        self._opened: list[Any] = []

    def _hooks(
        self, before_tick: Callable[[Engine], None] | None, observers: Sequence[object], builtin: list[bool]
    ) -> Hooks:
        """Every hook in the order the run needs: results first (the summary's core, then blocks),
        external observers before the report (so it shows their blocks), summary.json last."""
        hooks = Hooks()
        if before_tick is not None:
            hooks.add(BeforeTickHook(before_tick))
        hooks.add(SummaryObserver())
        hooks.add(BackendObserver())
        for service, ours in zip(self.services, builtin, strict=True):
            hooks.add(service, guarded=not ours)
        hooks.add(ClockObserver())
        hooks.add(TranscriptObserver())
        for observer in observers:
            hooks.add(observer, guarded=True)
        hooks.add(ReportObserver())
        hooks.add(SummaryFileObserver())
        return hooks

    @property
    def mission(self) -> Mission:
        """The checked mission."""
        assert self.checked.mission is not None
        return self.checked.mission

    @property
    def observer_errors(self) -> list[str]:
        return self.hooks.errors

    @property
    def ending(self) -> bool:
        """True after the run's last tick (the mission ended or its time is up)."""
        if self.status in DONE:
            return True
        return self.until is not None and self.clock.now() >= self.until - 1e-9

    # -- the phases ---------------------------------------------------------------------------

    def run(self) -> RunResult:
        self.check()
        with self._sigterm.installed():
            self.open_backend()
            try:
                self.open_services()
                self.build()
                self.loop()
            finally:
                self.shut_down()
        return self.write_results()

    def check(self) -> None:
        """The mission, the backend and its options: every refusal comes before anything moves.
        What runs is built here, once, on the engine the run ticks (``_engine_for``)."""
        try:
            self.kind = self.backends.get(self.backend_name)
        except BackendError as exc:
            raise RunError(exc.message) from None
        if self.loaded is not None:
            checked = check_loaded(self.loaded, self.path, self.registry, self.kinds, engine_for=self._engine_for)
        else:
            checked = check(self.path, self.registry, self.kinds, engine_for=self._engine_for)
        if not checked.ok:
            if self.engine is not None:
                self.engine.close()
                self.engine = None
            raise MissionInvalid(checked.problems)
        self.checked = checked
        mission = self.mission
        if not self.kind.simulated and mission.robot is None:
            raise RunError(
                f"mission {mission.name!r} names no robot: there is no hardware to drive "
                f"(run it on the simulator: --backend {DEFAULT})"
            )
        self._robot = self._place_robot()
        profile, locations = (self._robot[0], self._robot[1]) if self._robot is not None else (None, None)
        if profile is not None and locations is not None:
            self._check_profile_backends(profile, locations)
        try:
            self.options = resolve(self.kind, profile, locations, self.given)
        except BackendError as exc:
            raise RunError(exc.message, exc.problems) from None

    def _engine_for(self, mission: Mission, registry: Registry, kinds: NodeKinds) -> Engine:
        """The engine this run ticks, made as soon as the mission's rate and seed are known: its
        clock (simulated, or the wall's, which starts again once the robot is open), its seed,
        and the interfaces dict the services fill later. Its trace is attached in ``build``."""
        self.seed = mission.seed if self._seed is None else self._seed
        self.until = mission.until if self._until is None else self._until
        rate = mission.rate_hz
        self.clock = WallClock(rate) if self.realtime or not self.kind.simulated else SimClock(rate)
        self.engine = Engine(
            clock=self.clock,
            seed=self.seed,
            registry=registry,
            kinds=kinds,
        )
        self.engine.interfaces = self.interfaces
        return self.engine

    def _check_profile_backends(self, profile: Profile, locations: Locations) -> None:
        """The profile's `backends:` sections name installed backends: a misspelt one would be ignored."""
        installed = list(self.backends)
        unknown = [
            Problem(locations.find(("backends", name)), f"unknown backend {name!r}", did_you_mean(name, installed))
            for name in profile.backends
            if name not in installed
        ]
        if unknown:
            listed = ", ".join(installed)
            raise RunError(f"the robot profile configures backends not installed here (installed: {listed})", unknown)

    def _place_robot(self) -> tuple[Profile, Locations, GridMap, Pose2D] | None:
        """The mission's robot, map and start; None for a robot-less mission."""
        mission = self.mission
        if mission.robot is None:
            return None
        if mission.world is None:
            raise RunError(
                f"mission {mission.name!r} names robot {mission.robot!r} but no world: the simulator needs "
                f"one (`world:` a shipped map: {', '.join(known_maps())}, or a map YAML)"
            )
        profile, locations, grid = self.checked.profile, self.checked.profile_locations, self.checked.grid
        assert profile is not None and locations is not None and grid is not None  # a valid mission's
        x, y, theta = start_pose(mission, grid.places)
        return profile, locations, grid, Pose2D(x, y, theta)

    def open_backend(self) -> None:
        """The run folder; then the robot, if the mission has one. Mission time starts after."""
        self.folder = run_folder(self.mission.name, self.out)
        if self.record is not None:
            self.mission_file = self.record(self.folder)
        self.started_at = time.perf_counter()
        self._sink = (self.folder / "trace.jsonl").open("w", encoding="utf-8")
        # a real robot connects on a clock of its own: the run's starts when it is open
        connecting = self.clock if self.kind.simulated else WallClock(self.mission.rate_hz)
        if self._robot is not None:
            try:
                self.backend = open_kind(self.kind, self._request(connecting), self.options)
            except BackendError as exc:
                self._sink.close()
                raise RunError(exc.message, exc.problems) from None
        if not self.kind.simulated and not isinstance(self.clock, WallClock):
            self._rebuild_on(WallClock(self.mission.rate_hz))  # it said only once open: real time
        if isinstance(self.clock, WallClock):  # connecting took a while: mission time starts now
            self.clock.restart()
        if self.backend is not None and connecting is not self.clock:
            self.backend.use_clock(self.clock)  # what arrived while connecting, rebased

    def _rebuild_on(self, clock: Clock) -> None:
        """What runs, built again on ``clock``: only for a backend that says whether it runs in
        real time once it is open (a robot another process serves, on its board or simulated)."""
        assert self.engine is not None
        self.engine.close()
        self.clock = clock
        self.engine = Engine(clock=clock, seed=self.seed, registry=self.checked.registry, kinds=self.checked.kinds)
        self.engine.interfaces = self.interfaces
        mission = self.mission
        builder = self.engine.builder(mission.trees, mission.machines, mission.skill_params)
        self.checked.root = build_root(builder, mission, root_spec_path(mission))
        self.checked.picture = describe(self.checked.root)

    def robot_request(self, clock: Clock) -> OpenRequest | None:
        """What opening the mission's robot takes, on ``clock``: for a robot served by another
        process (``missions/distributed``), which opens it as this run would. After ``check``."""
        if self._robot is None:
            return None
        self.clock = clock
        return self._request()

    def _request(self, clock: Clock | None = None) -> OpenRequest:
        assert self._robot is not None
        mission = self.mission
        profile, _, grid, start = self._robot
        gatherings = tuple(
            (g.time, tuple(grid.places[g.at][:2]) if isinstance(g.at, str) else (g.at[0], g.at[1]), g.size, g.stay)
            for g in mission.gatherings
        )
        walks = tuple(
            ScriptedWalk(
                tuple(_point(grid, point) for point in w.path), speed=w.speed, at=w.at, repeat=w.repeat, pause=w.pause
            )
            for w in mission.walks
        )
        return OpenRequest(
            profile,
            start,
            clock or self.clock,
            seed=self.seed,
            grid=grid,
            people=mission.people,
            gatherings=gatherings,
            walks=walks,
            voices=mission.voices.model_dump(),
        )

    def open_services(self) -> None:
        """The interfaces skills get: the backend's devices, then each service's, in order."""
        self.interfaces.clear()  # the engine's own dict: what runs was built holding it
        if self.backend is not None:
            self.interfaces.update(self.backend.devices)
        for service in self.services:
            try:
                given = service.open(self)
            except RunError:
                raise
            except Exception as exc:  # a plugin's bug or a missing resource: said as a run error
                name = getattr(service, "name", "") or type(service).__name__
                raise RunError(f"service {name!r} cannot open: {type(exc).__name__}: {exc}") from exc
            self._opened.append(service)
            self.interfaces.update(given)

    def build(self) -> None:
        """The trace (observers subscribed) on the engine, the mission's keys and initial values;
        what runs was built when the mission was checked, on this engine."""
        assert self.engine is not None and self.checked.root is not None
        self.trace = Trace(self.clock, self._sink, keep=False)
        self.hooks.subscribe(self.trace)
        self.engine.trace = self.engine.blackboard.trace = self.trace
        initialise(self.engine, self.checked, self.overrides)
        self.root = self.checked.root
        self.engine.set_root(self.root)
        self.hooks.run("started", self)

    def loop(self) -> None:
        """Tick until the mission ends, its time is up, the operator stops it or a hook raises StopRun."""
        engine, clock, until = self.engine, self.clock, self.until
        assert engine is not None and self.root is not None
        interrupted, stopped = False, ""
        try:
            self._sigterm.arm()
            while until is None or clock.now() < until - 1e-9:
                self.hooks.run("before_tick", self)
                self.status = engine.tick()
                try:
                    if self.backend is not None:
                        self.backend.step()  # the world moves over the tick just decided
                    self.hooks.run("after_tick", self)  # then estimates update, uploads settle, displays
                except (StopRun, KeyboardInterrupt):
                    raise
                except Exception as exc:  # a robot that stopped reporting, a lost peer: the run ends, said
                    engine.error = f"after tick {clock.ticks}: {type(exc).__name__}: {exc}"
                    engine.trace.emit("error", engine.error)
                    engine.halt(f"engine error: {engine.error}")
                    self.status = Status.FAILURE
                    break
                if self.status in DONE:
                    break
        except KeyboardInterrupt:
            interrupted = True
            engine.halt("interrupted by the operator")
        except StopRun as stop:
            stopped = stop.reason
            engine.halt(stop.reason)
        finally:
            self._sigterm.armed = False  # shutting down: a second SIGTERM must not cut the cleanup short
        self.outcome, self.reason = outcome(engine.error, self.root, until, interrupted)
        if stopped:
            self.outcome, self.reason = "stopped_by_test", stopped
        self.final_blackboard = engine.blackboard.snapshot()
        self.counters = {key: jsonable(engine.blackboard.get(key, None)) for key in self.mission.counters}

    def step_world(self) -> None:
        """A tick's worth of the world without ticking the tree (an operator drives the robot while
        the run is held): the clock moves on, the world steps, and the run's services update (the
        localiser follows the robot)."""
        self.clock.next_tick()
        if self.backend is not None:
            self.backend.step()
        for service in self._opened:
            update = getattr(service, "after_tick", None)
            if callable(update):
                update(self)

    def shut_down(self) -> None:
        """Skills cancelled (motors stop), services closed, the robot stopped and released, the
        trace closed: each step runs even if one before it failed."""
        steps: list[Callable[[], Any]] = []
        if self.engine is not None:
            engine = self.engine
            steps.append(lambda: engine.close("mission ended"))
        steps += [service.close for service in self._opened]
        if self.backend is not None:
            steps.append(self.backend.close)
        if self._sink is not None:
            steps.append(self._sink.close)
        failed: BaseException | None = None
        for step in steps:
            try:
                step()
            except Exception as exc:
                failed = failed or exc
        if failed is not None:
            raise failed

    def write_results(self) -> RunResult:
        """Every observer's ``finished``, in order; the last one writes summary.json."""
        ended = {Status.SUCCESS: True, Status.FAILURE: False}.get(self.status)
        result = RunResult(self.outcome, self.reason, self.folder, {}, self.final_blackboard, ended)
        self.hooks.run("finished", self, result)
        return result


def _point(grid: GridMap, point: str | list[float]) -> tuple[float, float]:
    """A walk's point: a named place of the map, or [x, y] (checked before the run)."""
    if isinstance(point, str):
        x, y = grid.places[point][:2]
        return float(x), float(y)
    return float(point[0]), float(point[1])


def build(engine: Engine, checked: Checked, overrides: dict[str, Any] | None = None) -> py_trees.behaviour.Behaviour:
    """Declare the mission's keys, set its initial values and build what runs (for a caller that
    checked the mission on a throwaway engine; a run builds on its own once, when checking)."""
    mission = checked.mission
    assert mission is not None
    initialise(engine, checked, overrides)
    builder = engine.builder(mission.trees, mission.machines, mission.skill_params)
    return build_root(builder, mission, root_spec_path(mission))


def initialise(engine: Engine, checked: Checked, overrides: dict[str, Any] | None = None) -> None:
    """Declare the mission's keys and set their initial values (the trace's first events)."""
    mission = checked.mission
    assert mission is not None
    for key, tp in checked.key_types.items():
        engine.blackboard.declare(key, tp)
    for key, value in checked.key_defaults.items():
        engine.blackboard.set(key, value, writer="init")
    for key, value in {**mission.blackboard, **(overrides or {})}.items():
        engine.blackboard.set(key, value, writer="init")


def run_folder(name: str, out: Path | None) -> Path:
    """``out``, or a new ``runs/<mission>-<timestamp>`` folder."""
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
