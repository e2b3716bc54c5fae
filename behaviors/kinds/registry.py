"""Finds node kinds by name: botstage's own and those of installed plug-ins, registered alike.

A third-party package declares, in its pyproject.toml::

    [project.entry-points."botstage.nodes"]
    delay = "my_package.kinds:Delay"

where ``Delay`` subclasses ``CompositeKind``, ``DecoratorKind`` or ``LeafKind`` and its ``name``
is the entry point's name. The builder, the checker, the JSON Schema, the pictures and coverage
all read this registry, so a kind registered here is usable everywhere at once.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Iterator

from botstage.behaviors.kinds.base import NodeKind
from botstage.robots.plugins import PluginProblem, discover

ENTRY_POINT_GROUP = "botstage.nodes"
BUILTIN_MODULES = (
    "botstage.behaviors.kinds.composites",
    "botstage.behaviors.kinds.decorators",
    "botstage.behaviors.kinds.leaves",
    "botstage.behaviors.btcpp.nodes",  # BehaviorTree.CPP v4's built-in nodes, under their BT.CPP IDs
)


def _is_kind(value: object) -> bool:
    return isinstance(value, type) and issubclass(value, NodeKind) and bool(value.name)


def _not_a_kind(value: object) -> str:
    return "" if _is_kind(value) else "does not point to a NodeKind subclass with a name"


def _name(value: object) -> object:
    return getattr(value, "name", None)


class NodeKinds:
    """Node kinds by name, each with the origin it came from (builtin, a plug-in, code)."""

    def __init__(self, kinds: Iterable[NodeKind] = ()) -> None:
        self._kinds: dict[str, NodeKind] = {}
        self._origin: dict[str, str] = {}
        self.problems: list[PluginProblem] = []
        for kind in kinds:
            self.register(kind)

    @classmethod
    def default(cls) -> NodeKinds:
        """Built-in kinds plus every installed plug-in."""
        kinds = cls.builtin()
        kinds.load_entry_points()
        return kinds

    @classmethod
    def builtin(cls) -> NodeKinds:
        kinds = cls()
        for module_name in BUILTIN_MODULES:
            module = importlib.import_module(module_name)
            for value in vars(module).values():
                if _is_kind(value) and value.__module__ == module_name:
                    kinds.register(value(), origin="builtin")
        return kinds

    def register(self, kind: NodeKind | type[NodeKind], *, origin: str = "code") -> None:
        if isinstance(kind, type):
            kind = kind()
        if not (isinstance(kind, NodeKind) and kind.name):
            raise TypeError(f"{kind!r} is not a NodeKind with a name")
        if kind.name in self._kinds and type(self._kinds[kind.name]) is not type(kind):
            raise ValueError(f"node kind {kind.name!r} is already registered (from {self._origin[kind.name]})")
        self._kinds[kind.name] = kind
        self._origin[kind.name] = origin

    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> None:
        """Register plug-in kinds; a broken plug-in is recorded in ``problems``, never fatal."""
        for plugin in discover(group, self.problems, what="kind", problem_of=_not_a_kind, name_of=_name):
            plugin.register(lambda kind, origin: self.register(kind, origin=origin), self.problems)

    def get(self, name: str) -> NodeKind:
        return self._kinds[name]

    def origin(self, name: str) -> str:
        return self._origin[name]

    def __contains__(self, name: object) -> bool:
        return name in self._kinds

    def __iter__(self) -> Iterator[str]:
        return iter(self._kinds)

    def __len__(self) -> int:
        return len(self._kinds)
