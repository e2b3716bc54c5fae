"""What `botstage tree` and `botstage machine` share: the picture formats, and a picture drawn and written."""

from __future__ import annotations

import sys
from pathlib import Path

from botstage.behaviors.render import FORMATS
from botstage.missions.cli.common import _fail, _stderr, os_problem

FORMAT_HELP = ", ".join(FORMATS[:-1]) + f" or {FORMATS[-1]}"


def draw(
    mission: Path,
    tree: str | None,
    machine: bool,
    fmt: str,
    output: Path | None,
    trace: Path | None,
    at: int | None,
    coverage: Path | None = None,
) -> None:
    from botstage.missions.pictures import InvalidMission, PictureError, picture

    def note(line: str) -> None:
        _stderr([line])

    if output is None and fmt == "png":  # said before the work, not after it
        raise _fail("error: png is binary: give a file with -o", 2)
    try:
        data = picture(mission, fmt, machine=machine, tree=tree, trace=trace, at=at, coverage=coverage, note=note)
    except InvalidMission as exc:
        raise _fail([str(p) for p in exc.problems]) from None
    except PictureError as exc:
        raise _fail(f"error: {exc}", 2) from None
    if output is None:
        sys.stdout.write(data.decode())
        return
    try:
        output.write_bytes(data)
    except OSError as exc:
        raise _fail(f"error: cannot write the picture: {os_problem(exc)}") from None
