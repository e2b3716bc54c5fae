"""Check a mission before anything moves, and build it for the runner and the pictures.

A mission is checked from a file (``check``) or from memory (``check_loaded``: one built in
Python, whose locations point at the Python source). Every problem is reported at once as
``file:line:col: error: message (hint)``: YAML syntax, the mission's own keys, declared key
types, unknown skills, ports and types (from the engine's builder), states and transitions,
unreachable states, unhandled outcomes, blackboard keys read that nothing writes or
initialises, and ports bound to keys of another declared type.
"""

from __future__ import annotations

import contextlib
import difflib
import gc
import types
import typing
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import py_trees
from pydantic import ValidationError

from botstage.behaviors.blackboard import BlackboardError, normalise_key
from botstage.behaviors.builder import Builder, KeyUsage, SpecError, SpecPath
from botstage.behaviors.engine import Engine
from botstage.behaviors.kinds import NodeKinds
from botstage.behaviors.machine import MachinePlan
from botstage.behaviors.render import Item, describe
from botstage.missions.loader import Loaded, Location, Locations, Problem, load
from botstage.missions.schema import Mission, key_spec, parse_type
from botstage.robots.clock import SimClock
from botstage.robots.suggest import did_you_mean
from botstage.skills.base import check_type, plain_type, type_name
from botstage.skills.registry import Registry

if typing.TYPE_CHECKING:
    from botstage.robots.gridmap import GridMap
    from botstage.robots.profile import Profile


@dataclass
class Checked:
    path: Path
    loaded: Loaded
    mission: Mission | None
    problems: list[Problem]
    key_types: dict[str, Any] = field(default_factory=dict)
    key_defaults: dict[str, Any] = field(default_factory=dict)
    keys_used: set[str] = field(default_factory=set)  # read or written by what the mission runs
    # the skills what the mission runs calls, each with where its nodes are written (a deployment
    # checks each is served somewhere)
    skills_used: dict[str, list[Location]] = field(default_factory=dict)
    # what it was checked with: whatever builds it next (the run, its report, pictures) uses the same
    registry: Registry | None = None
    kinds: NodeKinds | None = None
    # what checking loaded, for the run to use rather than load again: the robot's profile (and
    # where its keys are written) and the world's map with its places
    profile: Profile | None = None
    profile_locations: Locations | None = None
    grid: GridMap | None = None
    # what runs, built on the engine the run gave (``check(engine_for=...)``): built once, here
    root: py_trees.behaviour.Behaviour | None = None
    picture: Item | None = None  # what it looks like, described before anything ticks

    @property
    def ok(self) -> bool:
        return not self.problems


class _Collector:
    def __init__(self, loaded: Loaded) -> None:
        self.loaded = loaded
        self.problems: list[Problem] = list(loaded.problems)

    def at(self, path: SpecPath, message: str, hint: str = "") -> None:
        self.problems.append(Problem(self.loaded.locations.find(path), message, hint))

    def result(self) -> list[Problem]:
        unique = {(p.location, p.message): p for p in self.problems}
        return sorted(unique.values(), key=lambda p: (p.location, p.message))


INTERNAL = "internal error while checking"


def check(
    path: str | Path,
    registry: Registry | None = None,
    kinds: NodeKinds | None = None,
    include_dirs: Iterable[str | Path] = (),
    engine_for: Callable[[Mission, Registry, NodeKinds], Engine] | None = None,
) -> Checked:
    """Load and check a mission file; never raises for a bad mission.

    ``include_dirs``: folders its includes may come from besides its own folder tree and the
    built-in library (see ``botstage.missions.loader.load``). A bug in the checker itself is reported as
    a located problem too (and asks to be reported), never as a traceback in the user's face.
    ``engine_for(mission, registry, kinds)``: the engine a run will tick; what runs is built on it and kept as
    ``Checked.root`` (else a throwaway engine checks it), so a run builds its tree once.
    """
    path = Path(path)
    return _safely(
        path,
        Location(str(path), 1, 1),
        lambda: _check(load(path, include_dirs), path, registry, kinds, engine_for),
    )


def check_loaded(
    loaded: Loaded,
    path: str | Path,
    registry: Registry | None = None,
    kinds: NodeKinds | None = None,
    engine_for: Callable[[Mission, Registry, NodeKinds], Engine] | None = None,
) -> Checked:
    """Check a mission already in memory, from any front end; never raises for a bad mission.

    ``path`` is where the mission comes from: it names a mission without a name, and relative
    robot and world paths are found beside it. Problems are located through ``loaded.locations``.
    ``engine_for``: as for ``check``.
    """
    path = Path(path)
    where = loaded.locations.root or Location(str(path), 1, 1)
    return _safely(path, where, lambda: _check(loaded, path, registry, kinds, engine_for))


def _safely(path: Path, where: Location, checking: Callable[[], Checked]) -> Checked:
    try:
        with _collection_paused():
            return checking()
    except Exception as exc:  # the safety net; the fuzz test asserts it is never needed
        problem = Problem(where, f"{INTERNAL}: {type(exc).__name__}: {exc}", "please report this with the file")
        return Checked(path, Loaded(None, Locations(root=where), [], [path]), None, [problem])


@contextlib.contextmanager
def _collection_paused() -> Iterator[None]:
    """Checking builds a graph of nodes that lives until it returns; the garbage collector,
    scanning it again and again as it grows, would cost a third of the check of a large mission."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _check(
    loaded: Loaded,
    path: Path,
    registry: Registry | None,
    kinds: NodeKinds | None,
    engine_for: Callable[[Mission, Registry, NodeKinds], Engine] | None = None,
) -> Checked:
    out = _Collector(loaded)
    if loaded.data is None:
        return Checked(path, loaded, None, out.result())
    mission = _validate_top_level(loaded.data, out)
    if not mission.name:
        mission = mission.model_copy(update={"name": path.stem})
    registry = registry or Registry.default()
    kinds = kinds or NodeKinds.default(mission.nodes)
    checked = Checked(path, loaded, mission, [], registry=registry, kinds=kinds)
    _check_keys(mission, checked, out)
    _check_robot(mission, path, registry, checked, out)
    params = _check_skill_params(mission, registry, out)
    run_engine = engine_for(mission, registry, kinds) if engine_for is not None and not out.problems else None
    engine = run_engine or _throwaway_engine(mission, registry, kinds)
    try:
        builder = engine.builder(mission.trees, mission.machines, params)
        root_path = _root_spec_path(mission, out)
        if root_path is not None:
            root = _build(builder, mission, root_path, out)
            _check_machines(builder.plans, out)
            _check_usages(builder.usages, mission, checked, out)
            checked.keys_used = {u.key for u in builder.usages}
            checked.skills_used = {
                name: [out.loaded.locations.find(p) for p in paths] for name, paths in builder.skills_used.items()
            }
            if run_engine is not None and root is not None:
                checked.root, checked.picture = root, describe(root)
    finally:
        if run_engine is None:
            engine.close()
    # every named tree and machine is checked on its own too, used or not: once (a chain of
    # a thousand subtrees is built once, not once from each of its links), on an engine of its
    # own (what does not run is not built on the run's)
    apart = _throwaway_engine(mission, registry, kinds)
    try:
        alone = apart.builder(mission.trees, mission.machines, params)
        built = set(builder.entered) | ({root_path} if root_path is not None else set())
        for section, names in (("trees", mission.trees), ("machines", mission.machines)):
            for name in names:
                if (section, name) not in built and (section, name) not in alone.entered:
                    _build(alone, mission, (section, name), out)
        _check_machines(alone.plans, out)
    finally:
        apart.close()
    checked.problems = out.result()
    return checked


def _throwaway_engine(mission: Mission, registry: Registry, kinds: NodeKinds) -> Engine:
    return Engine(clock=SimClock(mission.rate_hz), registry=registry, seed=mission.seed, kinds=kinds)


def _validate_top_level(data: dict[str, Any], out: _Collector) -> Mission:
    """Validate the mission's own keys; drop the bad ones so the rest can still be checked."""
    data = dict(data)
    for _ in range(len(data) + 1):
        try:
            return Mission.model_validate(data)
        except ValidationError as exc:
            dropped = False
            for error in exc.errors():
                loc = tuple(error["loc"])
                if error["type"] == "extra_forbidden":
                    key = str(loc[-1])
                    out.at(loc, f"unknown mission key {key!r}", did_you_mean(key, Mission.model_fields))
                else:
                    where = ".".join(str(p) for p in loc)
                    message = error["msg"].removeprefix("Value error, ")
                    out.at(loc, f"{where}: {message[:1].lower() + message[1:]}")
                if loc and loc[0] in data:
                    del data[loc[0]]
                    dropped = True
            if not dropped:
                break
    return Mission()


def _check_keys(mission: Mission, checked: Checked, out: _Collector) -> None:
    for key, raw in mission.keys.items():
        spec = key_spec(raw)
        try:
            rel = normalise_key(key)
        except BlackboardError as exc:
            out.at(("keys", key), str(exc))
            continue
        try:
            tp = parse_type(spec.type)
        except ValueError as exc:
            out.at(("keys", key) + (("type",) if not isinstance(raw, str) else ()), str(exc))
            continue
        checked.key_types[rel] = tp
        if spec.default is not None:
            try:
                checked.key_defaults[rel] = check_type(tp, spec.default)
            except TypeError as exc:
                out.at(("keys", key, "default"), f"default of {rel!r}: {exc}")
    for key, value in mission.blackboard.items():
        rel, declared, problem = check_write(key, value, checked.key_types)
        if rel is None:
            out.at(("blackboard", key), problem)
        elif problem:
            out.at(("blackboard", key), f"initial value of {rel!r} (declared {type_name(declared)}): {problem}")


def check_write(key: Any, value: Any, key_types: dict[str, Any]) -> tuple[str | None, Any, str]:
    """A write of ``value`` to ``key``, checked: (the relative key or None if malformed, its
    declared type or None, the problem or ''). Mission values and scenario writes both use it."""
    try:
        rel = normalise_key(key)
    except BlackboardError as exc:
        return None, None, str(exc)
    declared = key_types.get(rel)
    if declared is not None:
        try:
            check_type(declared, value)
        except TypeError as exc:
            return rel, declared, str(exc)
    return rel, declared, ""


def _check_robot(mission: Mission, path: Path, registry: Registry, checked: Checked, out: _Collector) -> None:
    from botstage.robots.profile import known_profiles, load_profile, profile_path

    if mission.robot is not None:
        found = profile_path(mission.robot, path.parent)
        if found is None:
            known = known_profiles()
            out.at(
                ("robot",),
                f"unknown robot {mission.robot!r}",
                did_you_mean(mission.robot, known) or "known: " + ", ".join(known),
            )
        else:
            profile, problems, loaded = load_profile(found)
            out.problems.extend(problems)
            checked.profile, checked.profile_locations = profile, loaded.locations
            if profile is not None:
                _check_backend_sections(profile, loaded.locations, out)
                for skill, params in profile.skills.items():
                    where = loaded.locations.find(("skills", skill))
                    if skill not in registry:
                        out.problems.append(Problem(where, f"unknown skill {skill!r}", did_you_mean(skill, registry)))
                        continue
                    try:
                        registry.get(skill).validate_params(params)
                    except ValidationError as exc:
                        first = exc.errors()[0]
                        out.problems.append(Problem(where, f"parameter of {skill!r}: {first['msg']}"))
    if mission.world is not None and mission.robot is None:
        out.at(("world",), "a world needs a robot to put in it")
    if mission.people and mission.world is None:
        out.at(("people",), "simulated people need a world to walk in")
    elif mission.walks and mission.world is None:
        out.at(("walks",), "walking people need a world to walk in")
    elif mission.world is not None:
        checked.grid = _check_world(mission, path, out)


def _check_backend_sections(profile: Profile, locations: Locations, out: _Collector) -> None:
    """A profile's backend sections (``ros2:``) are checked by their backend, found by name. A
    section whose backend is not installed is not read by anything here: the backend checks it
    when it is installed, and opening that backend says which set to install."""
    from botstage.robots.backend_registry import BackendRegistry

    for section in ("ros2",):
        if getattr(profile, section).model_dump(exclude_defaults=True) == {}:
            continue
        backends = BackendRegistry.default()
        if section not in backends:
            continue
        for where, message, hint in backends.get(section).check_profile(profile):
            out.problems.append(Problem(locations.find(where), message, hint))


def _check_world(mission: Mission, path: Path, out: _Collector) -> GridMap | None:
    """The world's problems; its map, if it loads."""
    from botstage.robots.gridmap import MapError, known_maps, load, map_path
    from botstage.robots.sim.scenery import check_scenery

    assert mission.world is not None
    found = map_path(mission.world, path.parent)
    if found is None:
        out.at(
            ("world",),
            f"unknown world {mission.world!r}",
            did_you_mean(mission.world, known_maps()) or "shipped maps: " + ", ".join(known_maps()),
        )
        return None
    try:
        grid = load(found)
    except MapError as exc:
        out.at(("world",), f"the map cannot be loaded: {exc}")
        return None
    for where, message, hint in check_scenery(mission.people, mission.gatherings, mission.walks, grid):
        out.at(where, message, hint)
    start = mission.start
    if start is None:
        if not grid.places:
            out.at(("world",), "say where the robot starts with `start:` (this map has no named places)")
        return grid
    if isinstance(start, str):
        if start not in grid.places:
            out.at(
                ("start",),
                f"the map has no place {start!r}",
                did_you_mean(start, grid.places) or "places: " + ", ".join(grid.places),
            )
    elif len(start) not in (2, 3):
        out.at(("start",), "a start pose is [x, y] or [x, y, yaw]")
    elif not grid.is_free(start[0], start[1]):
        out.at(("start",), f"({start[0]:g}, {start[1]:g}) is not free floor on the map")
    return grid


def start_pose(mission: Mission, places: dict[str, tuple[float, float, float]]) -> tuple[float, float, float]:
    """Where a valid mission's robot starts: its `start`, or the map's first named place."""
    if isinstance(mission.start, str):
        return places[mission.start]
    if isinstance(mission.start, list):
        x, y, *rest = mission.start
        return float(x), float(y), float(rest[0]) if rest else 0.0
    return next(iter(places.values()))


def _check_skill_params(mission: Mission, registry: Registry, out: _Collector) -> dict[str, dict[str, Any]]:
    valid = {}
    for name, params in mission.skill_params.items():
        if name not in registry:
            out.at(("skill_params", name), f"unknown skill {name!r}", did_you_mean(name, registry))
            continue
        try:
            registry.get(name).validate_params(params)
        except ValidationError as exc:
            for error in exc.errors():
                out.at(("skill_params", name, *error["loc"]), f"parameter of {name!r}: {error['msg']}")
            continue
        valid[name] = params
    return valid


def _root_spec_path(mission: Mission, out: _Collector) -> SpecPath | None:
    if mission.machine is not None:
        return ("machine",)
    if mission.root is not None:
        if mission.root not in mission.trees:
            out.at(("root",), f"unknown tree {mission.root!r}", did_you_mean(mission.root, mission.trees))
            return None
        return ("trees", mission.root)
    if "main" in mission.trees:
        return ("trees", "main")
    if len(mission.trees) == 1:
        return ("trees", next(iter(mission.trees)))
    if not mission.trees:
        out.at((), "a mission needs a `machine` or `trees` to run")
    else:
        out.at(
            ("trees",),
            "several trees and no machine: say which tree runs with `root: NAME`",
            f"trees: {', '.join(mission.trees)}",
        )
    return None


def root_spec_path(mission: Mission) -> SpecPath:
    """Which part of a valid mission runs: its machine, or its root tree."""
    if mission.machine is not None:
        return ("machine",)
    if mission.root is not None:
        return ("trees", mission.root)
    return ("trees", "main" if "main" in mission.trees else next(iter(mission.trees)))


def build_root(builder: Builder, mission: Mission, spec_path: SpecPath) -> py_trees.behaviour.Behaviour:
    if spec_path == ("machine",):
        return builder.machine(mission.machine, name=mission.name, spec_path=spec_path)
    if spec_path[0] == "machines":
        return builder.machine(mission.machines[spec_path[1]], name=str(spec_path[1]), spec_path=spec_path)
    return builder.named_tree(str(spec_path[1]))


def describe_part(checked: Checked, spec_path: SpecPath | None = None) -> Item:
    """What a valid mission runs (or its part at ``spec_path``) as pictures see it, built with the
    skills and node kinds it was checked with: the one path for `tree`, `machine`, the report,
    coverage and the Python API."""
    mission = checked.mission
    assert mission is not None and checked.ok
    engine = Engine(clock=SimClock(mission.rate_hz), registry=checked.registry, kinds=checked.kinds)
    try:
        builder = engine.builder(mission.trees, mission.machines, mission.skill_params)
        return describe(build_root(builder, mission, spec_path or root_spec_path(mission)))
    finally:
        engine.close()


def _build(
    builder: Builder, mission: Mission, spec_path: SpecPath, out: _Collector
) -> py_trees.behaviour.Behaviour | None:
    try:
        return build_root(builder, mission, spec_path)
    except SpecError as exc:
        for problem in exc.problems:
            out.at(problem.path, problem.message, problem.hint)
        return None


def _check_machines(plans: Iterable[MachinePlan], out: _Collector) -> None:
    for plan in plans:
        levels = [plan.level] + [i.level for i in plan.states.values() if i.level is not None]
        for level in levels:
            reachable = {level.initial}
            reachable |= {level.full(target) for _, target in level.preemptions}
            frontier = [level.initial]
            while frontier:
                info = plan.states[frontier.pop()]
                for targets in info.written.values():
                    for name, _guard in targets:
                        full = level.full(name)
                        if full not in reachable:
                            reachable.add(full)
                            frontier.append(full)
            for name in level.names:
                info = plan.states[level.full(name)]
                if info.path not in reachable:
                    out.at(info.spec_path, f"state {name!r} is unreachable: no transition or preemption leads to it")
                for outcome in sorted(info.possible - set(info.written)):
                    out.at(
                        info.spec_path,
                        f"state {name!r} can end with outcome {outcome!r} but has no transition for it",
                        f"add `{outcome}: <state or outcome>` to its transitions",
                    )


def _check_usages(usages: list[KeyUsage], mission: Mission, checked: Checked, out: _Collector) -> None:
    written = {u.key for u in usages if u.mode == "write"}
    initialised = set(checked.key_defaults)
    for key in mission.blackboard:
        with contextlib.suppress(BlackboardError):
            initialised.add(normalise_key(key))
    known = written | initialised | set(checked.key_types)
    for usage in usages:
        declared = checked.key_types.get(usage.key)
        if usage.mode == "read" and usage.key not in written and usage.key not in initialised:
            close = difflib.get_close_matches(usage.key, sorted(known), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}?" if close else "initialise it under `blackboard:`"
            out.at(
                usage.spec_path, f"blackboard key {usage.key!r} is read here but nothing writes or initialises it", hint
            )
        if declared is not None and not _compatible(declared, usage.type, usage.mode):
            port = "an input" if usage.mode == "read" else "an output"
            out.at(
                usage.spec_path,
                f"blackboard key {usage.key!r} is declared {type_name(declared)} but is bound to "
                f"{port} of type {type_name(usage.type)}",
            )


def _compatible(declared: Any, port: Any, mode: str) -> bool:
    """Can a value of one type flow into the other (reads: key -> port; writes: port -> key)?"""
    source, target = (declared, port) if mode == "read" else (port, declared)
    source, target = plain_type(source), plain_type(target)  # Seconds is a float
    if Any in (source, target) or source == target:
        return True
    if source is int and target is float:
        return True
    if typing.get_origin(source) in (typing.Union, types.UnionType):  # every member must fit
        return all(_compatible(member, target, "read") for member in typing.get_args(source))
    if typing.get_origin(target) in (typing.Union, types.UnionType):  # one member must take it
        return any(_compatible(source, member, "read") for member in typing.get_args(target))
    return getattr(source, "__origin__", source) is target  # list[float] into a plain list


__all__ = ["Checked", "Location", "build_root", "check", "check_loaded", "root_spec_path"]
