"""Where a part of a mission built in Python was made: the caller's ``file:line:col``.

Recorded once per object as it is made (a walk up the frames and one position lookup, no source
parsing), so a mistake in a tree built in Python is reported at the line that built it, exactly
as a mistake in YAML is reported at its line.
"""

from __future__ import annotations

import itertools
import linecache
import os
import sys
from functools import lru_cache
from pathlib import Path
from types import FrameType

from botstage.missions.loader import Location, display_name

_PACKAGE = __name__.rpartition(".")[0]  # frames inside the API are not the caller


def _outside() -> FrameType | None:
    """The first frame that is not the API's own: the user's code that made the part."""
    frame: FrameType | None = sys._getframe(2)
    while frame is not None:
        module = frame.f_globals.get("__name__", "")
        if module != _PACKAGE and not module.startswith(_PACKAGE + "."):
            return frame
        frame = frame.f_back
    return None


def caller() -> Location:
    """Where the user's code called into the API: the start of the call expression."""
    frame = _outside()
    if frame is None:
        return Location("<python>", 1, 1)
    code = frame.f_code
    line, column = frame.f_lineno or 1, 0
    if frame.f_lasti >= 0:  # one position per 2-byte code unit; the call's spans the whole call
        position = next(itertools.islice(code.co_positions(), frame.f_lasti // 2, None), None)
        if position is not None and position[0] is not None:
            line, column = position[0], position[2] or 0
    return Location(_shown(code.co_filename, os.getcwd()), line, _character_column(code.co_filename, line, column))


def caller_file() -> Path:
    """The file of the user's code calling into the API (a mission's origin)."""
    frame = _outside()
    filename = frame.f_code.co_filename if frame is not None else "<python>"
    if filename.startswith("<"):  # a REPL or exec(): nothing on disk, name it like a file would be
        return Path.cwd() / "mission"
    return Path(filename).resolve()


@lru_cache(maxsize=256)
def _shown(filename: str, cwd: str) -> str:
    """As compilers print it: relative to the working directory (``cwd`` keys the cache)."""
    return filename if filename.startswith("<") else display_name(Path(filename))


def _character_column(filename: str, line: int, byte_column: int) -> int:
    """Python counts columns in UTF-8 bytes; editors and YAML locations count characters."""
    if byte_column:
        text = linecache.getline(filename, line)
        if text and not text.isascii():
            byte_column = len(text.encode("utf-8")[:byte_column].decode("utf-8", errors="ignore"))
    return byte_column + 1
