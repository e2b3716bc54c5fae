"""What an operator does to a run by hand (the e-stop, driving the robot while the run is held),
done one way live (the monitor's control) and in a replay (a scenario's events), and said in the
trace in words both read: a run steered by hand replays as a scenario.

The trace records each action as a log line of node ``monitor``: the e-stop as ``ESTOP``; a
stretch of teleop as ``teleop v=… w=…`` each time the command changes (the first one starting the
stretch) and ``teleop ended``. Each teleop step is one tick period of the world with the tree held,
so the times of those lines give how long each command was held.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from botstage.missions.session.session import RunSession

ESTOP = "e-stop from the monitor"
ESTOP_RELEASED = "e-stop released by the operator"
TELEOP_ENDED = "teleop ended"
_TELEOP = re.compile(r"^teleop v=(?P<v>[-+0-9.e]+) w=(?P<w>[-+0-9.e]+)$")


def stop_everything(session: RunSession, reason: str = ESTOP) -> None:
    """Every skill cancelled with ``reason`` and the drive stopped (the mission restarts from its root
    at its next tick)."""
    if session.engine is not None:
        session.engine.halt(reason)
    drive = session.interfaces.get("drive")
    if drive is not None:
        drive.stop()


def drive_one_step(session: RunSession, v: float, w: float) -> None:
    """The robot driven by hand for one tick period: the world moves, the tree does not tick."""
    drive = session.interfaces.get("drive")
    if drive is not None:
        drive.cmd_vel(v, w)
    session.step_world()


def teleop_note(v: float, w: float) -> str:
    return f"teleop v={v:g} w={w:g}"


def read_teleop_note(message: str) -> tuple[float, float] | None:
    """The command a ``teleop v=… w=…`` line gives (None for any other line)."""
    found = _TELEOP.match(message)
    return (float(found["v"]), float(found["w"])) if found else None


@dataclass
class TeleopStretch:
    """Commands held for so many seconds of mission time, from a trace's teleop lines."""

    start: float
    commands: list[tuple[float, float, float]]  # (v, w, seconds)
    _last: tuple[float, float, float] | None = None  # (v, w, since)

    @classmethod
    def begin(cls, t: float, v: float, w: float) -> TeleopStretch:
        return cls(t, [], (v, w, t))

    def change(self, t: float, v: float, w: float) -> None:
        self._close(t)
        self._last = (v, w, t)

    def end(self, t: float) -> None:
        self._close(t)

    def _close(self, t: float) -> None:
        if self._last is not None:
            v, w, since = self._last
            if t > since:
                self.commands.append((v, w, round(t - since, 6)))
            self._last = None
