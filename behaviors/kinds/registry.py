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
from importlib.metadata import entry_points

from behaviors.kinds.base import NodeKind
from skills.registry import PluginProblem

ENTRY_POINT_GROUP = "botstage.nodes"
BUILTIN_MODULES = ("behaviors.kinds.composites", "behaviors.kinds.decorators", "behaviors.kinds.leaves")


def _is_kind(value: object) -> bool:
    return isinstance(value, type) and issubclass(value, NodeKind) and bool(value.name)


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
        for ep in entry_points(group=group):
            label = f"{ep.name} = {ep.value}"
            try:
                value = ep.load()
            except Exception as exc:
                self.problems.append(PluginProblem(label, f"import failed: {type(exc).__name__}: {exc}"))
                continue
            if not _is_kind(value):
                self.problems.append(PluginProblem(label, "does not point to a NodeKind subclass with a name"))
                continue
            if value.name != ep.name:
                self.problems.append(
                    PluginProblem(label, f"entry point name differs from the kind's name {value.name!r}")
                )
                continue
            if value.name in self._kinds:
                if type(self._kinds[value.name]) is not value:
                    self.problems.append(
                        PluginProblem(label, f"node kind {value.name!r} already comes from {self._origin[value.name]}")
                    )
                continue
            dist = getattr(ep, "dist", None)
            self.register(value, origin=f"plugin {dist.name if dist else ep.value}")

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
