"""Faults typed at a board emulator's console, one a line: `botstage emulate` reads them from its
standard input so that a driver under test can be disturbed by hand while it runs.

Every argument is read and bounded here, and every line gets an answer: a console that died on
one bad line (a count too large to allocate) would ignore every later one without a word.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from botstage.robots.emulators.launchpad import MAX_DROP, MAX_GARBAGE, MAX_UNPLUG_S, WHEELS

if TYPE_CHECKING:
    from botstage.robots.emulators.pty_board import PtyBoard

FAULTS = "garbage N, drop N, stall left|right|none (wheels only), unplug SECONDS, reset, status"
USAGE = {
    "garbage": f"garbage N: N random bytes, 1 to {MAX_GARBAGE:,}",
    "drop": f"drop N: lose the next N lines, 1 to {MAX_DROP:,}",
    "stall": "stall left|right|none",
    "unplug": f"unplug SECONDS: more than 0, at most {MAX_UNPLUG_S:g}",
    "reset": "reset (no argument)",
    "status": "status (no argument)",
}


class BadFault(ValueError):
    """A typed line that names no fault, or gives one a wrong argument."""


def _count(words: list[str], most: int) -> int:
    try:
        value = int(words[1])
    except ValueError:
        raise BadFault(f"{words[1]!r} is not a whole number") from None
    if not 1 <= value <= most:
        raise BadFault(f"{value} is out of range")
    return value


def _seconds(words: list[str]) -> float:
    try:
        value = float(words[1])
    except ValueError:
        raise BadFault(f"{words[1]!r} is not a number") from None
    if not math.isfinite(value) or not 0 < value <= MAX_UNPLUG_S:
        raise BadFault(f"{words[1]} is out of range")
    return value


def _run(emulator: PtyBoard, words: list[str]) -> str | None:
    fault = words[0]
    arguments = 1 if fault in ("garbage", "drop", "stall", "unplug") else 0
    if len(words) != 1 + arguments:
        raise BadFault("wrong number of arguments")
    if fault == "garbage":
        emulator.inject_garbage(_count(words, MAX_GARBAGE))
    elif fault == "drop":
        emulator.drop_lines(_count(words, MAX_DROP))
    elif fault == "stall":
        if not hasattr(emulator, "stall"):
            raise BadFault("this board drives no wheels")
        if words[1] not in (*WHEELS, "none"):
            raise BadFault(f"no wheel {words[1]!r}")
        emulator.stall(None if words[1] == "none" else words[1])
    elif fault == "unplug":
        emulator.disconnect(_seconds(words))
    elif fault == "reset":
        emulator.board_reset()
    else:
        pose = emulator.world.body.pose  # type: ignore[attr-defined]
        doing = (
            f"motors {emulator.speeds}" if hasattr(emulator, "speeds") else f"skill {getattr(emulator, 'skill', '?')}"
        )
        return f"pose {pose.x:.3f} {pose.y:.3f} {pose.theta:+.3f}  {doing}  {dict(emulator.counters)}"
    return None


def apply_fault(emulator: PtyBoard, line: str) -> str | None:
    """Carry out one typed line on the emulator; what to tell the operator, if anything. Never raises
    for a line's content: a bad one gets its reason and the usage of the fault it named."""
    words = line.split()
    if not words:
        return None
    if words[0] not in USAGE:
        return f"unknown fault {words[0]!r}; faults: {FAULTS}"
    try:
        return _run(emulator, words)
    except BadFault as exc:
        return f"cannot read {line.strip()!r}: {exc} (usage: {USAGE[words[0]]})"
    except (ValueError, OSError, MemoryError) as exc:  # the emulator refused: said, and the console goes on
        return f"cannot do {line.strip()!r}: {exc}"
