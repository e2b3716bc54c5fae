"""Named run observers and run services: built-in ones and third-party ones from entry points.

A third-party package declares, in its pyproject.toml::

    [project.entry-points."botstage.observers"]   # enabled per run: botstage run --observe groot2
    groot2 = "my_package.groot:Groot2Publisher"

    [project.entry-points."botstage.services"]    # opened in every run, after the built-in ones
    elevator = "my_package.elevator:ElevatorService"

Each entry point names a factory (usually a class) called without arguments once per run.
Built-ins are registered exactly like plugins (and declared in botstage's own pyproject.toml; the
same object from both is one entry). A broken plugin is recorded in ``problems``, never fatal.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from botstage.missions.session.observer import HOOKS
from botstage.robots.plugins import PluginProblem, discover

OBSERVERS_GROUP = "botstage.observers"
SERVICES_GROUP = "botstage.services"
BUILTIN_OBSERVERS = ("console = botstage.missions.session.console:ConsoleLog",)
BUILTIN_SERVICES = (
    "robot = botstage.missions.session.services:RobotService",
    "uploads = botstage.missions.session.services:UploadsService",
    "files = botstage.missions.session.services:FilesService",
    "orders = botstage.missions.session.services:OrdersService",
)

Factory = Callable[[], Any]


def _name(factory: object) -> object:
    return getattr(factory, "name", None)


class PluginError(LookupError):
    """A named observer or service cannot be had: unknown, or its factory failed."""


class UnknownPlugin(PluginError):
    pass


def _load(value: str) -> Any:
    module, _, attr = value.partition(":")
    return getattr(importlib.import_module(module.strip()), attr.strip())


class PluginRegistry:
    """Factories by name for one entry-point group (observers or services)."""

    def __init__(self, group: str, what: str, check: Callable[[Any], str] | None = None) -> None:
        self.group = group
        self.what = what  # "observer" or "service", for messages
        self.check = check  # what is wrong with a factory ("" when nothing)
        self._factories: dict[str, Factory] = {}
        self._origin: dict[str, str] = {}
        self.problems: list[PluginProblem] = []

    @classmethod
    def with_builtins(
        cls,
        group: str,
        what: str,
        builtin: Sequence[str],
        plugins: bool = True,
        check: Callable[[Any], str] | None = None,
    ) -> PluginRegistry:
        registry = cls(group, what, check)
        for line in builtin:
            name, _, value = line.partition("=")
            registry.register(name.strip(), _load(value), origin="builtin")
        if plugins:
            registry.load_entry_points()
        return registry

    def register(self, name: str, factory: Factory, *, origin: str = "", replace: bool = False) -> None:
        if not callable(factory):
            raise TypeError(f"{self.what} {name!r}: {factory!r} is not a class or factory")
        known = self._factories.get(name)
        if known is not None and known is not factory and not replace:
            raise ValueError(f"{self.what} {name!r} is already registered (from {self._origin[name] or 'code'})")
        if known is None or replace:
            self._factories[name] = factory
            self._origin[name] = origin

    def load_entry_points(self) -> None:
        """Register plugins; a broken plugin is recorded in ``problems``, never fatal."""
        for plugin in discover(self.group, self.problems, what=self.what, problem_of=self._problem_of, name_of=_name):
            plugin.register(
                lambda factory, origin, name=plugin.name: self.register(name, factory, origin=origin), self.problems
            )

    def _problem_of(self, factory: Any) -> str:
        if not callable(factory):
            return f"does not point to a {self.what} class or factory"
        return self.check(factory) if self.check is not None else ""

    def get(self, name: str) -> Factory:
        try:
            return self._factories[name]
        except KeyError:
            close = difflib.get_close_matches(name, list(self._factories), n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            known = ", ".join(self) or "none"
            raise UnknownPlugin(f"unknown {self.what} {name!r}{hint}; installed: {known}") from None

    def create(self, name: str) -> Any:
        """A new instance of ``name`` (one per run); the instance knows its registered name."""
        factory = self.get(name)
        try:
            instance = factory()
        except Exception as exc:  # a plugin's bug: said with its name, never a traceback
            raise PluginError(f"{self.what} {name!r} cannot be made: {type(exc).__name__}: {exc}") from exc
        if not getattr(instance, "name", ""):
            with contextlib.suppress(AttributeError):  # a factory's object without a settable name
                instance.name = name
        return instance

    def origin(self, name: str) -> str:
        return self._origin[name]

    def description(self, name: str) -> str:
        """The first line of the factory's docstring."""
        doc = (self._factories[name].__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""

    def __iter__(self) -> Iterator[str]:
        """Built-ins first in their order, then plugins by name."""
        builtin = [n for n in self._factories if self._origin[n] == "builtin"]
        return iter(builtin + sorted(n for n in self._factories if self._origin[n] != "builtin"))

    def __contains__(self, name: object) -> bool:
        return name in self._factories

    def __len__(self) -> int:
        return len(self._factories)


def _observer_problem(factory: Any) -> str:
    if isinstance(factory, type) and not any(callable(getattr(factory, hook, None)) for hook in HOOKS):
        return f"has none of the observer hooks ({', '.join(HOOKS)})"
    return ""


def _service_problem(factory: Any) -> str:
    if isinstance(factory, type) and not all(callable(getattr(factory, m, None)) for m in ("open", "close")):
        return "a service needs open(session) and close()"
    return ""


def observer_registry(plugins: bool = True) -> PluginRegistry:
    """Observers a run can enable by name (``--observe NAME``)."""
    return PluginRegistry.with_builtins(OBSERVERS_GROUP, "observer", BUILTIN_OBSERVERS, plugins, _observer_problem)


def service_registry(plugins: bool = True) -> PluginRegistry:
    """The services every run opens, in order (the robot's first: the order of after-tick work)."""
    return PluginRegistry.with_builtins(SERVICES_GROUP, "service", BUILTIN_SERVICES, plugins, _service_problem)
