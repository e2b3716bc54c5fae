"""What every verb group shares: the console, and errors as one line per problem on stderr."""

from __future__ import annotations

import sys

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
