"""Finds backends by name: the built-in ones and third-party ones from the entry-point group.

Built-ins are registered exactly like plugins (``sim``, ``emulator``, ``hardware`` and ``ros2`` are also
declared under ``botstage.backends`` in pyproject.toml; the list here keeps an uninstalled
checkout working, and the same class from both is one backend). A broken plugin is recorded in
``problems``, never fatal: the other backends stay usable.
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from botstage.robots.backend import ENTRY_POINT_GROUP, Backend, BackendError, BackendKind, BackendOptions, OpenRequest
from botstage.robots.plugins import PluginProblem, discover, missing_extra

if TYPE_CHECKING:
    from botstage.robots.backend_options import OptionSources
    from botstage.robots.located_yaml import Locations

BUILTIN = ("botstage.robots.sim.kind:SimKind",)
DEFAULT = "sim"


def _not_a_kind(value: object) -> str:
    ok = isinstance(value, type) and issubclass(value, BackendKind) and value.name
    return "" if ok else "does not point to a BackendKind subclass with a name"


def _name(value: object) -> object:
    return getattr(value, "name", None)


def _load(spec: str) -> Any:
    module, _, attr = spec.partition(":")
    return getattr(importlib.import_module(module), attr)


def open_kind(kind: BackendKind, request: OpenRequest, options: BackendOptions) -> Backend:
    """``kind.open``, its reasons for not opening (bad start, no board on the port) as ``BackendError``."""
    try:
        return kind.open(request, options)
    except (ValueError, ConnectionError, OSError) as exc:
        raise BackendError(str(exc)) from None


class BackendRegistry:
    def __init__(self) -> None:
        self._kinds: dict[str, BackendKind] = {}
        self._origin: dict[str, str] = {}
        self.problems: list[PluginProblem] = []

    @classmethod
    def default(cls) -> BackendRegistry:
        """Built-in backends plus every installed plugin."""
        registry = cls.builtin()
        registry.load_entry_points()
        return registry

    @classmethod
    def builtin(cls) -> BackendRegistry:
        registry = cls()
        for spec in BUILTIN:
            registry.register(_load(spec), origin="builtin")
        return registry

    def register(self, kind: type[BackendKind] | BackendKind, *, origin: str = "", replace: bool = False) -> None:
        """Add a kind (a ``BackendKind`` subclass, or an instance of one) under its name."""
        instance = kind() if isinstance(kind, type) and issubclass(kind, BackendKind) else kind
        if not isinstance(instance, BackendKind) or not instance.name:
            raise TypeError(f"{kind!r} is not a BackendKind with a name")
        known = self._kinds.get(instance.name)
        if known is not None and type(known) is not type(instance) and not replace:
            raise ValueError(f"backend {instance.name!r} is already registered (from {self._origin[instance.name]})")
        if known is None or replace:
            self._kinds[instance.name] = instance
            self._origin[instance.name] = origin

    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> None:
        """Register plugins; a broken plugin is recorded in ``problems``, never fatal."""
        for plugin in discover(group, self.problems, what="backend", problem_of=_not_a_kind, name_of=_name):
            plugin.register(lambda kind, origin: self.register(kind, origin=origin), self.problems)

    def get(self, name: str) -> BackendKind:
        """The kind named ``name``; an unknown name's error lists what is installed."""
        try:
            return self._kinds[name]
        except KeyError:
            close = difflib.get_close_matches(name, list(self._kinds), n=1, cutoff=0.6)
            lacking = missing_extra(self.problems, name)
            if lacking:
                raise BackendError(f"backend {name!r} is in {lacking}") from None
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise BackendError(f"unknown backend {name!r}{hint}; installed: {self.listing()}") from None

    def origin(self, name: str) -> str:
        return self._origin[name]

    def listing(self) -> str:
        """One line: each installed backend with its description."""
        return "; ".join(f"{name} ({kind.description})" for name, kind in self.items())

    def items(self) -> list[tuple[str, BackendKind]]:
        """Built-ins first in their order, then plugins by name."""
        builtin = [n for n in self._kinds if self._origin[n] == "builtin"]
        others = sorted(n for n in self._kinds if self._origin[n] != "builtin")
        return [(name, self._kinds[name]) for name in builtin + others]

    def open(
        self,
        name: str,
        request: OpenRequest,
        given: OptionSources | None = None,
        locations: Locations | None = None,
    ) -> tuple[BackendKind, Backend]:
        """Open backend ``name`` for ``request`` with its options (profile's, then ``given``), checked first."""
        from botstage.robots.backend_options import resolve

        kind = self.get(name)
        options = resolve(kind, request.profile, locations, given)
        return kind, open_kind(kind, request, options)

    def __contains__(self, name: object) -> bool:
        return name in self._kinds

    def __iter__(self) -> Iterator[str]:
        return iter(name for name, _ in self.items())

    def __len__(self) -> int:
        return len(self._kinds)
