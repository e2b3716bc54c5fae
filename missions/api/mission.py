"""A mission as a Python object: built in Python or loaded from YAML, then checked, drawn and run.

``to_dict()`` is exactly the data the YAML front end loads (so the engine cannot tell the two
apart) and ``to_yaml()`` the file a user could save. Checking uses the same checker as files do,
with locations pointing at the Python lines that built each part.
"""

from __future__ import annotations

import copy
import importlib
import importlib.util
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from botstage.missions.api.lowering import Lowering, Part, in_order
from botstage.missions.api.machine import StateMachine
from botstage.missions.api.nodes import NodeLike, as_node
from botstage.missions.api.specs import machine_of, node_of
from botstage.missions.api.where import caller, caller_file
from botstage.missions.check import Checked, check_loaded, describe_part
from botstage.missions.loader import Loaded, Location, Problem, load

if TYPE_CHECKING:  # the runner loads the simulator and friends: only when a mission runs
    from botstage.missions.runner import RunResult
    from botstage.skills.registry import Registry

# the file format's top-level keys, in the order a file is written (`include` is the loader's)
FIELDS = (
    "name",
    "description",
    "robot",
    "world",
    "start",
    "people",
    "gatherings",
    "walks",
    "voices",
    "seed",
    "rate_hz",
    "until",
    "keys",
    "blackboard",
    "skill_params",
    "counters",
    "trees",
    "machines",
    "machine",
    "root",
)
COLLECTIONS: dict[str, type] = {  # empty is the default: not written
    "gatherings": list,
    "walks": list,
    "keys": dict,
    "blackboard": dict,
    "skill_params": dict,
    "counters": list,
    "trees": dict,
    "machines": dict,
}
RUN_FILE = "mission.yaml"  # what a run of a Python mission leaves in its folder, and runs


def _invalid(problems: list[Problem]) -> Exception:
    from botstage.missions.runner import MissionInvalid

    return MissionInvalid(problems)


class Mission:
    """A mission; keywords are the file format's keys, None meaning "not said" (its default).

    ``Mission("patrol", seed=7, until=60, blackboard={"battery_pct": 100})``, then
    ``add_tree``, ``add_machine``, and ``mission.machine = StateMachine(...)`` or ``root=``.
    """

    name: str | None
    description: str | None
    robot: str | None
    world: str | None
    start: str | list[float] | None
    people: int | None
    gatherings: list[Any]
    walks: list[Any]
    voices: dict[str, Any] | None
    seed: int | None
    rate_hz: float | None
    until: float | None
    keys: dict[str, Any]
    blackboard: dict[str, Any]
    skill_params: dict[str, dict[str, Any]]
    counters: list[str]
    trees: dict[str, Any]
    machines: dict[str, Any]
    machine: Any
    root: str | None

    def __init__(
        self,
        name: str | None = None,
        *,
        description: str | None = None,
        robot: str | None = None,
        world: str | None = None,
        start: str | Iterable[float] | None = None,
        people: int | None = None,
        gatherings: Iterable[Mapping[str, Any]] | None = None,
        walks: Iterable[Mapping[str, Any]] | None = None,
        voices: Mapping[str, Any] | None = None,
        seed: int | None = None,
        rate_hz: float | None = None,
        until: float | None = None,
        keys: Mapping[str, Any] | None = None,
        blackboard: Mapping[str, Any] | None = None,
        skill_params: Mapping[str, Mapping[str, Any]] | None = None,
        counters: Iterable[str] | None = None,
        trees: Mapping[str, NodeLike] | None = None,
        machines: Mapping[str, Any] | None = None,
        machine: StateMachine | Mapping[str, Any] | None = None,
        root: str | None = None,
    ) -> None:
        given = dict(locals())
        where = caller()
        self._start(where, caller_file())
        for field in FIELDS:
            value = given[field]
            if value is not None:
                if field in COLLECTIONS:
                    value = COLLECTIONS[field](value)
                elif field == "start" and not isinstance(value, str):
                    value = list(value)
                setattr(self, field, value)
                self._placed[(field,)] = where
        self._tracking = True

    def _start(self, where: Location | None, origin: Path) -> None:
        """Every field unset, nothing placed: what both front ends start from."""
        state = {
            "where": where,  # where the mission was made (problems of the mission as a whole go there)
            "origin": origin,  # names a nameless mission; relative robot and world paths are beside it
            "_tracking": False,  # record where fields are set (not while a file is read)
            "_placed": {},  # spec path -> where Python set it
            "_raw": {},  # what a file said that does not fit a field (kept for the checker to report)
            "_base": None,  # the file's locations
            "_load_problems": [],
            "_file": None,
            "_as_loaded": None,
            "_order": None,  # the file's key order
        }
        for attribute, value in state.items():
            object.__setattr__(self, attribute, value)
        for field in FIELDS:
            object.__setattr__(self, field, COLLECTIONS[field]() if field in COLLECTIONS else None)

    def __setattr__(self, attribute: str, value: Any) -> None:
        if attribute in FIELDS:
            self._raw.pop(attribute, None)
            if value is None and attribute in COLLECTIONS:
                value = COLLECTIONS[attribute]()
            if self._tracking:
                self._placed[(attribute,)] = caller()
        object.__setattr__(self, attribute, value)

    # -- building ---------------------------------------------------------------------------

    def add_tree(self, name: str, node: NodeLike) -> Mission:
        """A named tree: what runs (``root``, or ``main``), a subtree, or a state's contents."""
        if name in self.trees:
            raise ValueError(f"the mission already has a tree {name!r}")
        self._raw.pop("trees", None)  # a file's malformed `trees:` gives way to trees added here
        self.trees[name] = as_node(node)
        self._placed[("trees", name)] = caller()
        return self

    def add_machine(self, name: str, machine: StateMachine | Mapping[str, Any]) -> Mission:
        """A named machine, for ``add_state(machine="name")`` and ``MachineRef("name")``."""
        if name in self.machines:
            raise ValueError(f"the mission already has a machine {name!r}")
        self._raw.pop("machines", None)
        self.machines[name] = machine
        self._placed[("machines", name)] = caller()
        return self

    # -- the YAML front end -----------------------------------------------------------------

    @classmethod
    def from_yaml(cls, path: str | Path) -> Mission:
        """A mission file (with its includes merged in) as a Mission; problems are its file's.

        Raises runner's ``MissionInvalid`` when the file cannot be read as a mission at all.
        """
        path = Path(path)
        loaded = load(path)
        if loaded.data is None:
            raise _invalid(loaded.problems)
        mission = cls.__new__(cls)
        mission._start(None, path)
        mission._base = loaded.locations
        mission._load_problems = list(loaded.problems)
        mission._file = path
        mission._as_loaded = copy.deepcopy(loaded.data)
        mission._order = tuple(loaded.data)
        for name, value in loaded.data.items():
            if name in FIELDS and value is not None and isinstance(value, COLLECTIONS.get(name, object)):
                if name == "trees":
                    value = {tree: node_of(spec) for tree, spec in value.items()}
                elif name == "machines":
                    value = {machine: machine_of(spec) for machine, spec in value.items()}
                elif name == "machine":
                    value = machine_of(value)
                object.__setattr__(mission, name, value)
            else:
                mission._raw[name] = value
        mission._tracking = True
        return mission

    @classmethod
    def from_python(cls, target: str | Path) -> Mission:
        """The mission a Python module defines: what its ``build()`` returns, else its ``mission``.

        ``target`` is a file (``my_mission.py``) or a module (``botstage.missions.examples.hello_api``).
        """
        if str(target).endswith(".py"):
            path = Path(target).resolve()
            spec = importlib.util.spec_from_file_location(f"botstage_mission_{path.stem}", path)
            if spec is None or spec.loader is None:
                raise ImportError(f"cannot import {target}")
            module = importlib.util.module_from_spec(spec)
            sys.modules[spec.name] = module
            spec.loader.exec_module(module)
        else:
            module = importlib.import_module(str(target))
        found = module.build() if callable(getattr(module, "build", None)) else getattr(module, "mission", None)
        if not isinstance(found, Mission):
            raise TypeError(f"{target} has neither build() returning a Mission nor a `mission`")
        return found

    def to_dict(self) -> dict[str, Any]:
        """The mission as the YAML front end loads it; ValueError if a value is not plain data."""
        data, low = self._lowered()
        low.raise_problems()
        return data

    def to_yaml(self) -> str:
        """The mission file a user could save: loading it gives ``to_dict()`` back."""
        return dump_yaml(self.to_dict())

    def _lowered(self) -> tuple[dict[str, Any], Lowering]:
        low = Lowering(self._base, self.where)
        data: dict[str, Any] = {}
        for field in FIELDS:
            if field in self._raw:
                data[field] = low.value(self._raw[field], (field,))
                continue
            value = getattr(self, field)
            if value is None or (field in COLLECTIONS and not value):
                continue
            low.place((field,), self._placed.get((field,)))
            if field in ("trees", "machines") and isinstance(value, Mapping):
                for name in value:
                    low.place((field, name), self._placed.get((field, name)))
                if field == "trees":
                    value = {name: tree.as_node() if isinstance(tree, Part) else tree for name, tree in value.items()}
            data[field] = low.value(value, (field,))
        for name, value in self._raw.items():
            if name not in FIELDS:
                data[name] = low.value(value, (name,))
        return in_order(data, self._order), low

    # -- checking, drawing, running ---------------------------------------------------------

    def check(self, registry: Registry | None = None) -> Checked:
        """Check it as ``botstage validate`` checks a file; problems point at the Python lines
        (or the YAML lines, for what came from a file)."""
        return check_loaded(self._loaded(), self.origin, registry)

    def _loaded(self) -> Loaded:
        """The mission as the checker takes it: its data, with where each part was written."""
        data, low = self._lowered()
        unwritable = low.problems()  # like a file that does not parse: nothing else can be judged
        return Loaded(None if unwritable else data, low.locations, [*self._load_problems, *unwritable], [self.origin])

    def checked(self, registry: Registry | None = None) -> Checked:
        """The check of a valid mission; runner's ``MissionInvalid`` (its problems) otherwise."""
        result = self.check(registry)
        if not result.ok:
            raise _invalid(result.problems)
        return result

    def draw(
        self,
        fmt: str | None = None,
        *,
        tree: str | None = None,
        machine: bool = False,
        registry: Registry | None = None,
    ) -> str | bytes:
        """A picture of what runs (or of its machine, or of a named tree), as ``botstage tree`` /
        ``botstage machine`` draw it: text for ascii, unicode, dot, svg, mermaid and json, bytes
        for png. ``fmt`` defaults to unicode for trees, ascii for machines."""
        from botstage.behaviors.render import FORMATS, render
        from botstage.missions.pictures import machine_picture

        fmt = fmt or ("ascii" if machine else "unicode")
        if fmt not in FORMATS:
            raise ValueError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        if tree is not None and machine:
            raise ValueError("draw a named tree or the machine, not both")
        checked = self.checked(registry)
        spec = checked.mission
        assert spec is not None
        if tree is not None and tree not in spec.trees:
            raise ValueError(f"no tree {tree!r} (trees: {', '.join(spec.trees) or 'none'})")
        item = describe_part(checked, ("trees", tree) if tree is not None else None)
        if machine:  # as `botstage machine`: the machines it runs wherever they sit, else its tree
            item = machine_picture(checked, item, Path(spec.name), lambda line: None)
        picture = render(item, fmt)
        return picture if fmt == "png" else picture.decode()

    def run(self, *, out: Path | None = None, registry: Registry | None = None, **options: Any) -> RunResult:
        """Check, then run as ``botstage.missions.runner.run`` does (same options: ``backend``, ``seed``,
        ``until``, ``realtime``, ``blackboard``, ``before_tick``, ...).

        A mission changed since (or never) loaded from a file runs from memory: checked once, so
        problems point at the Python lines, and built and run as checked. Its run folder keeps
        it as ``mission.yaml`` (what ``summary.json`` names, for replays), written, never read.
        """
        from botstage.missions.runner import run

        if self._file is not None and self.to_dict() == self._as_loaded:
            return run(self._file, out=out, registry=registry, **options)

        def record(folder: Path) -> Path:
            path = folder / RUN_FILE
            name = self.name or self.origin.stem
            path.write_text(dump_yaml(self._runnable(name)), encoding="utf-8")
            return path

        return run(self.origin, out=out, registry=registry, loaded=self._loaded(), record=record, **options)

    def _runnable(self, name: str) -> dict[str, Any]:
        """The data to run from a file elsewhere: named, its robot and world paths made absolute."""
        from botstage.robots.gridmap import known_maps, map_path
        from botstage.robots.profile import known_profiles, profile_path

        data = {"name": name, **self.to_dict()}
        for field, find, shipped in (("robot", profile_path, known_profiles), ("world", map_path, known_maps)):
            value = data.get(field)
            if isinstance(value, str) and value not in shipped():
                found = find(value, self.origin.parent)
                if found is not None:
                    data[field] = str(found.resolve())
        return data

    def __repr__(self) -> str:
        where = f" at {self.where}" if self.where is not None else f" from {self._file}"
        return f"<Mission {self.name or self.origin.stem}{where}>"


class _Dumper(yaml.SafeDumper):
    """Block style, with short leaf mappings and lists in flow style, as missions are written."""

    def ignore_aliases(self, data: Any) -> bool:
        return True

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)  # a list under a key is indented, as missions are written


def _leaf(items: Iterable[Any]) -> bool:
    return all(not isinstance(item, dict | list) for item in items)


_Dumper.add_representer(
    dict,
    lambda dumper, data: dumper.represent_mapping(
        "tag:yaml.org,2002:map", data, flow_style=len(data) <= 4 and _leaf(data.values())
    ),
)
_Dumper.add_representer(
    list,
    lambda dumper, data: dumper.represent_sequence(
        "tag:yaml.org,2002:seq", data, flow_style=len(data) <= 8 and _leaf(data)
    ),
)


def dump_yaml(data: Mapping[str, Any]) -> str:
    """A mission's data as a mission file's text."""
    return yaml.dump(dict(data), Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=100)


__all__ = ["FIELDS", "RUN_FILE", "Mission", "dump_yaml"]
