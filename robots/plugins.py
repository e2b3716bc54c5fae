"""Plug-ins through entry points, found the same way for every registry (skills, node kinds,
backends, observers, services): a plug-in that cannot be imported, is not what its group takes,
or is registered under another name than its own is recorded as a problem, never fatal."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any


@dataclass(frozen=True, slots=True)
class PluginProblem:
    entry_point: str  # as declared: "name = module:attribute"
    reason: str


@dataclass(frozen=True, slots=True)
class Plugin:
    """One entry point, loaded and checked."""

    name: str
    value: Any
    origin: str  # "plugin <distribution>"
    label: str

    def register(self, register: Callable[[Any, str], None], problems: list[PluginProblem]) -> None:
        """Add it with ``register(value, origin)``; a refusal (a name taken) becomes a problem."""
        try:
            register(self.value, self.origin)
        except (TypeError, ValueError) as exc:
            problems.append(PluginProblem(self.label, str(exc)))


def discover(
    group: str,
    problems: list[PluginProblem],
    *,
    what: str,
    problem_of: Callable[[Any], str],
    name_of: Callable[[Any], object] = lambda value: None,
) -> Iterator[Plugin]:
    """The loadable plug-ins of ``group``. ``problem_of(value)`` says what is wrong with one
    ("" when nothing); ``name_of(value)`` is the name it declares itself, if any, which must be
    the entry point's."""
    for ep in entry_points(group=group):
        label = f"{ep.name} = {ep.value}"
        try:
            value = ep.load()
        except Exception as exc:
            problems.append(PluginProblem(label, f"import failed: {type(exc).__name__}: {exc}"))
            continue
        wrong = problem_of(value)
        if wrong:
            problems.append(PluginProblem(label, wrong))
            continue
        declared = name_of(value)
        if isinstance(declared, str) and declared and declared != ep.name:
            problems.append(PluginProblem(label, f"entry point name differs from the {what}'s name {declared!r}"))
            continue
        yield Plugin(ep.name, value, f"plugin {_distribution(ep)}", label)


_DISTRIBUTIONS: dict[object, str] = {}


def _distribution(ep: Any) -> str:
    """The name of the distribution declaring ``ep``, read once per distribution and process: each
    read parses the distribution's METADATA, and botstage alone declares some sixty entry points."""
    dist = getattr(ep, "dist", None)
    if dist is None:
        return ep.value
    where = getattr(dist, "_path", None)  # a distribution on disk: its .dist-info folder
    key = str(where) if where is not None else (ep.group, ep.name, ep.value)
    if key not in _DISTRIBUTIONS:
        _DISTRIBUTIONS[key] = dist.name
    return _DISTRIBUTIONS[key]
