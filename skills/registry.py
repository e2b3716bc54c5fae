"""Finds skills by name: the built-in ones and third-party ones from the entry-point group.

A third-party package declares, in its pyproject.toml::

    [project.entry-points."botstage.skills"]
    my_skill = "my_package.my_module:MySkill"

Scenario tests replace a skill by name with a mock of the same contract (``with_override``),
so trees and machines cannot tell the difference.
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Iterable, Iterator
from importlib.metadata import entry_points

from botstage.robots.plugins import PluginProblem, discover, missing_extra
from botstage.skills.base import Skill

__all__ = ["ENTRY_POINT_GROUP", "PluginProblem", "Registry", "UnknownSkillError", "suggest"]

ENTRY_POINT_GROUP = "botstage.skills"
BUILTIN_MODULES = (
    "botstage.skills.wait",
    "botstage.skills.log",
    "botstage.skills.set",
    "botstage.skills.count",
    "botstage.skills.check",
    "botstage.skills.move",
    "botstage.skills.navigate",
    "botstage.skills.back_to_point",
    "botstage.skills.wander",
    "botstage.skills.approach",
    "botstage.skills.detect_crowd",
    "botstage.skills.recoveries",
    "botstage.skills.speak",
    "botstage.skills.upload",
    "botstage.skills.photo",
    "botstage.skills.display",
    "botstage.skills.wait_for",
    "botstage.skills.orders",
    "botstage.skills.monitors",
    "botstage.skills.gesture_drive",
    "botstage.skills.track_face",
)


class UnknownSkillError(LookupError):
    def __init__(self, name: str, known: Iterable[str], lacking: str = "") -> None:
        self.name = name
        self.suggestion = None if lacking else suggest(name, known)
        if lacking:  # the plug-in set that has it is not installed: say which and how
            super().__init__(f"skill {name!r} is in {lacking}")
            return
        hint = f" (did you mean {self.suggestion!r}?)" if self.suggestion else ""
        super().__init__(f"unknown skill {name!r}{hint}")


def suggest(name: str, known: Iterable[str]) -> str | None:
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return close[0] if close else None


def _not_a_skill(value: object) -> str:
    ok = isinstance(value, type) and issubclass(value, Skill) and value.name
    return "" if ok else "does not point to a Skill subclass with a name"


def _name(value: object) -> object:
    return getattr(value, "name", None)


class Registry:
    def __init__(self, skills: Iterable[type[Skill]] = ()) -> None:
        self._skills: dict[str, type[Skill]] = {}
        self._origin: dict[str, str] = {}
        self.problems: list[PluginProblem] = []
        for cls in skills:
            self.register(cls)

    @classmethod
    def default(cls) -> Registry:
        """Built-in skills plus every installed plugin."""
        registry = cls.builtin()
        registry.load_entry_points()
        return registry

    @classmethod
    def builtin(cls) -> Registry:
        """The skills botstage ships, without plugins."""
        registry = cls()
        for module_name in BUILTIN_MODULES:
            module = importlib.import_module(module_name)
            for value in vars(module).values():
                if (
                    isinstance(value, type)
                    and issubclass(value, Skill)
                    and value.name
                    and value.__module__ == module_name
                ):
                    registry.register(value, origin="builtin")
        return registry

    @classmethod
    def shipped(cls) -> Registry:
        """The skills a YAML mission has from botstage: the core's and those of its plug-in sets
        behind a pip extra that are installed (speech's ``listen``, chat's ``converse``), as the
        shipped mission schema lists them. Third parties' plug-ins are left out, and so are Nav2's
        leaves, which belong to the Nav2 node set that XML trees use."""
        registry = cls.builtin()
        behind_extras = entry_points(group=ENTRY_POINT_GROUP)
        own = {ep.name for ep in behind_extras if ep.extras and ep.value.startswith("botstage.")}
        for plugin in discover(ENTRY_POINT_GROUP, [], what="skill", problem_of=_not_a_skill, name_of=_name):
            if plugin.origin == "plugin botstage" and plugin.name in own:
                plugin.register(lambda value, origin: registry.register(value, origin=origin), registry.problems)
        return registry

    def register(self, cls: type[Skill], *, origin: str = "", replace: bool = False) -> None:
        if not (isinstance(cls, type) and issubclass(cls, Skill) and cls.name):
            raise TypeError(f"{cls!r} is not a Skill subclass with a name")
        if cls.name in self._skills and not replace and self._skills[cls.name] is not cls:
            raise ValueError(f"skill {cls.name!r} is already registered (from {self._origin[cls.name] or 'code'})")
        self._skills[cls.name] = cls
        self._origin[cls.name] = origin

    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> None:
        """Register plugins; a broken plugin is recorded in ``problems``, never fatal."""
        for plugin in discover(group, self.problems, what="skill", problem_of=_not_a_skill, name_of=_name):
            plugin.register(lambda cls, origin: self.register(cls, origin=origin), self.problems)

    def get(self, name: str) -> type[Skill]:
        try:
            return self._skills[name]
        except KeyError:
            raise UnknownSkillError(name, self._skills, missing_extra(self.problems, name)) from None

    def origin(self, name: str) -> str:
        return self._origin[name]

    def with_override(self, cls: type[Skill], name: str | None = None) -> Registry:
        """A copy where ``name`` (default: ``cls.name``) resolves to ``cls``."""
        copy = Registry()
        copy._skills = dict(self._skills)
        copy._origin = dict(self._origin)
        copy._skills[name or cls.name] = cls
        copy._origin[name or cls.name] = "override"
        return copy

    def __contains__(self, name: object) -> bool:
        return name in self._skills

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._skills))

    def __len__(self) -> int:
        return len(self._skills)
