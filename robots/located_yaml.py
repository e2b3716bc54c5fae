"""YAML files whose every entry keeps its file, line and column (missions, profiles, scenarios).

We compose the node graph ourselves from the parser's events (libyaml's when installed) and build
plain Python data from it, so each mapping entry and sequence item keeps where it came from and
duplicate keys are caught (PyYAML silently keeps the last one). Nothing here raises for bad
input: every problem is collected with its location.

The files are input from anyone, so reading is bounded (``botstage.robots.limits``): only regular files of
at most ``MAX_FILE_BYTES``, nesting at most ``MAX_NESTING`` deep, at most ``MAX_VALUES`` values of
which ``MAX_ALIAS_VALUES`` repeated by aliases (a "billion laughs" stops at once). Numbers follow
YAML 1.2 where 1.1 surprises: ``1e5`` and ``1.0e308`` are floats, not strings.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import SafeConstructor
from yaml.resolver import Resolver

from botstage.robots import limits

Path_ = tuple[str | int, ...]


@dataclass(frozen=True, order=True, slots=True)
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


@dataclass
class Budget:
    """What one load (a file and all it includes) has used of the limits so far."""

    values: int = 0
    aliased: int = 0
    files: int = 0


def display_name(path: Path) -> str:
    """Paths relative to the working directory when they are below it, as compilers print them."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        return str(path)


# -- reading --------------------------------------------------------------------------------


class MissingType:
    pass


MISSING_FILE = MissingType()


class FileRefused(ValueError):
    """A file that is not read: not a regular file, too large, not UTF-8. The message says why
    and never quotes the file."""


_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _not_regular(mode: int) -> str:
    what = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    return f"it is {what}: only regular files are read" if what != "not a regular file" else what


class NotText(FileRefused):
    """A file that is not UTF-8 text (an image given for its YAML header, say)."""


def read_bytes(path: Path, limit: int, kind: str = "file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    Checked before opening (a FIFO would block, /dev/zero never ends) and again on the open file
    (it may have been swapped); at most ``limit + 1`` bytes are read whatever the file claims.
    Raises FileNotFoundError, FileRefused, or OSError.
    """
    try:
        info = os.stat(path)
    except ValueError as exc:  # a NUL byte in the name
        raise FileRefused(f"not a usable file name: {exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise FileRefused(_not_regular(info.st_mode))
    too_large = f"the file is larger than {limit:,} bytes (the limit for a {kind})"
    if info.st_size > limit:
        raise FileRefused(too_large)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    with os.fdopen(fd, "rb") as file:
        mode = os.fstat(file.fileno()).st_mode
        if not stat.S_ISREG(mode):
            raise FileRefused(_not_regular(mode))
        raw = file.read(limit + 1)
    if len(raw) > limit:
        raise FileRefused(too_large)
    return raw


def read_text(path: Path, limit: int = limits.MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes (see ``read_bytes``)."""
    raw = read_bytes(path, limit, "YAML file")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise NotText(f"not UTF-8 text (byte {exc.start + 1} cannot be decoded)") from None


# -- numbers: YAML 1.1's implicit types, but an exponent needs no sign -------------------------

_FLOAT_TAG = "tag:yaml.org,2002:float"
_FLOAT = re.compile(
    r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)


class NumberResolver(Resolver):
    """PyYAML's resolver, except that ``1e5``, ``1.0e308`` and ``2E-3`` are floats (YAML 1.1
    wants a sign in the exponent and a dot, so PyYAML reads them as strings; YAML 1.2 does not)."""

    yaml_implicit_resolvers = {
        first: [(tag, _FLOAT if tag == _FLOAT_TAG else regexp) for tag, regexp in resolvers]
        for first, resolvers in Resolver.yaml_implicit_resolvers.items()
    }


_RESOLVER = NumberResolver()
_EventLoader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's parser when installed


class BoundedLoader(yaml.SafeLoader):
    """A SafeLoader with the number resolver, for plain data (no locations) from trusted code."""

    yaml_implicit_resolvers = NumberResolver.yaml_implicit_resolvers


def _resolve(value: str, implicit: tuple[bool, bool]) -> str:
    return _RESOLVER.resolve(yaml.ScalarNode, value, implicit)


# -- composing: events to a node graph, iteratively and bounded -------------------------------

_SCALAR, _SEQUENCE, _MAPPING = 0, 1, 2
_STR = "tag:yaml.org,2002:str"
_MERGE = "tag:yaml.org,2002:merge"
_TEXT_TAGS = frozenset({_STR, _MERGE, "tag:yaml.org,2002:value"})  # `<<` and `=` out of place are text
_SCALAR_TAGS = {
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:int",
    _FLOAT_TAG,
    "tag:yaml.org,2002:binary",
    "tag:yaml.org,2002:timestamp",
}


class _Node:
    """A composed YAML node: lighter than PyYAML's (no marks), since files may hold many."""

    __slots__ = ("active", "col", "kind", "line", "seen", "tag", "value")

    def __init__(self, kind: int, tag: str, value: Any, line: int, col: int) -> None:
        self.kind = kind
        self.tag = tag
        self.value = value
        self.line = line
        self.col = col
        self.seen = False  # constructed once already: the next time is an alias
        self.active = False  # being constructed: an alias to it now is recursive


class _Stop(Exception):
    """A limit was reached: the file's data is refused with this problem."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem


def _where(file: str, mark: Any) -> Location:
    return Location(file, mark.line + 1, mark.column + 1)


Sites = dict[tuple[int, int], Location]  # (id of a collection, item or entry index) -> where an alias stands


def _compose(loader: Any, file: str, problems: list[Problem], sites: Sites) -> _Node | None:
    """The first document's node graph; a second document is a problem. Raises _Stop.

    An alias is the node it names (shared), so where each alias stands is kept in ``sites``."""
    events = yaml.events
    loader.get_event()  # stream start
    if loader.check_event(events.StreamEndEvent):
        return None
    loader.get_event()  # document start
    anchors: dict[str, _Node] = {}
    stack: list[list[Any]] = []  # [collection node, pending mapping key or None]
    root: _Node | None = None
    composed = 0
    while True:
        event = loader.get_event()
        kind = type(event)
        if kind is events.SequenceEndEvent or kind is events.MappingEndEvent:
            stack.pop()
            if not stack:
                break
            continue
        mark = event.start_mark
        if kind is events.AliasEvent:
            node = anchors.get(event.anchor)
            if node is None:
                raise _Stop(Problem(_where(file, mark), f"YAML alias *{event.anchor} refers to no anchor"))
        else:
            composed += 1
            if composed > limits.MAX_VALUES:
                raise _Stop(Problem(_where(file, mark), f"the file holds more than {limits.MAX_VALUES:,} values"))
            tag = event.tag
            if kind is events.ScalarEvent:
                if tag is None or tag == "!":
                    tag = _resolve(event.value, event.implicit)
                node = _Node(_SCALAR, tag, event.value, mark.line + 1, mark.column + 1)
            else:
                if len(stack) >= limits.MAX_NESTING:
                    raise _Stop(Problem(_where(file, mark), f"nested more than {limits.MAX_NESTING} levels deep"))
                collection = _SEQUENCE if kind is events.SequenceStartEvent else _MAPPING
                node = _Node(collection, tag or "", [], mark.line + 1, mark.column + 1)
            if event.anchor is not None:
                anchors[event.anchor] = node
        if not stack:
            root = node
        else:
            top = stack[-1]
            if kind is events.AliasEvent and (top[0].kind == _SEQUENCE or top[1] is not None):
                sites[(id(top[0]), len(top[0].value))] = _where(file, mark)
            if top[0].kind == _SEQUENCE:
                top[0].value.append(node)
            elif top[1] is None:
                top[1] = node
            else:
                top[0].value.append((top[1], node))
                top[1] = None
        if kind is events.SequenceStartEvent or kind is events.MappingStartEvent:
            stack.append([node, None])
        elif not stack:
            break
    loader.get_event()  # document end
    if loader.check_event(events.DocumentStartEvent):
        loader.get_event()
        first = loader.peek_event()
        problems.append(Problem(Location(file, first.start_mark.line + 1, 1), "one document per file, found more"))
    return root


# -- constructing: the node graph to plain data with locations --------------------------------


class _Composer:
    """Turns a composed node graph into data, recording locations and problems."""

    def __init__(
        self, file: str, locations: Locations, problems: list[Problem], prefix: Path_, budget: Budget, sites: Sites
    ) -> None:
        self.file = file
        self.locations = locations
        self.problems = problems
        self.prefix = prefix
        self.budget = budget
        self.sites = sites
        self.alias: Location | None = None  # where the outermost alias being expanded stands
        self.constructor = SafeConstructor()

    def loc(self, node: _Node) -> Location:
        return Location(self.file, node.line, node.col)

    def _count(self, node: _Node) -> None:
        budget = self.budget
        budget.values += 1
        if node.seen:
            budget.aliased += 1
            if budget.aliased > limits.MAX_ALIAS_VALUES:
                message = f"YAML aliases expand to more than {limits.MAX_ALIAS_VALUES:,} values"
                raise _Stop(Problem(self.alias or self.loc(node), message))
        else:
            node.seen = True
        if budget.values > limits.MAX_VALUES:
            raise _Stop(Problem(self.loc(node), f"more than {limits.MAX_VALUES:,} values (aliases expanded)"))

    def data(self, node: _Node, path: Path_, depth: int = 0) -> Any:
        self._count(node)
        if node.kind == _SCALAR:
            return self.scalar(node)
        if node.active:
            self.problems.append(Problem(self.loc(node), "a YAML alias refers to itself (recursive anchor)"))
            return None
        if depth >= limits.MAX_NESTING:
            raise _Stop(
                Problem(self.loc(node), f"nested more than {limits.MAX_NESTING} levels deep (aliases expanded)")
            )
        node.active = True
        try:
            if node.kind == _SEQUENCE:
                return self.sequence(node, path, depth)
            return self.mapping(node, path, depth)
        finally:
            node.active = False

    def scalar(self, node: _Node) -> Any:
        tag = node.tag
        if tag in _TEXT_TAGS:
            return node.value
        if tag not in _SCALAR_TAGS:
            self.problems.append(Problem(self.loc(node), f"bad YAML value: the tag {tag!r} is not supported here"))
            return None
        try:
            return SafeConstructor.yaml_constructors[tag](self.constructor, yaml.ScalarNode(tag, node.value))
        except Exception:  # int("abc") under !!int, too many digits, a bad date or base64
            kind = tag.rsplit(":", 1)[-1]
            self.problems.append(Problem(self.loc(node), f"bad YAML value: not a valid {kind}"))
            return None

    def aliased(self, node: _Node, path: Path_, depth: int, site: Location) -> Any:
        """The data of an alias, located where the alias stands."""
        if self.alias is not None:
            return self.data(node, path, depth)
        self.alias = site
        try:
            return self.data(node, path, depth)
        finally:
            self.alias = None

    def sequence(self, node: _Node, path: Path_, depth: int) -> list[Any]:
        items = []
        by_path = self.locations.by_path
        base = self.prefix + path
        sites = self.sites
        for index, item in enumerate(node.value):
            site = sites.get((id(node), index)) if sites else None
            if site is None:
                by_path[base + (index,)] = Location(self.file, item.line, item.col)
                items.append(self.data(item, path + (index,), depth + 1))
            else:
                by_path[base + (index,)] = site
                items.append(self.aliased(item, path + (index,), depth + 1, site))
        return items

    def mapping(self, node: _Node, path: Path_, depth: int) -> dict[Any, Any]:
        result: dict[Any, Any] = {}
        merged: list[_Node] = []
        first: dict[Any, Location] = {}
        by_path = self.locations.by_path
        base = self.prefix + path
        sites = self.sites
        for index, (key_node, value_node) in enumerate(node.value):
            if key_node.kind == _SCALAR and key_node.tag == _MERGE:
                merged.extend(self._merge_sources(value_node))
                continue
            key = self.data(key_node, path, depth + 1)
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
            by_path[base + (key,)] = where
            site = sites.get((id(node), index)) if sites else None
            if site is None:
                result[key] = self.data(value_node, path + (key,), depth + 1)
            else:
                result[key] = self.aliased(value_node, path + (key,), depth + 1, site)
        if merged:
            # YAML merge keys: the mapping's own keys win, then earlier merged mappings
            inherited: dict[Any, Any] = {}
            for source in reversed(merged):
                values = self.data(source, path, depth)
                if isinstance(values, dict):
                    inherited.update(values)
            for key, where in first.items():
                by_path[base + (key,)] = where
            result = {**inherited, **result}
        return result

    def _merge_sources(self, value: _Node) -> list[_Node]:
        sources = value.value if value.kind == _SEQUENCE else [value]
        if all(source.kind == _MAPPING for source in sources):
            return sources
        self.problems.append(Problem(self.loc(value), "bad YAML merge: `<<` takes a mapping or a list of mappings"))
        return []


def _syntax_problem(exc: yaml.YAMLError, text: str, name: str) -> Problem:
    """A located problem for a YAML error; libyaml's wording is replaced by PyYAML's (which names
    the character or token found) when the file is small enough to parse again quickly."""
    nesting = "maximum nesting depth" in str(exc)  # libyaml's own cap: its mark is all we need, at once
    # (PyYAML's pure-Python scanner takes quadratic time on deeply nested flow collections)
    if _EventLoader is not yaml.SafeLoader and len(text) <= 256 * 1024 and not nesting:
        try:
            loader = yaml.SafeLoader(text)  # its reader checks the characters at once
            while loader.get_event() is not None:
                pass
        except yaml.YAMLError as python_exc:
            exc = python_exc
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = Location(name, mark.line + 1, mark.column + 1) if mark else Location(name, 1, 1)
        message = exc.problem or str(exc)
        if exc.context:
            message = f"{exc.context}, {message}"
        if "maximum nesting depth" in message:  # libyaml ≥ 0.2.5's own cap (PyYAML 6.0.4 wheels): one wording
            return Problem(where, f"nested more than {limits.MAX_NESTING} levels deep")
        return Problem(where, f"YAML syntax: {message}")
    if isinstance(exc, yaml.reader.ReaderError):
        before = text[: max(exc.position, 0)]
        line = before.count("\n") + 1
        col = len(before) - (before.rfind("\n") + 1) + 1
        return Problem(Location(name, line, col), f"YAML: character #x{exc.character:04x} is not allowed")
    return Problem(Location(name, 1, 1), f"YAML: {str(exc).splitlines()[0]}")


def parse(
    path: Path, problems: list[Problem], locations: Locations, prefix: Path_ = (), budget: Budget | None = None
) -> Any:
    """The data of one YAML file, its locations recorded under ``prefix``; None if it cannot be
    read or parsed (with the problem recorded), MISSING_FILE if there is no such file.
    ``budget`` is shared by the files of one load, so includes count against the same limits."""
    name = display_name(path)
    budget = budget if budget is not None else Budget()
    budget.files += 1
    try:
        text = read_text(path)
    except FileNotFoundError:
        return MISSING_FILE
    except FileRefused as exc:
        problems.append(Problem(Location(name, 1, 1), f"cannot read the file: {exc}"))
        return None
    except OSError as exc:
        problems.append(Problem(Location(name, 1, 1), f"cannot read the file: {exc.strerror or exc}"))
        return None
    return parse_text(text, name, problems, locations, prefix, budget)


def parse_text(
    text: str,
    name: str,
    problems: list[Problem],
    locations: Locations,
    prefix: Path_ = (),
    budget: Budget | None = None,
) -> Any:
    """The data of YAML ``text`` from the file ``name``; None (with problems recorded) if it has none."""
    budget = budget if budget is not None else Budget()
    sites: Sites = {}
    loader = None
    try:
        loader = _EventLoader(text)
        root = _compose(loader, name, problems, sites)
    except _Stop as stop:
        problems.append(stop.problem)
        return None
    except yaml.YAMLError as exc:
        problems.append(_syntax_problem(exc, text, name))
        return None
    except UnicodeError:  # a lone surrogate, from text that did not come from a file
        problems.append(Problem(Location(name, 1, 1), "YAML: the text is not valid Unicode"))
        return None
    finally:
        if loader is not None:
            loader.dispose()
    if root is None:
        problems.append(Problem(Location(name, 1, 1), "the file is empty"))
        return None
    try:
        return _Composer(name, locations, problems, prefix, budget, sites).data(root, ())
    except _Stop as stop:
        problems.append(stop.problem)
        return None


class YamlProblem(ValueError):
    """The first problem of a YAML file read without locations."""

    def __init__(self, problem: Problem) -> None:
        super().__init__(str(problem))
        self.problem = problem


def load_data(path: str | Path) -> Any:
    """Plain data from a YAML file, read with the same bounds and numbers as located files; for
    files without locations (map headers, place lists). Raises FileNotFoundError, FileRefused,
    OSError, or YamlProblem."""
    path = Path(path)
    problems: list[Problem] = []
    name = display_name(path)
    data = parse_text(read_text(path), name, problems, Locations(root=Location(name, 1, 1)))
    if problems:
        raise YamlProblem(problems[0])
    return data


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
    try:
        return candidate if candidate.suffix in (".yaml", ".yml") and candidate.exists() else None
    except (OSError, ValueError):  # a name too long, a NUL byte
        return None
