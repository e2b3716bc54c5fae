"""What a node needs from the run it belongs to, and nothing more.

Nodes (skills, decorators, machines, plug-in kinds) hold a ``Runtime``, never the engine: the
engine is one implementation of it, a test double can be another, and this module imports no
other part of ``behaviors`` so it is a leaf every node module may depend on.
"""

from __future__ import annotations

from collections.abc import Mapping
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import py_trees

    from botstage.behaviors.blackboard import Blackboard
    from botstage.behaviors.trace import Trace
    from botstage.robots.clock import Clock
    from botstage.skills.base import Outcome
    from botstage.skills.registry import Registry
    from botstage.skills.workers import Workers


class Runtime(Protocol):
    """The narrow services of one run: time, the event trace, keys, workers and devices."""

    clock: Clock
    trace: Trace
    blackboard: Blackboard
    workers: Workers
    interfaces: Mapping[str, Any]
    registry: Registry
    seed: int
    # outcomes an operator forces (fault injection, the live monitor): by node path or skill name,
    # each taken by the next tick of a node it names, which ends with it instead of running on
    forces: dict[str, Outcome]

    @property
    def halt_reason(self) -> str:
        """Why nodes are being halted right now (cancelled skills report it)."""
        ...

    def halting(self, reason: str) -> AbstractContextManager[None]:
        """Halt nodes inside this block for ``reason``."""
        ...

    def note_halt(self, node: py_trees.behaviour.Behaviour) -> None:
        """A running node was halted: record it so a restart shows as a new status change."""
        ...

    def log_sink(self, node: str, level: str, message: str) -> None:
        """Where a node's log lines go (the trace)."""
        ...
