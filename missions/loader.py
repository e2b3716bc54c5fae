"""Load mission YAML keeping the file, line and column of every node.

PyYAML's composer gives every node its position; we build plain Python data from the node graph
ourselves so each mapping entry and sequence item keeps where it came from, duplicate keys are
caught (PyYAML silently keeps the last one), and `include:`d files are merged in with their own
positions. Nothing here raises for bad input: every problem is collected with its location.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import ConstructorError, SafeConstructor

Path_ = tuple[str | int, ...]
INCLUDABLE = ("trees", "machines", "keys")  # what an included file may contribute


@dataclass(frozen=True, order=True)
class Location:
    file: str
    line: int  # 1-based
    col: int  # 1-based

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


@dataclass(frozen=True)
class Problem:
    location: Location
    message: str
    hint: str = ""

    def __str__(self) -> str:
        return f"{self.location}: error: {self.message}" + (f" ({self.hint})" if self.hint else "")


@dataclass
class Locations:
    """Where each part of the (merged) mission came from, by its path in the data."""

    by_path: dict[Path_, Location] = field(default_factory=dict)
    root: Location | None = None

    def find(self, path: Iterable[str | int]) -> Location:
        """The location of ``path``, or of its nearest ancestor that exists in the file."""
        parts = tuple(path)
        while parts:
            found = self.by_path.get(parts)
            if found is not None:
                return found
            parts = parts[:-1]
        assert self.root is not None
        return self.root


@dataclass
class Loaded:
    data: dict[str, Any] | None
    locations: Locations
    problems: list[Problem]
    files: list[Path]


def display_name(path: Path) -> str:
    """Paths relative to the working directory when they are below it, as compilers print them."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


class _Builder:
    """Turns a composed node graph into data, recording locations and problems."""

    def __init__(self, file: str, locations: Locations, problems: list[Problem], prefix: Path_ = ()) -> None:
        self.file = file
        self.locations = locations
        self.problems = problems
        self.prefix = prefix
        self.constructor = SafeConstructor()
        self.active: set[int] = set()

    def loc(self, node: yaml.Node) -> Location:
        return Location(self.file, node.start_mark.line + 1, node.start_mark.column + 1)

    def data(self, node: yaml.Node, path: Path_) -> Any:
        if id(node) in self.active:
            self.problems.append(Problem(self.loc(node), "a YAML alias refers to itself (recursive anchor)"))
            return None
        if isinstance(node, yaml.ScalarNode):
            try:
                return self.constructor.construct_object(node, deep=True)
            except ConstructorError as exc:
                self.problems.append(Problem(self.loc(node), f"bad YAML value: {exc.problem}"))
                return None
        self.active.add(id(node))
        try:
            if isinstance(node, yaml.SequenceNode):
                items = []
                for index, item in enumerate(node.value):
                    self.locations.by_path[self.prefix + path + (index,)] = self.loc(item)
                    items.append(self.data(item, path + (index,)))
                return items
            assert isinstance(node, yaml.MappingNode)
            try:
                self.constructor.flatten_mapping(node)  # YAML merge keys (<<)
            except ConstructorError as exc:
                self.problems.append(Problem(self.loc(node), f"bad YAML merge: {exc.problem}"))
            result: dict[Any, Any] = {}
            first: dict[Any, Location] = {}
            for key_node, value_node in node.value:
                key = self.data(key_node, path)
                if isinstance(key, list | dict):
                    self.problems.append(Problem(self.loc(key_node), "a mapping key must be a plain value"))
                    continue
                where = self.loc(key_node)
                if key in first:
                    self.problems.append(
                        Problem(where, f"duplicate key {key!r}", f"first defined at line {first[key].line}")
                    )
                    continue
                first[key] = where
                self.locations.by_path[self.prefix + path + (key,)] = where
                result[key] = self.data(value_node, path + (key,))
            return result
        finally:
            self.active.discard(id(node))


def _parse(path: Path, problems: list[Problem], locations: Locations, prefix: Path_ = ()) -> Any:
    name = display_name(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return _Missing
    except (OSError, UnicodeDecodeError) as exc:
        problems.append(Problem(Location(name, 1, 1), f"cannot read the file: {getattr(exc, 'strerror', None) or exc}"))
        return None
    try:
        nodes = list(yaml.compose_all(text, Loader=yaml.SafeLoader))
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = Location(name, mark.line + 1, mark.column + 1) if mark else Location(name, 1, 1)
        message = exc.problem or str(exc)
        if exc.context:
            message = f"{exc.context}, {message}"
        problems.append(Problem(where, f"YAML syntax: {message}"))
        return None
    except yaml.YAMLError as exc:
        problems.append(Problem(Location(name, 1, 1), f"YAML: {exc}"))
        return None
    if not nodes or nodes[0] is None:
        problems.append(Problem(Location(name, 1, 1), "the file is empty"))
        return None
    if len(nodes) > 1:
        second = nodes[1]
        problems.append(Problem(Location(name, second.start_mark.line + 1, 1), "one document per file, found more"))
    return _Builder(name, locations, problems, prefix).data(nodes[0], ())


class _MissingType:
    pass


_Missing = _MissingType()


def load(path: str | Path) -> Loaded:
    """Load a mission and everything it includes; problems are collected, never raised."""
    path = Path(path)
    locations = Locations(root=Location(display_name(path), 1, 1))
    problems: list[Problem] = []
    data = _parse(path, problems, locations)
    files = [path]
    if data is _Missing:
        problems.append(Problem(locations.root, "no such file"))  # type: ignore[arg-type]
        return Loaded(None, locations, problems, files)
    if data is None:
        return Loaded(None, locations, problems, files)
    if not isinstance(data, dict):
        problems.append(Problem(locations.root, "a mission is a mapping (name:, trees:, machine:, ...)"))  # type: ignore[arg-type]
        return Loaded(None, locations, problems, files)
    _include(data, path, locations, problems, files, stack=(path.resolve(),), prefix=())
    return Loaded(data, locations, problems, files)


def _include(
    data: dict[str, Any],
    path: Path,
    locations: Locations,
    problems: list[Problem],
    files: list[Path],
    stack: tuple[Path, ...],
    prefix: Path_,
) -> None:
    """Merge the trees, machines and keys of each included file into ``data``."""
    raw = data.pop("include", None)
    if raw is None:
        return
    entries = [raw] if isinstance(raw, str) else raw
    if not isinstance(entries, list):
        problems.append(Problem(locations.find(prefix + ("include",)), "include takes a file name or a list of them"))
        return
    for index, entry in enumerate(entries):
        where = locations.find(prefix + ("include",) + ((index,) if isinstance(raw, list) else ()))
        if not isinstance(entry, str) or not entry:
            problems.append(Problem(where, "an include is a file path, relative to the including file"))
            continue
        target = (path.parent / entry).resolve()
        if target in stack:
            chain = " -> ".join(display_name(p) for p in (*stack, target))
            problems.append(Problem(where, f"include cycle: {chain}"))
            continue
        included_locations = Locations(root=Location(display_name(target), 1, 1))
        included = _parse(target, problems, included_locations)
        if included is _Missing:
            problems.append(Problem(where, f"included file {entry!r} does not exist", f"looked for {target}"))
            continue
        if included is None:
            continue
        files.append(target)
        if not isinstance(included, dict):
            problems.append(
                Problem(included_locations.root, "an included file is a mapping of trees:, machines:, keys:")
            )  # type: ignore[arg-type]
            continue
        _include(included, target, included_locations, problems, files, (*stack, target), ())
        for key in included:
            if key not in INCLUDABLE:
                problems.append(
                    Problem(
                        included_locations.find((key,)),
                        f"an included file may hold only {', '.join(INCLUDABLE)}; found {key!r}",
                    )
                )
        for section in INCLUDABLE:
            entries_in = included.get(section)
            if entries_in is None:
                continue
            if not isinstance(entries_in, Mapping):
                problems.append(
                    Problem(included_locations.find((section,)), f"{section} is a mapping of name: definition")
                )
                continue
            merged = data.setdefault(section, {})
            if not isinstance(merged, dict):
                continue  # the including file's own error is reported by the schema check
            for name, value in entries_in.items():
                if name in merged:
                    first = locations.find(prefix + (section, name))
                    problems.append(
                        Problem(
                            included_locations.find((section, name)),
                            f"duplicate name {name!r} in {section}",
                            f"also defined at {first}",
                        )
                    )
                    continue
                merged[name] = value
                for sub, loc in included_locations.by_path.items():
                    if sub[:2] == (section, name):
                        locations.by_path[prefix + sub] = loc
