"""Plug-ins through entry points, found the same way for every registry (skills, node kinds,
backends, observers, services): a plug-in that cannot be imported, is not what its group takes,
or is registered under another name than its own is recorded as a problem, never fatal.

botstage's own plug-in sets (hardware, ros2, speech, chat, web, …) are declared the same way, each
entry point naming its pip extra (``listen = botstage.skills.listen:Listen [speech]``). When that
extra's packages are not installed the entry point is not imported at all: it is recorded as a
problem that names the extra, so a mission that uses it is told what to install."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from importlib.metadata import PackageNotFoundError, distribution, entry_points, version
from typing import Any


@dataclass(frozen=True, slots=True)
class PluginProblem:
    entry_point: str  # as declared: "name = module:attribute"
    reason: str
    extra: str = ""  # the pip extra of its distribution that is not installed, if that is why

    @property
    def name(self) -> str:
        return self.entry_point.partition("=")[0].strip()


def install_hint(distribution_name: str, extra: str) -> str:
    return f"pip install '{distribution_name}[{extra}]'"


def missing_extra(problems: list[PluginProblem], name: str) -> str:
    """Which plug-in set would provide ``name`` and how to install it ("" if none would)."""
    for problem in problems:
        if problem.extra and problem.name == name:
            return problem.reason
    return ""


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
        lacking = _lacking_extra(ep)
        if lacking:
            dist_name = _distribution(ep)
            reason = f"{dist_name}'s {lacking} set, which is not installed: {install_hint(dist_name, lacking)}"
            problems.append(PluginProblem(label, reason, lacking))
            continue
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


def _lacking_extra(ep: Any) -> str:
    """The first of ``ep``'s extras whose requirements are not all installed ("" when none)."""
    dist = getattr(ep, "dist", None)
    if not ep.extras or dist is None:
        return ""
    return next((extra for extra in ep.extras if not _extra_installed(dist.name, extra)), "")


@cache
def _extra_installed(dist_name: str, extra: str) -> bool:
    """Whether every package ``dist_name[extra]`` requires is installed (by name: the versions
    were pip's business)."""
    try:
        requires = distribution(dist_name).requires or []
    except PackageNotFoundError:
        return False
    marker = f'extra == "{extra}"'
    for requirement in requires:
        spec, _, markers = requirement.partition(";")
        if marker not in markers.replace("'", '"'):
            continue
        name = spec.strip().split("[")[0]
        for stop in "<>=!~ (":
            name = name.split(stop)[0]
        try:
            version(name.strip())
        except PackageNotFoundError:
            return False
    return True
