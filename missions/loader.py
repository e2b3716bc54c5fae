"""Load a mission keeping the file, line and column of every node, with its includes.

A mission file's format is found by its suffix in a registry (entry-point group
``botstage.formats``): YAML (``.yaml``, ``.yml``, and any suffix no format claims) is built in;
a plug-in set adds its own (BehaviorTree.CPP's set reads ``.xml``), so this module imports no
other format's reader.

`include:`d files are merged in (their trees, machines and keys) with their own positions;
include cycles and missing files are located problems like any other.

An include is a path relative to the including file. It must lie, symlinks resolved, in the
top mission's folder tree, the built-in library (``missions/lib``) or a folder the caller allows
(``include_dirs``, and ``BOTSTAGE_INCLUDE_PATH``: folders separated by ``os.pathsep``); a name
not found beside the including file is looked for in those folders, in that order. Anything else
is refused without being opened, so a mission cannot read (or quote) files from elsewhere.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, Protocol

from botstage.robots import limits
from botstage.robots.located_yaml import (
    MISSING_FILE,
    Budget,
    Loaded,
    Location,
    Locations,
    Path_,
    Problem,
    display_name,
    parse,
)
from botstage.robots.plugins import PluginProblem, discover

INCLUDABLE = ("trees", "machines", "keys")  # what an included file may contribute
LIBRARY_DIR = Path(__file__).resolve().parent / "lib"  # the built-in library of shared trees
FORMAT_GROUP = "botstage.formats"

__all__ = [
    "FORMAT_GROUP",
    "INCLUDABLE",
    "LIBRARY_DIR",
    "YAML",
    "Loaded",
    "Location",
    "Locations",
    "MissionFormat",
    "Problem",
    "display_name",
    "format_of",
    "load",
]


class MissionFormat(Protocol):
    """A mission file format: the suffixes it reads and how (problems collected, never raised)."""

    name: str
    suffixes: tuple[str, ...]

    def load(self, path: Path, include_dirs: Iterable[str | Path] = ()) -> Loaded: ...


class YamlFormat:
    """botstage's own format: mission YAML with ``include:``s."""

    name = "yaml"
    suffixes = (".yaml", ".yml")

    def load(self, path: Path, include_dirs: Iterable[str | Path] = ()) -> Loaded:
        return _load_yaml(path, include_dirs)


YAML = YamlFormat()


def _not_a_format(value: object) -> str:
    suffixes = getattr(value, "suffixes", None)
    if (
        isinstance(suffixes, tuple)
        and all(isinstance(s, str) for s in suffixes)
        and callable(getattr(value, "load", None))
    ):
        return ""
    return "does not point to a mission format (an object with suffixes and load)"


@cache
def _plugin_formats() -> tuple[dict[str, MissionFormat], tuple[PluginProblem, ...]]:
    """Formats of installed plug-ins by suffix, read once per process (only when a file is not YAML)."""
    problems: list[PluginProblem] = []
    found: dict[str, MissionFormat] = {}
    for plugin in discover(FORMAT_GROUP, problems, what="format", problem_of=_not_a_format, name_of=lambda v: None):
        for suffix in plugin.value.suffixes:
            found.setdefault(suffix.lower(), plugin.value)
    return found, tuple(problems)


def format_of(path: str | Path) -> MissionFormat:
    """The format that reads ``path``, by its suffix; YAML when no format claims the suffix."""
    suffix = Path(path).suffix.lower()
    if suffix in YAML.suffixes:
        return YAML
    return _plugin_formats()[0].get(suffix, YAML)


@dataclass
class _Load:
    """One load's state: where includes may come from, and what has been read so far."""

    roots: list[Path]  # the mission's folder, then the caller's folders, then the library
    problems: list[Problem]
    files: list[Path]
    budget: Budget


def include_roots(path: Path, include_dirs: Iterable[str | Path] = ()) -> list[Path]:
    """The folders a mission at ``path`` may include from, in the order names are looked up."""
    extra = [*include_dirs, *os.environ.get(limits.INCLUDE_PATH_ENV, "").split(os.pathsep)]
    roots = [_resolved(path.parent), *(_resolved(Path(d).expanduser()) for d in extra if str(d)), LIBRARY_DIR]
    return list(dict.fromkeys(root for root in roots if root is not None))


def _resolved(folder: Path) -> Path | None:
    try:
        return folder.resolve()
    except (OSError, RuntimeError):  # a symlink loop: no folder to include from
        return None


def load(path: str | Path, include_dirs: Iterable[str | Path] = ()) -> Loaded:
    """Load a mission and everything it includes; problems are collected, never raised.

    ``include_dirs``: folders besides the mission's own tree and the built-in library that
    includes may come from (``BOTSTAGE_INCLUDE_PATH`` adds more). The file's format is found by
    its suffix (``format_of``)."""
    path = Path(path)
    return format_of(path).load(path, include_dirs)


def _load_yaml(path: Path, include_dirs: Iterable[str | Path]) -> Loaded:
    locations = Locations(root=Location(display_name(path), 1, 1))
    state = _Load(include_roots(path, include_dirs), [], [path], Budget())
    data = parse(path, state.problems, locations, budget=state.budget)
    if data is MISSING_FILE:
        state.problems.append(Problem(locations.root, "no such file"))  # type: ignore[arg-type]
        return Loaded(None, locations, state.problems, state.files)
    if data is None:
        return Loaded(None, locations, state.problems, state.files)
    if not isinstance(data, dict):
        state.problems.append(Problem(locations.root, "a mission is a mapping (name:, trees:, machine:, ...)"))  # type: ignore[arg-type]
        return Loaded(None, locations, state.problems, state.files)
    _include(data, path, locations, state, stack=(path.resolve(),), prefix=())
    return Loaded(data, locations, state.problems, state.files)


def _allowed(target: Path, roots: list[Path]) -> bool:
    return any(target.is_relative_to(root) for root in roots)


def _target(entry: str, including: Path, roots: list[Path]) -> Path:
    """The file an include names: beside the including file, else in the first root that has it."""
    beside = (including.parent / entry).resolve()
    if Path(entry).is_absolute() or beside.exists():
        return beside
    for root in roots[1:]:
        candidate = (root / entry).resolve()
        if candidate.exists() and _allowed(candidate, roots):
            return candidate
    return beside


def _include(
    data: dict[str, Any],
    path: Path,
    locations: Locations,
    state: _Load,
    stack: tuple[Path, ...],
    prefix: Path_,
) -> None:
    """Merge the trees, machines and keys of each included file into ``data``."""
    problems = state.problems
    raw = data.pop("include", None)
    if raw is None:
        return
    entries = [raw] if isinstance(raw, str) else raw
    if not isinstance(entries, list):
        problems.append(Problem(locations.find(prefix + ("include",)), "include takes a file name or a list of them"))
        return
    for index, entry in enumerate(entries):
        where = locations.find(prefix + ("include",) + ((index,) if isinstance(raw, list) else ()))
        if not isinstance(entry, str) or not entry or "\0" in entry:
            problems.append(Problem(where, "an include is a file path, relative to the including file"))
            continue
        try:
            target = _target(entry, path, state.roots)
        except (OSError, RuntimeError) as exc:  # a name too long, a symlink loop
            problems.append(Problem(where, f"include {entry!r} cannot be followed: {exc}"))
            continue
        if not _allowed(target, state.roots):
            problems.append(
                Problem(
                    where,
                    f"include {entry!r} is outside the folders a mission may include from",
                    f"allowed: {state.roots[0]}, the built-in library and folders named by --include-dir "
                    f"or {limits.INCLUDE_PATH_ENV}",
                )
            )
            continue
        if target in stack:
            chain = " -> ".join(display_name(p) for p in (*stack, target))
            problems.append(Problem(where, f"include cycle: {chain}"))
            continue
        if state.budget.files > limits.MAX_INCLUDED_FILES:
            problems.append(Problem(where, f"more than {limits.MAX_INCLUDED_FILES} included files"))
            return
        included_locations = Locations(root=Location(display_name(target), 1, 1))
        included = parse(target, problems, included_locations, budget=state.budget)
        if included is MISSING_FILE:
            problems.append(
                Problem(where, f"included file {entry!r} does not exist", f"looked for {display_name(target)}")
            )
            continue
        if included is None:
            continue
        state.files.append(target)
        if not isinstance(included, dict):
            problems.append(
                Problem(included_locations.root, "an included file is a mapping of trees:, machines:, keys:")
            )  # type: ignore[arg-type]
            continue
        _include(included, target, included_locations, state, (*stack, target), ())
        _merge(included, included_locations, data, locations, prefix, problems)


def _merge(
    included: dict[str, Any],
    included_locations: Locations,
    data: dict[str, Any],
    locations: Locations,
    prefix: Path_,
    problems: list[Problem],
) -> None:
    """Merge an included file's sections into the including data, with their locations."""
    for key in included:
        if key not in INCLUDABLE:
            problems.append(
                Problem(
                    included_locations.find((key,)),
                    f"an included file may hold only {', '.join(INCLUDABLE)}; found {key!r}",
                )
            )
    taken: set[tuple[Any, ...]] = set()
    for section in INCLUDABLE:
        entries_in = included.get(section)
        if entries_in is None:
            continue
        if not isinstance(entries_in, Mapping):
            problems.append(Problem(included_locations.find((section,)), f"{section} is a mapping of name: definition"))
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
            taken.add((section, name))
    # one pass over the included locations (not one per name: a large include would be quadratic)
    for sub, loc in included_locations.by_path.items():
        if sub[:2] in taken:
            locations.by_path[prefix + sub] = loc
