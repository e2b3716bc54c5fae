"""What every verb group shares: the console, errors as one line per problem on stderr, and the
checks of option values (numbers, ports, paths) that make a bad value a usage error (exit 2)
before anything starts, instead of a traceback halfway through."""

from __future__ import annotations

import math
import os
import stat
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import typer
from rich.console import Console

console = Console()


def _fail(lines: list[str] | str, code: int = 1) -> typer.Exit:
    _stderr([lines] if isinstance(lines, str) else lines)
    return typer.Exit(code)


def _stderr(lines: list[str]) -> None:
    """One line per problem, never wrapped: editors and grep read `file:line:col: error: ...`."""
    sys.stderr.write("".join(line + "\n" for line in lines))
    sys.stderr.flush()


def os_problem(exc: OSError) -> str:
    """An OSError as a user reads it: the reason, then the path (no errno, no exception name)."""
    reason = exc.strerror or str(exc)
    where = exc.filename if exc.filename is not None else ""
    return f"{where}: {reason}" if where else reason


# -- numbers ------------------------------------------------------------------------------------


def number(*, gt: float | None = None, ge: float | None = None, le: float | None = None) -> Callable[[Any], Any]:
    """A typer callback: the option's number must be finite and within the bounds (None passes).

    The messages are pydantic's, as typer gives for a value that is not a number at all:
    ``Invalid value for '--until': input should be greater than 0``.
    """

    def show(bound: float) -> str:
        return str(int(bound)) if float(bound).is_integer() else f"{bound:g}"

    def check(value: Any) -> Any:
        if value is None:
            return None
        if isinstance(value, float) and not math.isfinite(value):
            raise typer.BadParameter("input should be a finite number")
        if gt is not None and not value > gt:
            raise typer.BadParameter(f"input should be greater than {show(gt)}")
        if ge is not None and not value >= ge:
            raise typer.BadParameter(f"input should be greater than or equal to {show(ge)}")
        if le is not None and not value <= le:
            raise typer.BadParameter(f"input should be less than or equal to {show(le)}")
        return value

    return check


POSITIVE = number(gt=0)  # a duration, a rate, a size
NON_NEGATIVE = number(ge=0)  # a seed, a tick
TCP_PORT = number(ge=0, le=65535)  # 0: the kernel picks a free port (where a command says so)


# -- paths --------------------------------------------------------------------------------------


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISREG(mode):
        return "a file"
    return "a special file (a device, a pipe or a socket)"


def _nearest_existing(path: Path) -> Path:
    for parent in path.absolute().parents:
        if parent.exists():
            return parent
    return Path("/")


def output_dir(value: Path | None) -> Path | None:
    """A typer callback: a folder to write into, existing or one that can be made (None passes)."""
    if value is None:
        return None
    try:
        mode = value.stat().st_mode
    except FileNotFoundError:
        parent = _nearest_existing(value)
        if not parent.is_dir():
            raise typer.BadParameter(f"cannot make folder {str(value)!r}: {str(parent)!r} is not a directory") from None
        if not os.access(parent, os.W_OK | os.X_OK):
            raise typer.BadParameter(f"cannot make folder {str(value)!r}: {str(parent)!r} is not writable") from None
        return value
    except OSError as exc:
        raise typer.BadParameter(f"{str(value)!r}: {exc.strerror or exc}") from None
    if not stat.S_ISDIR(mode):
        raise typer.BadParameter(f"{str(value)!r} is {_kind(mode)}, not a folder")
    if not os.access(value, os.W_OK | os.X_OK):
        raise typer.BadParameter(f"folder {str(value)!r} is not writable")
    return value


def output_file(value: Path | None) -> Path | None:
    """A typer callback: a file to write, in an existing folder; never a folder (None passes)."""
    if value is None:
        return None
    try:
        mode = value.stat().st_mode
    except FileNotFoundError:
        parent = value.absolute().parent
        if not parent.is_dir():
            raise typer.BadParameter(f"cannot write {str(value)!r}: no folder {str(parent)!r}") from None
        if not os.access(parent, os.W_OK | os.X_OK):
            raise typer.BadParameter(f"cannot write {str(value)!r}: folder {str(parent)!r} is not writable") from None
        return value
    except OSError as exc:
        raise typer.BadParameter(f"{str(value)!r}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise typer.BadParameter(f"{str(value)!r} is a directory, not a file")
    if not os.access(value, os.W_OK):
        raise typer.BadParameter(f"{str(value)!r} is not writable")
    return value


def _input_file(value: Path) -> Path:
    try:
        mode = value.stat().st_mode
    except OSError as exc:
        reason = "no such file" if isinstance(exc, FileNotFoundError) else exc.strerror or str(exc)
        raise typer.BadParameter(f"{str(value)!r}: {reason}") from None
    if not stat.S_ISREG(mode):
        raise typer.BadParameter(f"{str(value)!r} is {_kind(mode)}, not a file to read")
    if not os.access(value, os.R_OK):
        raise typer.BadParameter(f"{str(value)!r} is not readable")
    return value


def input_file(value: Path | None) -> Path | None:
    """A typer callback: an existing, readable regular file (a device or a pipe could be endless)."""
    return None if value is None else _input_file(value)


def input_files(values: list[Path] | None) -> list[Path] | None:
    """``input_file`` for each of a repeatable option's or an argument's paths."""
    return None if values is None else [_input_file(value) for value in values]


def input_paths(values: list[Path] | None) -> list[Path] | None:
    """Existing regular files or folders (folders are searched by the command)."""
    if values is None:
        return None
    return [value if value.is_dir() else _input_file(value) for value in values]


def no_special_files(values: list[Path] | None) -> list[Path] | None:
    """Paths that may be missing (the command says so) or folders, but never a device or a pipe."""
    for value in values or []:
        try:
            mode = value.stat().st_mode
        except OSError:
            continue  # missing or unreadable: the command reports it in its own way
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
            raise typer.BadParameter(f"{str(value)!r} is {_kind(mode)}, not a file to read")
    return values
