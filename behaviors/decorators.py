"""Decorators that need the mission clock or blackboard conditions.

py_trees' own Timeout reads the wall clock, and its EternalGuard takes Python callables; these
take the mission clock and a condition from ``botstage.skills.expression`` instead, and always leave a
reason for the trace when they fail.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import py_trees
from py_trees.common import Status

from botstage.behaviors.blackboard import BlackboardError
from botstage.skills.expression import EvaluationError, Expression

if TYPE_CHECKING:
    from botstage.behaviors.runtime import Runtime


class _ReasonedDecorator(py_trees.decorators.Decorator):
    """A decorator that can fail on its own, halting its child and saying why."""

    runtime: Runtime

    def _fail(self, feedback: str, halt_reason: str) -> Iterator[py_trees.behaviour.Behaviour]:
        self.feedback_message = feedback
        with self.runtime.halting(halt_reason):
            self.stop(Status.FAILURE)
        yield self

    def update(self) -> Status:
        self.feedback_message = self.decorated.feedback_message
        return self.decorated.status


class ClockTimeout(_ReasonedDecorator):
    """Fail, halting the child, when it has run for ``duration`` seconds of mission time."""

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, duration: float, runtime: Runtime) -> None:
        super().__init__(name=name, child=child)
        self.duration = duration
        self.runtime = runtime
        self._deadline = 0.0

    def initialise(self) -> None:
        self._deadline = self.runtime.clock.now() + self.duration - 1e-9

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status is Status.RUNNING and self.runtime.clock.now() >= self._deadline:
            why = f"timed out after {self.duration:g} s"
            yield from self._fail(why, f"timeout of {self.path!r} after {self.duration:g} s")
            return
        yield from super().tick()


class Guard(_ReasonedDecorator):
    """Run the child only while a condition holds.

    ``mode="while"`` (an eternal guard) checks before every tick and halts a running child the
    moment the condition turns false; ``mode="if"`` checks only before the child starts.
    Either way a false condition is FAILURE with the condition as the reason.
    """

    def __init__(
        self,
        name: str,
        child: py_trees.behaviour.Behaviour,
        condition: Expression,
        mode: str,
        runtime: Runtime,
        path: str,
    ) -> None:
        super().__init__(name=name, child=child)
        if mode not in ("while", "if"):
            raise ValueError(f"guard mode must be 'while' or 'if', got {mode!r}")
        self.condition = condition
        self.mode = mode
        self.runtime = runtime
        self.path = path
        self.access = runtime.blackboard.client(path, reads=condition.keys)

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.mode == "while" or self.status is not Status.RUNNING:
            try:
                holds = self.condition.test(self.access.get)
                why = f"guard {self.condition.source!r} is false"
            except (BlackboardError, EvaluationError) as exc:
                holds, why = False, f"guard {self.condition.source!r} cannot be evaluated: {exc}"
            if not holds:
                yield from self._fail(why, why)
                return
        yield from super().tick()
