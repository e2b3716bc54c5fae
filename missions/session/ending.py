"""How a run ends: SIGTERM stops it as Ctrl-C does, and what its outcome and reason are."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.machine import MachineBehaviour, failure_reason


class SigtermLatch:
    """SIGTERM stops a run as cleanly as Ctrl-C does (skills cancelled, motors stopped), from the
    moment the run starts opening things: one that comes before the first tick is held and ends
    the run there (``pending``), so nothing is left half open and the results are still written."""

    def __init__(self) -> None:
        self.armed = False  # in the tick loop: raise at once
        self.pending = False

    def _handler(self, signum: int, frame: Any) -> None:
        if self.armed:
            raise KeyboardInterrupt
        self.pending = True

    @contextmanager
    def installed(self) -> Iterator[None]:
        try:
            previous = signal.signal(signal.SIGTERM, self._handler)
        except ValueError:  # not the main thread: leave signals alone
            yield
            return
        try:
            yield
        finally:
            signal.signal(signal.SIGTERM, previous)

    def arm(self) -> None:
        """From now on a SIGTERM interrupts; one that came already does so now."""
        self.armed = True
        if self.pending:
            raise KeyboardInterrupt


def outcome(
    error: str | None, root: py_trees.behaviour.Behaviour, until: float | None, interrupted: bool
) -> tuple[str, str]:
    """The run's outcome and reason: the root machine's, else the root's status, else the time limit."""
    if interrupted:
        return "interrupted", "interrupted by the operator"
    if error is not None:
        return "error", error
    ended = getattr(root, "outcome", None)
    if ended is not None:
        return ended.name, ended.reason
    if root.status in (Status.SUCCESS, Status.FAILURE):
        # a root tree that ended with the machine it runs beside its helpers (a display, a
        # battery watch) reports that machine's outcome: `docked` says more than `success`
        done = [c.outcome for c in root.children if isinstance(c, MachineBehaviour) and c.outcome is not None]
        if len(done) == 1:
            return done[0].name, done[0].reason
    if root.status is Status.SUCCESS:
        return "success", ""
    if root.status is Status.FAILURE:
        return "failure", failure_reason(root)
    return "time_limit", f"the time limit of {until:g} s of mission time was reached"
