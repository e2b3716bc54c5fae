"""How `botstage` finds its verbs and loads each one only when it is used.

A verb is a Typer command function or a Typer sub-app named by ``module:attr``: the core's are
listed by the app module, a plug-in set's (botstage's own or a third party's) come from the
``botstage.commands`` entry-point group. Listing them for ``botstage --help`` imports none of their
modules: the one-line help is read from the verb's source (its function's docstring, or its
Typer's ``help=``), so the help costs milliseconds however heavy a verb's imports are. A verb's
module is imported when the verb runs or shows its own help. A plug-in verb whose module, or a
package it imports while running, is not installed says which pip extra brings it.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import typer
from typer.core import TyperCommand, TyperGroup

GROUP = "botstage.commands"


@dataclass(frozen=True)
class Verb:
    """A verb by name and where its command is (``module:attr``); a plug-in's also by its distribution."""

    name: str
    target: str
    distribution: str | None = None  # None: the core's
    extras: tuple[str, ...] = ()  # the entry point's [extras]: what `pip install` brings its dependencies

    @property
    def module(self) -> str:
        return self.target.partition(":")[0]

    @property
    def attr(self) -> str:
        return self.target.partition(":")[2]

    def install_hint(self) -> str:
        """What to install for this verb: ``pip install 'botstage[web]'``, or the distribution's name."""
        if self.distribution is None:
            return "reinstall botstage"
        extras = f"[{','.join(self.extras)}]" if self.extras else ""
        return f"pip install '{self.distribution}{extras}'"


@cache
def plugin_verbs() -> tuple[Verb, ...]:
    """The verbs the installed distributions register in ``botstage.commands`` (read once a process)."""
    from importlib.metadata import entry_points

    found = []
    for point in entry_points(group=GROUP):
        dist = getattr(point, "dist", None)
        found.append(
            Verb(point.name, point.value.split("[")[0].strip(), dist.name if dist else "?", tuple(point.extras))
        )
    return tuple(found)


def summary(verb: Verb) -> str:
    """The verb's help text as its source says it, without importing its module ('' if not found)."""
    try:
        spec = importlib.util.find_spec(verb.module)  # imports the parent packages, never the module
        source = Path(spec.origin).read_text(encoding="utf-8") if spec and spec.origin else ""
    except (ImportError, OSError, ValueError, UnicodeDecodeError):
        return ""
    return _help_in_source(source, verb.attr)


def _help_in_source(source: str, attr: str) -> str:
    text = "\n" + source
    for head in (f"\ndef {attr}(", f"\nasync def {attr}(", f"\n{attr} = ", f"\n{attr}: "):
        at = text.find(head)
        if at < 0:
            continue
        try:
            statement = ast.parse(_top_level_statement(text[at + 1 :])).body[0]
        except (SyntaxError, IndexError):
            return ""
        if isinstance(statement, ast.FunctionDef | ast.AsyncFunctionDef):
            return ast.get_docstring(statement) or ""
        call = getattr(statement, "value", None)
        for keyword in getattr(call, "keywords", []):
            if keyword.arg == "help" and isinstance(keyword.value, ast.Constant):
                return str(keyword.value.value)
        return ""
    return ""


def _top_level_statement(text: str) -> str:
    """The top-level statement ``text`` starts with: up to the next line at column 0 that does not
    close its brackets (a signature's ``) -> None:`` or a call's ``)``)."""
    lines = text.splitlines(keepends=True)
    taken = lines[:1]
    for line in lines[1:]:
        if line.strip() and not line[0].isspace() and not line.startswith(")"):
            break
        taken.append(line)
    return "".join(taken)


def to_command(name: str, obj: Any, group: TyperGroup) -> Any:
    """A Typer function or sub-app (or a Typer command already made) as the named click command."""
    if isinstance(obj, TyperCommand | TyperGroup):
        command = obj
    elif isinstance(obj, typer.Typer):
        command = typer.main.get_group(obj)  # a group even with one command: `speech recognize` stays
    elif callable(obj):
        info = typer.models.CommandInfo(name=name, callback=obj)
        command = typer.main.get_command_from_info(
            info, pretty_exceptions_short=True, rich_markup_mode=group.rich_markup_mode
        )
    else:
        raise TypeError(f"{type(obj).__name__} is not a Typer command or app")
    command.name = name
    return command


def missing_package(error: ImportError) -> str | None:
    """The top-level package an ImportError says is not installed (None: not that kind of error)."""
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    top = error.name.split(".")[0]
    return None if top == "botstage" else top


def _refusal(verb: Verb, error: ImportError) -> typer.Exit:
    from botstage.missions.cli.common import _fail

    package = missing_package(error)
    if package is None:  # the plug-in itself is broken: its distribution's problem, said in one line
        where = f"from {verb.distribution}" if verb.distribution else "botstage's"
        return _fail(f"error: `botstage {verb.name}` ({where}) cannot be loaded: {error}")
    origin = "botstage" if verb.distribution in (None, "botstage") else verb.distribution
    return _fail(
        f"error: `botstage {verb.name}` needs {package}, which is not installed: {verb.install_hint()} "
        f"(the command is {origin}'s {verb.module})"
    )


def _unavailable(verb: Verb, error: ImportError) -> TyperCommand:
    """A stand-in for a plug-in verb whose module cannot be imported: it says why, whatever it is given."""

    def refuse() -> None:
        raise _refusal(verb, error)

    return TyperCommand(
        name=verb.name,
        help=summary(verb),
        callback=refuse,
        add_help_option=False,
        context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
    )


class _Names(Mapping[str, Any]):
    """The group's ``commands``: names known without loading (Typer suggests close ones from them)."""

    def __init__(self, group: LazyGroup) -> None:
        self._group = group

    def __iter__(self) -> Iterator[str]:
        return iter(self._group.verbs())

    def __len__(self) -> int:
        return len(self._group.verbs())

    def __getitem__(self, name: str) -> Any:
        command = self._group.load(name)
        if command is None:
            raise KeyError(name)
        return command


class LazyGroup(TyperGroup):
    """The app's group: core verbs first, in their order, then plug-in verbs by name."""

    core: dict[str, str] = {}  # name -> module:attr, set by the app module

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.commands = _Names(self)  # type: ignore[assignment]
        self._loaded: dict[str, Any] = {}
        self._verbs: dict[str, Verb] | None = None
        self._listing = False
        self._running: Verb | None = None

    def verbs(self) -> dict[str, Verb]:
        """Every verb by name: the core's, then the plug-ins' (a name taken is kept by the first)."""
        if self._verbs is None:
            found = {name: Verb(name, target) for name, target in self.core.items()}
            for verb in sorted(plugin_verbs(), key=lambda verb: verb.name):
                if verb.name in found:
                    first = found[verb.name].distribution or "botstage's core"
                    sys.stderr.write(f"warning: `{verb.name}` from {verb.distribution} ignored: {first} has it\n")
                    continue
                found[verb.name] = verb
            self._verbs = found
        return self._verbs

    def list_commands(self, ctx: typer.Context) -> list[str]:
        return list(self.core) + [name for name in self.verbs() if name not in self.core]

    def get_command(self, ctx: typer.Context, cmd_name: str) -> Any:
        if self._listing and cmd_name not in self._loaded:
            verb = self.verbs().get(cmd_name)
            return None if verb is None else TyperCommand(name=cmd_name, help=summary(verb))
        return self.load(cmd_name)

    def load(self, name: str) -> Any:
        """The verb's command, its module imported now (None: no such verb)."""
        if name in self._loaded:
            return self._loaded[name]
        verb = Verb(name, self.core[name]) if name in self.core else self.verbs().get(name)
        if verb is None:
            return None
        try:
            obj = getattr(importlib.import_module(verb.module), verb.attr)
        except ImportError as error:
            if verb.distribution is None:
                raise  # a core verb always loads: anything else is botstage's bug
            command = _unavailable(verb, error)
        else:
            command = to_command(name, obj, self)
        self._running = verb
        self._loaded[name] = command
        return command

    def format_help(self, ctx: typer.Context, formatter: Any) -> None:
        self._listing = True
        try:
            super().format_help(ctx, formatter)
        finally:
            self._listing = False

    def invoke(self, ctx: typer.Context) -> Any:
        try:
            return super().invoke(ctx)
        except ImportError as error:
            verb = self._running
            if verb is None or verb.distribution is None or missing_package(error) is None:
                raise
            raise _refusal(verb, error) from None
