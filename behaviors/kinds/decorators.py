"""The built-in decorators: inverting and forcing results, one shot, retry, repeat, timeouts
on the mission clock, and guards on blackboard conditions."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, ClassVar, Literal

import py_trees
from py_trees.common import Status
from pydantic import Field

from botstage.behaviors.decorators import ClockTimeout, Guard
from botstage.behaviors.kinds.base import DecoratorKind, KindOptions, NodeBuild
from botstage.robots.limits import MAX_SECONDS, MAX_TIMES, PositiveSeconds, Seconds, Times

if TYPE_CHECKING:
    from botstage.behaviors.runtime import Runtime


class Inverter(DecoratorKind):
    name = "inverter"
    description = "success becomes failure and failure success"
    behaviour: ClassVar[type[py_trees.decorators.Decorator]] = py_trees.decorators.Inverter

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return self.behaviour(name=b.name, child=b.child)


class ForceSuccess(Inverter):
    name = "force_success"
    description = "failure becomes success"
    behaviour = py_trees.decorators.FailureIsSuccess


class ForceFailure(Inverter):
    name = "force_failure"
    description = "success becomes failure"
    behaviour = py_trees.decorators.SuccessIsFailure


class OneShotOptions(KindOptions):
    policy: str = Field(
        default="on_success",
        description="keep the result after the first success, or after the first completion",
        json_schema_extra={"enum": ["on_success", "on_completion"]},
    )


class OneShot(DecoratorKind):
    name = "one_shot"
    description = "run the child until it succeeds (or completes), then keep that result"
    Options = OneShotOptions
    POLICIES: ClassVar[dict[str, py_trees.common.OneShotPolicy]] = {
        "on_success": py_trees.common.OneShotPolicy.ON_SUCCESSFUL_COMPLETION,
        "on_completion": py_trees.common.OneShotPolicy.ON_COMPLETION,
    }

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        policy = b.options.policy
        if policy not in self.POLICIES:
            b.problem("one_shot policy must be on_success or on_completion", "policy")
            policy = "on_success"
        return py_trees.decorators.OneShot(name=b.name, child=b.child, policy=self.POLICIES[policy])

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return "one shot"


class Retry(DecoratorKind):
    name = "retry"
    description = "run the child again after a failure, up to this many failures"
    argument = Times
    argument_help = f"a whole number of times from 1 to {MAX_TIMES:,}"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return py_trees.decorators.Retry(name=b.name, child=b.child, num_failures=b.value)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"retry ×{node.num_failures}"


class Repeat(DecoratorKind):
    name = "repeat"
    description = "run the child again after a success, this many successes in all (or forever)"
    argument = Times | Literal["forever", -1]
    argument_help = f"a whole number of times from 1 to {MAX_TIMES:,}, or 'forever'"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        times = -1 if b.value in ("forever", -1) else b.value
        return py_trees.decorators.Repeat(name=b.name, child=b.child, num_success=times)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return "repeat forever" if node.num_success == -1 else f"repeat ×{node.num_success}"


class Timeout(DecoratorKind):
    name = "timeout"
    description = "fail, halting the child, after this many seconds of mission time"
    argument = PositiveSeconds
    argument_help = f"a positive number of seconds, at most {MAX_SECONDS:,.0f}"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        node = ClockTimeout(name=b.name, child=b.child, duration=float(b.value), runtime=b.runtime)
        node.path = b.path
        return node

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"timeout {node.duration:g} s"


class While(DecoratorKind):
    """An eternal guard: checked before every tick, halting the child the moment it is false."""

    name = "while"
    description = "run the child while the condition holds; fail (halting it) when it turns false"
    argument = str
    argument_help = "a condition (a string)"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        condition = b.expression(b.value, self.name)
        if condition is None:
            return None
        return Guard(name=b.name, child=b.child, condition=condition, mode=self.name, runtime=b.runtime, path=b.path)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"{node.mode} {node.condition.source}"


class If(While):
    name = "if"
    description = "start the child only if the condition holds, else fail"


class _DelayBehaviour(py_trees.decorators.Decorator):
    """RUNNING for ``duration`` seconds of mission time after it starts, then the child's status.

    BehaviorTree.CPP's Delay: the wait starts again whenever the node is (re)started or halted.
    """

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, duration: float, runtime: Runtime) -> None:
        super().__init__(name=name, child=child)
        self.duration = duration
        self.runtime = runtime
        self._ready_at = 0.0

    def initialise(self) -> None:
        self._ready_at = self.runtime.clock.now() + self.duration - 1e-9

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status is not Status.RUNNING:
            self.initialise()
        if self.runtime.clock.now() < self._ready_at:
            self.status = Status.RUNNING
            self.feedback_message = f"waiting {self.duration:g} s"
            yield self
            return
        yield from super().tick()

    def update(self) -> Status:
        return self.decorated.status


class Delay(DecoratorKind):
    name = "delay"
    description = "wait this many seconds of mission time, then run the child"
    argument = Seconds
    argument_help = f"a number of seconds from 0 to {MAX_SECONDS:,.0f}"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return _DelayBehaviour(b.name, b.child, float(b.value), b.runtime)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"delay {node.duration:g} s"


class _KeepRunningUntilFailure(py_trees.decorators.Decorator):
    """RUNNING while the child succeeds (it starts again next tick); FAILURE when it fails."""

    def update(self) -> Status:
        if self.decorated.status is Status.FAILURE:
            return Status.FAILURE
        return Status.RUNNING


class KeepRunningUntilFailure(DecoratorKind):
    name = "keep_running_until_failure"
    description = "run the child again each time it succeeds; fail when it fails"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return _KeepRunningUntilFailure(name=b.name, child=b.child)
