"""From the Python API's objects to the plain data a mission file holds, with where each part came from.

The engine, the checker and the runner only ever see this plain data (what the YAML front end
produces too), so a mission built in Python and its YAML twin cannot be told apart. Locations
are the Python source lines that made each part, merged over a YAML file's when the mission was
loaded from one.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from typing import Any

from botstage.missions.loader import Location, Locations, Problem

SpecPath = tuple[Any, ...]  # a place in the data: ("trees", "main", "sequence", 0)
PLAIN = (type(None), bool, int, float, str)


class Part:
    """Something the API builds (a node, a machine, a state): it lowers to plain data and
    remembers where it was made (None for a part read from a file, whose locations are the file's)."""

    where: Location | None = None

    def lower(self, low: Lowering, path: SpecPath) -> Any:
        raise NotImplementedError

    def as_node(self) -> Part:
        """This part where a tree node is expected."""
        raise TypeError(f"a {type(self).__name__} is not a tree node")

    def to_dict(self) -> Any:
        """The spec, as the YAML front end would produce it."""
        low = Lowering(root=self.where)
        data = low.value(self, ())
        low.raise_problems()
        return data


def in_order(data: dict[Any, Any], order: Iterable[Any] | None) -> dict[Any, Any]:
    """``data`` with the keys a file had in the file's order (the checker names the first of
    several unknown keys, so order is part of what a file says); new keys after them."""
    if not order:
        return data
    known = [k for k in order if k in data]
    return {**{k: data[k] for k in known}, **data}


class Lowering:
    """One pass from objects to data: the data, its Locations and the values that are not data."""

    def __init__(self, base: Locations | None = None, root: Location | None = None) -> None:
        by_path = dict(base.by_path) if base is not None else {}
        root = root or (base.root if base is not None else None) or Location("<python>", 1, 1)
        self.locations = Locations(by_path=by_path, root=root)
        self._purge = bool(by_path)  # a Python part replaces what a file said under its path
        self._unplain: list[tuple[SpecPath, str]] = []
        self._active: set[int] = set()

    def place(self, path: SpecPath, where: Location | None) -> None:
        if where is None:
            return
        if self._purge:
            for known in [p for p in self.locations.by_path if p[: len(path)] == path]:
                del self.locations.by_path[known]
        self.locations.by_path[path] = where

    def value(self, value: Any, path: SpecPath) -> Any:
        """``value`` as plain data; API objects lower themselves, recording where they were made."""
        if isinstance(value, Part):
            if id(value) in self._active:
                self._unplain.append((path, f"a {type(value).__name__} contains itself"))
                return None
            self.place(path, value.where)
            self._active.add(id(value))
            try:
                return value.lower(self, path)
            finally:
                self._active.discard(id(value))
        if isinstance(value, PLAIN):
            return value
        if isinstance(value, Mapping):
            data = {}
            for key, item in value.items():
                if not isinstance(key, PLAIN):
                    self._unplain.append((path, f"a mapping key must be a plain value, got {type(key).__name__}"))
                    continue
                data[key] = self.value(item, path + (key,))
            return data
        if isinstance(value, list | tuple):
            return [self.value(item, path + (index,)) for index, item in enumerate(value)]
        if isinstance(value, os.PathLike):
            return os.fspath(value)
        shown = repr(value)
        shown = shown if len(shown) <= 40 else shown[:37] + "..."
        self._unplain.append(
            (
                path,
                f"{type(value).__name__} {shown} cannot be written in a mission (use numbers, strings, "
                "booleans, lists, mappings or the API's objects)",
            )
        )
        return None

    def problems(self) -> list[Problem]:
        return [Problem(self.locations.find(path), message) for path, message in self._unplain]

    def raise_problems(self) -> None:
        problems = self.problems()
        if problems:
            raise ValueError("\n".join(str(p) for p in problems))
