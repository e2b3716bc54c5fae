"""Finds node kinds by name: botstage's own and those of installed plug-ins, registered alike.

Names are *scoped*, so one concept has one name where a user writes it. A mission's trees are
written in one scope (its ``nodes:``, ``botstage`` unless it says otherwise):

- ``botstage``: botstage's own kinds (``sequence``, ``selector``, ``timeout``, ...) and plug-in
  kinds registered one by one. This is what a YAML mission sees.
- a plug-in scope such as ``btcpp`` (what a BehaviorTree.CPP XML file sees): the node sets that
  declare that scope (BT.CPP's built-in nodes, Nav2's), plus everything of ``botstage``, which
  XML holds as custom nodes (what ``botstage export`` writes), as BT.CPP's factory holds
  registered custom nodes beside its own.

A third-party package declares one kind, visible in every scope, in its pyproject.toml::

    [project.entry-points."botstage.nodes"]
    delay = "my_package.kinds:Delay"

where ``Delay`` subclasses ``CompositeKind``, ``DecoratorKind`` or ``LeafKind`` and its ``name``
is the entry point's name; or a whole ``NodeSet`` for one scope, named as its entry point
(BT.CPP's set registers itself so: ``btcpp = "botstage.behaviors.btcpp.nodes:NODE_SET"``).
The builder, the checker, the JSON Schema, the pictures and coverage all read this registry, so
a kind registered here is usable everywhere at once.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from botstage.behaviors.kinds.base import NodeKind
from botstage.robots.plugins import PluginProblem, discover

ENTRY_POINT_GROUP = "botstage.nodes"
CORE_SCOPE = "botstage"  # what a YAML mission sees
CORE_MODULES = (
    "botstage.behaviors.kinds.composites",
    "botstage.behaviors.kinds.decorators",
    "botstage.behaviors.kinds.leaves",
)


@dataclass(frozen=True)
class NodeSet:
    """A plug-in's node set that exists only in one scope: a tool's own vocabulary (BT.CPP's
    built-in nodes) must not sit beside botstage's under names that differ only in case."""

    name: str
    scope: str
    kinds: tuple[type[NodeKind], ...]
    description: str = ""


def _is_kind(value: object) -> bool:
    return isinstance(value, type) and issubclass(value, NodeKind) and bool(value.name)


def _not_a_kind(value: object) -> str:
    if _is_kind(value) or isinstance(value, NodeSet):
        return ""
    return "does not point to a NodeKind subclass with a name, nor a NodeSet"


def _name(value: object) -> object:
    return getattr(value, "name", None)


class NodeKinds:
    """Node kinds by name in one scope, each with the origin it came from (builtin, a plug-in, code)
    and the node set it belongs to (``botstage`` for botstage's own and single plug-in kinds)."""

    def __init__(self, kinds: Iterable[NodeKind] = (), *, scope: str = CORE_SCOPE) -> None:
        self.scope = scope
        self._kinds: dict[str, NodeKind] = {}
        self._origin: dict[str, str] = {}
        self._set: dict[str, str] = {}
        self.aliases: dict[str, str] = {}  # an old spelling kept readable -> its one listed kind
        self.sets: dict[str, NodeSet] = {}  # node sets of this scope, by name
        self.problems: list[PluginProblem] = []
        for kind in kinds:
            self.register(kind)

    @classmethod
    def default(cls, scope: str = CORE_SCOPE) -> NodeKinds:
        """botstage's kinds plus every installed plug-in, as ``scope`` sees them."""
        kinds = cls.builtin(scope)
        kinds.load_entry_points()
        return kinds

    @classmethod
    def builtin(cls, scope: str = CORE_SCOPE) -> NodeKinds:
        """botstage's own kinds only (no plug-in)."""
        kinds = cls(scope=scope)
        for module_name in CORE_MODULES:
            module = importlib.import_module(module_name)
            for value in vars(module).values():
                if _is_kind(value) and value.__module__ == module_name:
                    kinds.register(value(), origin="builtin")
        return kinds

    def register(self, kind: NodeKind | type[NodeKind], *, origin: str = "code", node_set: str = CORE_SCOPE) -> None:
        if isinstance(kind, type):
            kind = kind()
        if not (isinstance(kind, NodeKind) and kind.name):
            raise TypeError(f"{kind!r} is not a NodeKind with a name")
        for name in (kind.name, *kind.aliases):
            if name in self and type(self.get(name)) is not type(kind):
                raise ValueError(
                    f"node kind {name!r} is already registered (from {self._origin[self._canonical(name)]})"
                )
        self._kinds[kind.name] = kind
        self._origin[kind.name] = origin
        self._set[kind.name] = node_set
        for alias in kind.aliases:
            self.aliases[alias] = kind.name

    def register_set(self, node_set: NodeSet, *, origin: str = "code") -> None:
        """Register a node set's kinds if it belongs to this scope (a set of another scope is kept
        out: its names are not this scope's)."""
        if node_set.scope != self.scope:
            return
        self.sets[node_set.name] = node_set
        for kind in node_set.kinds:
            self.register(kind, origin=origin, node_set=node_set.name)

    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> None:
        """Register plug-in kinds and node sets; a broken plug-in is recorded in ``problems``, never fatal."""
        for plugin in discover(group, self.problems, what="kind", problem_of=_not_a_kind, name_of=_name):
            plugin.register(self._register_plugin, self.problems)

    def _register_plugin(self, value: NodeSet | type[NodeKind], origin: str) -> None:
        if isinstance(value, NodeSet):
            self.register_set(value, origin=origin)
        else:
            self.register(value, origin=origin)

    def _canonical(self, name: str) -> str:
        return self.aliases.get(name, name)

    def get(self, name: str) -> NodeKind:
        return self._kinds[self._canonical(name)]

    def origin(self, name: str) -> str:
        return self._origin[self._canonical(name)]

    def node_set(self, name: str) -> str:
        """The node set a kind belongs to: ``botstage`` for botstage's own and single plug-in kinds."""
        return self._set[self._canonical(name)]

    def scoped(self) -> list[str]:
        """The kinds this scope's own node sets bring (none in ``botstage``): in XML, the nodes
        whose ports are written as they are, not botstage's kinds written as custom nodes."""
        return [name for name in self._kinds if self._set[name] != CORE_SCOPE]

    def listed(self) -> list[str]:
        """What a listing of this scope shows: in ``botstage`` every kind; in a plug-in scope only
        its sets' kinds (botstage's are listed once, under their own scope), so no listing holds one
        concept under two names. Aliases are never listed."""
        return list(self._kinds) if self.scope == CORE_SCOPE else self.scoped()

    def __contains__(self, name: object) -> bool:
        return name in self._kinds or name in self.aliases

    def __iter__(self) -> Iterator[str]:
        """Every kind of this scope by its one name (aliases left out)."""
        return iter(self._kinds)

    def __len__(self) -> int:
        return len(self._kinds)
