"""The engine: one clock, one blackboard, one trace, one worker pool, and the tick loop.

Every node built for an engine shares these. ``tick()`` ticks the root once, records each
node whose status changed, then (on the sim clock) waits for work submitted during the tick
so its completion is observed at a deterministic tick, and finally steps the clock.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from typing import Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.blackboard import Blackboard
from botstage.behaviors.builder import Builder
from botstage.behaviors.kinds import NodeKinds
from botstage.behaviors.trace import Trace
from botstage.robots.clock import Clock, SimClock
from botstage.skills.base import Outcome
from botstage.skills.registry import Registry
from botstage.skills.workers import Workers


class Engine:
    """The run's clock, blackboard, trace, workers and devices (a ``Runtime`` for its nodes), and
    the tick loop over the root it is given."""

    def __init__(
        self,
        *,
        clock: Clock | None = None,
        registry: Registry | None = None,
        seed: int = 0,
        interfaces: Mapping[str, Any] | None = None,
        trace: Trace | None = None,
        workers: Workers | None = None,
        kinds: NodeKinds | None = None,
    ) -> None:
        self.clock: Clock = clock or SimClock()
        self.trace = trace or Trace(self.clock)
        self.blackboard = Blackboard(self.trace)
        self.registry = registry or Registry.default()
        self.kinds = kinds or NodeKinds.default()
        self.workers = workers or Workers()
        self.interfaces = dict(interfaces or {})
        self.seed = seed
        self.halt_reason = "halted"
        self.root: py_trees.behaviour.Behaviour | None = None
        self.status = Status.INVALID
        self.error: str | None = None
        self._last: dict[py_trees.behaviour.Behaviour, Status] = {}
        self.forces: dict[str, Outcome] = {}  # see Runtime.forces

    # -- building ---------------------------------------------------------------------------

    def builder(
        self,
        trees: Mapping[str, Any] | None = None,
        machines: Mapping[str, Any] | None = None,
        skill_params: Mapping[str, Mapping[str, Any]] | None = None,
    ) -> Builder:
        return Builder(self, trees, machines, skill_params, kinds=self.kinds)

    def set_root(self, root: py_trees.behaviour.Behaviour) -> None:
        self.root = root

    # -- services for nodes -----------------------------------------------------------------

    def log_sink(self, node: str, level: str, message: str) -> None:
        self.trace.emit("log", node, level, message)

    def note_halt(self, node: py_trees.behaviour.Behaviour) -> None:
        """A running node was halted: record it, so a restart shows as a new status change."""
        self._last[node] = Status.INVALID
        self.trace.emit("status", getattr(node, "path", node.name), "RUNNING", "INVALID", self.halt_reason)

    @contextlib.contextmanager
    def halting(self, reason: str) -> Iterator[None]:
        """Say why nodes are being halted; cancelled skills report this reason."""
        previous, self.halt_reason = self.halt_reason, reason
        try:
            yield
        finally:
            self.halt_reason = previous

    # -- running ----------------------------------------------------------------------------

    def tick(self) -> Status:
        root = self.root
        if root is None:
            raise RuntimeError("the engine has no root: call set_root() first")
        trace = self.trace
        trace.emit("tick")
        last = self._last
        try:
            for node in root.tick():
                status = node.status
                previous = last.get(node)
                if previous is not status:
                    last[node] = status
                    trace.emit(
                        "status",
                        getattr(node, "path", node.name),
                        previous.value if previous is not None else "INVALID",
                        status.value,
                        node.feedback_message,
                    )
        except Exception as exc:  # a bug below must not take the robot down with it
            self.error = f"{type(exc).__name__}: {exc}"
            trace.emit("error", self.error)
            self.halt(f"engine error: {self.error}")
            self.status = Status.FAILURE
        else:
            self.status = root.status
        trace.emit("tick_end", self.status.value)
        if self.clock.simulated:
            self.workers.drain()
        self.clock.next_tick()
        return self.status

    def run(self, *, until: float | None = None, max_ticks: int | None = None, stop_when_done: bool = True) -> Status:
        """Tick until the root finishes, ``until`` seconds of mission time pass, or ``max_ticks``."""
        ticks = 0
        while True:
            if until is not None and self.clock.now() >= until - 1e-9:
                break
            if max_ticks is not None and ticks >= max_ticks:
                break
            status = self.tick()
            ticks += 1
            if stop_when_done and status in (Status.SUCCESS, Status.FAILURE):
                break
        return self.status

    def halt(self, reason: str = "halted") -> None:
        """Stop whatever runs: every running skill is cancelled (its finally runs)."""
        if self.root is not None and self.root.status is not Status.INVALID:
            with self.halting(reason):
                try:
                    self.root.stop(Status.INVALID)
                except Exception as exc:
                    self.trace.emit("error", f"while halting: {type(exc).__name__}: {exc}")
                self._note_halted()

    def _note_halted(self) -> None:
        """Composites and machines halted with the root: their RUNNING ends in the trace too (skills
        said so as they were cancelled), so a halted tree never shows as running."""
        for node, last in self._last.items():
            if last is Status.RUNNING and node.status is Status.INVALID:
                self.note_halt(node)

    def close(self, reason: str = "shutdown") -> None:
        self.halt(reason)
        self.workers.shutdown()
        self.trace.flush()
        self.blackboard.close()

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
