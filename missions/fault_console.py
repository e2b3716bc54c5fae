"""Faults typed at a board emulator's console, one a line: `botstage emulate` reads them from its
standard input so that a driver under test can be disturbed by hand while it runs."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robots.emulators.launchpad import LaunchpadEmulator

FAULTS = "garbage N, drop N, stall left|right|none, unplug SECONDS, reset, status"


def apply_fault(emulator: LaunchpadEmulator, line: str) -> str | None:
    """Carry out one typed line on the emulator; what to tell the operator, if anything."""
    words = line.split()
    try:
        if words[:1] == ["garbage"]:
            emulator.inject_garbage(int(words[1]))
        elif words[:1] == ["drop"]:
            emulator.drop_lines(int(words[1]))
        elif words[:1] == ["stall"]:
            emulator.stall(None if words[1] == "none" else words[1])
        elif words[:1] == ["unplug"]:
            emulator.disconnect(float(words[1]))
        elif words[:1] == ["reset"]:
            emulator.board_reset()
        elif words[:1] == ["status"]:
            pose = emulator.world.body.pose
            return (
                f"pose {pose.x:.3f} {pose.y:.3f} {pose.theta:+.3f}  motors {emulator.speeds}  {dict(emulator.counters)}"
            )
        elif words:
            return f"unknown fault {words[0]!r}"
    except (IndexError, ValueError):
        return f"cannot read {line.strip()!r}"
    return None
