"""YAML files whose every entry keeps its file, line and column (missions, robot profiles).

PyYAML's composer gives every node its position; we build plain Python data from the node graph
ourselves so each mapping entry and sequence item keeps where it came from, and duplicate keys
are caught (PyYAML silently keeps the last one). Nothing here raises for bad input: every
problem is collected with its location.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import ConstructorError, SafeConstructor

Path_ = tuple[str | int, ...]


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


class _Composer:
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


def parse(path: Path, problems: list[Problem], locations: Locations, prefix: Path_ = ()) -> Any:
    name = display_name(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return MISSING_FILE
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
    return _Composer(name, locations, problems, prefix).data(nodes[0], ())


class MissingType:
    pass


MISSING_FILE = MissingType()


def load_document(path: str | Path) -> Loaded:
    """One YAML file, its data and locations; problems collected, never raised."""
    path = Path(path)
    locations = Locations(root=Location(display_name(path), 1, 1))
    problems: list[Problem] = []
    data = parse(path, problems, locations)
    if data is MISSING_FILE:
        problems.append(Problem(locations.root, "no such file"))  # type: ignore[arg-type]
        data = None
    elif data is not None and not isinstance(data, dict):
        problems.append(Problem(locations.root, "expected a mapping at the top of the file"))  # type: ignore[arg-type]
        data = None
    return Loaded(data, locations, problems, [path])


def find_yaml(name_or_path: str, folder: Path, names: list[str], relative_to: Path | None = None) -> Path | None:
    """A resource named in a mission: one of ``names`` shipped in ``folder``, or a path to a YAML
    file (relative to the mission's folder). None when neither exists."""
    if name_or_path in names:
        return folder / f"{name_or_path}.yaml"
    candidate = Path(name_or_path)
    if relative_to is not None and not candidate.is_absolute():
        candidate = relative_to / candidate
    return candidate if candidate.suffix in (".yaml", ".yml") and candidate.exists() else None
