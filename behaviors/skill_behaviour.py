"""A skill as a py_trees Behaviour: ports bound to blackboard keys or literals.

Guarantees the engine promises users:
- halting the node cancels the skill (its ``finally`` has run) before the halt returns;
- before an *action* skill starts, any running lower-priority branch of a reactive selector
  above it is halted first, so two actions never overlap (py_trees would start the new
  branch and only then halt the old one);
- whatever the skill does (raise, return an undeclared outcome, read a key nobody wrote)
  ends as FAILURE with a reason in the trace, never as an exception in the tree.
"""

from __future__ import annotations

import contextlib
import random
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.blackboard import BlackboardError
from botstage.behaviors.trace import jsonable
from botstage.skills.base import FAILURE, Outcome, Skill, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.expression import ExpressionError, compile_expression

if TYPE_CHECKING:
    from botstage.behaviors.runtime import Runtime

_NO_OUTPUTS: dict[str, Any] = {}  # shared by every trace event without outputs; never mutated


@dataclass(frozen=True, slots=True)
class KeyRef:
    """An input bound to a blackboard key rather than a literal."""

    key: str

    def __str__(self) -> str:
        return "{" + self.key + "}"


def access_for(
    skill_cls: type[Skill], inputs: Mapping[str, Any], outputs: Mapping[str, str]
) -> tuple[set[str], set[str]]:
    """The keys a skill node reads and writes, from its bindings and port declarations."""
    reads: set[str] = set()
    writes: set[str] = set(outputs.values())
    for port_name, value in inputs.items():
        port = skill_cls.inputs.get(port_name)
        if isinstance(value, KeyRef):
            reads.add(value.key)
        elif port is not None and isinstance(value, str):
            if port.expression:
                with contextlib.suppress(ExpressionError):  # reported by the builder with its location
                    reads |= compile_expression(value).keys
            elif port.names_key == "read":
                reads.add(value)
            elif port.names_key == "write":
                writes.add(value)
    return reads, writes


class SkillBehaviour(py_trees.behaviour.Behaviour):
    def __init__(
        self,
        name: str,
        path: str,
        skill: Skill,
        runtime: Runtime,
        inputs: Mapping[str, Any] | None = None,
        outputs: Mapping[str, str] | None = None,
        success_on: frozenset[str] = frozenset({"success"}),
    ) -> None:
        super().__init__(name)
        self.path = path
        self.skill = skill
        self.runtime = runtime
        self.inputs = dict(inputs or {})
        self.outputs = dict(outputs or {})
        self.success_on = success_on
        self.outcome: Outcome | None = None
        reads, writes = access_for(type(skill), self.inputs, self.outputs)
        self.access = runtime.blackboard.client(path, reads=reads, writes=writes)
        ctx = SkillContext(
            clock=runtime.clock,
            params=skill.params,
            logger=SkillLogger(path, sink=runtime.log_sink),
            blackboard=self.access,
            workers=runtime.workers,
            interfaces=runtime.interfaces,
            rng=random.Random(f"{runtime.seed}:{path}"),
            node=path,
        )
        self.execution = SkillExecution(skill, ctx)
        self._has_refs = any(isinstance(v, KeyRef) for v in self.inputs.values())
        self._shown_inputs = jsonable(self.inputs)
        self._first: Outcome | None = None
        self._fresh = False
        self._preempts = skill.kind == "action"
        self._failed_at_start = False
        self._selectors: list[tuple[py_trees.composites.Selector, py_trees.behaviour.Behaviour]] | None = None

    # -- py_trees hooks ---------------------------------------------------------------------

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        """Behaviour.tick without its per-tick debug formatting: same semantics, on the hot path."""
        if self.status is not Status.RUNNING:
            self.initialise()
        new_status = self.update()
        if new_status is not Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self

    def stop(self, new_status: Status) -> None:
        halted = new_status is Status.INVALID and self.status is Status.RUNNING
        self.terminate(new_status)
        self.status = new_status
        if halted:
            self.runtime.note_halt(self)

    def initialise(self) -> None:
        # An action that failed at once on its last try is not let to preempt: it would cancel
        # the lower-priority branch on every tick and never run itself (a livelock).
        if self._preempts and not self._failed_at_start and (self._selectors is None or self._selectors):
            self._halt_lower_priority()
        self._fresh = True
        self.outcome = None
        self.feedback_message = ""
        try:
            inputs = self._resolve_inputs() if self._has_refs else self.inputs
        except BlackboardError as exc:
            self._first = Outcome(FAILURE, str(exc))
            return
        shown = self._shown_inputs if inputs is self.inputs else jsonable(inputs)
        self.runtime.trace.emit("skill_start", self.path, self.skill.name, shown)
        self._first = self.execution.start(inputs)

    def update(self) -> Status:
        if self.runtime.forces and (forced := self._take_forced()) is not None:
            return self._finish(forced)
        if self._fresh:
            self._fresh = False
            outcome = self._first
            self._first = None
            self._failed_at_start = outcome is not None and outcome.name not in self.success_on
        else:
            outcome = self.execution.step()
        if outcome is None:
            return Status.RUNNING
        return self._finish(outcome)

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID and self.execution.running:
            problem = self.execution.cancel()
            reason = self.runtime.halt_reason
            if problem:
                reason = f"{reason}; {problem}"
            self.runtime.trace.emit("skill_cancel", self.path, self.skill.name, reason)
            self.feedback_message = f"cancelled: {reason}"

    # -- internals --------------------------------------------------------------------------

    def _take_forced(self) -> Outcome | None:
        """An outcome the operator forces on this node (by path, else by skill): the running call
        is cancelled (its finally runs) and the node ends with the forced outcome instead."""
        forces = self.runtime.forces
        forced = forces.pop(self.path, None) or forces.pop(self.skill.name, None)
        if forced is None:
            return None
        self._fresh, self._first = False, None
        if self.execution.running:
            self.execution.cancel()
        return forced

    def _resolve_inputs(self) -> dict[str, Any]:
        get = self.access.get
        return {k: get(v.key) if isinstance(v, KeyRef) else v for k, v in self.inputs.items()}

    def _finish(self, outcome: Outcome) -> Status:
        if outcome.outputs and self.outputs:
            try:
                for port, key in self.outputs.items():
                    if port in outcome.outputs:
                        self.access.set(key, outcome.outputs[port])
            except BlackboardError as exc:
                outcome = Outcome(FAILURE, f"could not write output {port!r}: {exc}", outcome.outputs)
        self.outcome = outcome
        self.feedback_message = outcome.reason
        self.runtime.trace.emit(
            "skill_outcome",
            self.path,
            self.skill.name,
            outcome.name,
            outcome.reason,
            jsonable(outcome.outputs) if outcome.outputs else _NO_OUTPUTS,
        )
        return Status.SUCCESS if outcome.name in self.success_on else Status.FAILURE

    def _halt_lower_priority(self) -> None:
        selectors = self._selectors
        if selectors is None:
            selectors = self._selectors = reactive_selectors_above(self)
        for selector, branch in selectors:
            current = selector.current_child
            if current is None or current is branch or current.status is not Status.RUNNING:
                continue
            children = selector.children
            if children.index(current) > children.index(branch):
                with self.runtime.halting(f"preempted by higher-priority {self.path!r}"):
                    current.stop(Status.INVALID)


def reactive_selectors_above(
    node: py_trees.behaviour.Behaviour,
) -> list[tuple[py_trees.composites.Selector, py_trees.behaviour.Behaviour]]:
    """Each selector without memory above ``node``, with the child of it that leads to ``node``."""
    found = []
    child, parent = node, node.parent
    while parent is not None:
        if isinstance(parent, py_trees.composites.Selector) and not parent.memory:
            found.append((parent, child))
        child, parent = parent, parent.parent
    return found
