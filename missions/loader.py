"""Load mission YAML keeping the file, line and column of every node, with its includes.

`include:`d files are merged in (their trees, machines and keys) with their own positions;
include cycles and missing files are located problems like any other.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from robots.located_yaml import (
    MISSING_FILE,
    Loaded,
    Location,
    Locations,
    Path_,
    Problem,
    display_name,
    parse,
)

INCLUDABLE = ("trees", "machines", "keys")  # what an included file may contribute

__all__ = ["INCLUDABLE", "Loaded", "Location", "Locations", "Problem", "display_name", "load"]


def load(path: str | Path) -> Loaded:
    """Load a mission and everything it includes; problems are collected, never raised."""
    path = Path(path)
    locations = Locations(root=Location(display_name(path), 1, 1))
    problems: list[Problem] = []
    data = parse(path, problems, locations)
    files = [path]
    if data is MISSING_FILE:
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
        included = parse(target, problems, included_locations)
        if included is MISSING_FILE:
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
