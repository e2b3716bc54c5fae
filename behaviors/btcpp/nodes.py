"""BehaviorTree.CPP v4's built-in node set, registered as botstage node kinds under BT.CPP's IDs.

Ports are options beside the kind, named as in BT.CPP (``{RetryUntilSuccessful: NODE,
num_attempts: 3}``, ``{Parallel: [...], success_count: 2}``); leaves take their ports as their
value (``{Sleep: {msec: 500}}``). The XML importer (``behaviors.btcpp.to_spec``) writes exactly
this. Where an existing botstage node has BT.CPP's semantics it is reused (Inverter, ForceSuccess,
ForceFailure, KeepRunningUntilFailure, the mission-clock Timeout); the rest are in
``behaviors.btcpp.behaviours``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, ClassVar

import py_trees
from py_trees.common import Status
from pydantic import Field, create_model

from behaviors.btcpp import behaviours as bt
from behaviors.decorators import ClockTimeout
from behaviors.kinds import decorators as botstage
from behaviors.kinds.base import CompositeKind, DecoratorKind, KindOptions, LeafKind, NodeBuild
from behaviors.skill_behaviour import KeyRef
from behaviors.skill_binding import parse_binding
from behaviors.suggest import did_you_mean

Count = Annotated[int, Field(ge=-1000, le=1_000_000)]
Millis = Annotated[int, Field(ge=0, le=1_000_000_000)]


def _key_or_literal(b: NodeBuild, raw: Any, mode: str, *where: str | int) -> Any:
    """A port value: ``{key}`` becomes a key (remapped, its use recorded), anything else a literal."""
    value = parse_binding(raw)
    if not isinstance(value, KeyRef):
        return value
    key = b.builder.key(value.key, b.spec_path + where, b.scope)
    if key is None:
        return None
    b.builder.use(key, mode, b.spec_path + where, b.scope)
    return bt.BoundKey(key)


def _required(b: NodeBuild, port: str) -> Any:
    """A required port's value; None when it was missing or wrong (the builder has reported it)."""
    return getattr(b.options, port, None)


# -- controls -------------------------------------------------------------------------------


class Sequence(CompositeKind):
    name = "Sequence"
    description = "BT.CPP Sequence: children in order, resuming the running one; a failure restarts it"
    shape = "sequence"
    memory: ClassVar[bool] = False
    carry_on: ClassVar[Status] = Status.SUCCESS

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return bt.Sequence(b.name, b.children, self.carry_on, memory=self.memory)


class SequenceWithMemory(Sequence):
    name = "SequenceWithMemory"
    description = "BT.CPP SequenceWithMemory: as Sequence, but a failed child is ticked again next time"
    memory = True


class Fallback(Sequence):
    name = "Fallback"
    description = "BT.CPP Fallback: children in order until one succeeds, resuming the running one"
    shape = "selector"
    carry_on = Status.FAILURE


class ReactiveSequence(CompositeKind):
    name = "ReactiveSequence"
    description = "BT.CPP ReactiveSequence: from the first child every tick; a failure halts the running child"
    shape = "sequence"
    decisive: ClassVar[Status] = Status.FAILURE

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return bt.Reactive(b.name, b.children, self.decisive)


class ReactiveFallback(ReactiveSequence):
    name = "ReactiveFallback"
    description = "BT.CPP ReactiveFallback: from the first child every tick; a success halts the running child"
    shape = "selector"
    decisive = Status.SUCCESS


class ParallelOptions(KindOptions):
    success_count: Count = Field(default=-1, description="successes needed; -1 all children, -2 all but one ...")
    failure_count: Count = Field(default=1, description="failures that fail it; -1 all children ...")


class Parallel(CompositeKind):
    name = "Parallel"
    description = "BT.CPP Parallel: tick every running child; success_count successes or failure_count failures"
    shape = "parallel"
    Options = ParallelOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        options: ParallelOptions = b.options
        count = len(b.children)
        for port in ("success_count", "failure_count"):
            if bt.threshold(getattr(options, port), count) > count:
                b.problem(f"{port} {getattr(options, port)} is more than the {count} children", port)
                return None
        return bt.Parallel(b.name, b.children, options.success_count, options.failure_count)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"Parallel ({node.success_count}/{node.failure_count})"


class ParallelAllOptions(KindOptions):
    max_failures: Count = Field(default=1, description="failures that make it fail once all completed; -1 all")


class ParallelAll(CompositeKind):
    name = "ParallelAll"
    description = "BT.CPP ParallelAll: run every child to completion; fail at max_failures failures"
    shape = "parallel"
    Options = ParallelAllOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if bt.threshold(b.options.max_failures, len(b.children)) > len(b.children):
            b.problem(f"max_failures {b.options.max_failures} is more than the {len(b.children)} children")
            return None
        return bt.ParallelAll(b.name, b.children, b.options.max_failures)


class IfThenElse(CompositeKind):
    name = "IfThenElse"
    description = "BT.CPP IfThenElse: children condition, then, [else]; the condition is not re-checked"
    shape = "selector"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if len(b.children) not in (2, 3):
            b.problem(f"{self.name} takes 2 or 3 children, got {len(b.children)}", self.name)
            return None
        return bt.IfThenElse(b.name, b.children)


class WhileDoElse(IfThenElse):
    name = "WhileDoElse"
    description = "BT.CPP WhileDoElse: children condition, do, [else]; the condition is checked every tick"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if len(b.children) not in (2, 3):
            b.problem(f"{self.name} takes 2 or 3 children, got {len(b.children)}", self.name)
            return None
        return bt.WhileDoElse(b.name, b.children)


def _switch_options(cases: int) -> type[KindOptions]:
    fields: dict[str, Any] = {"variable": (Any, Field(description="the value to switch on, usually {key}"))}
    for n in range(1, cases + 1):
        fields[f"case_{n}"] = (str | int | float | bool | None, Field(default=None, description=f"case {n}"))
    return create_model(f"Switch{cases}Options", __base__=KindOptions, **fields)


class _Switch(CompositeKind):
    cases: ClassVar[int] = 0
    shape = "selector"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if len(b.children) != self.cases + 1:
            b.problem(
                f"{self.name} takes {self.cases + 1} children (one per case, then the default), got {len(b.children)}",
                self.name,
            )
            return None
        if not hasattr(b.options, "variable"):
            return None
        variable = _key_or_literal(b, b.options.variable, "read", "variable")
        cases = [getattr(b.options, f"case_{n}") for n in range(1, self.cases + 1)]
        texts = [None if c is None else bt.as_text(c) for c in cases]
        reads = [variable.key] if isinstance(variable, bt.BoundKey) else []
        if variable is not None and not isinstance(variable, bt.BoundKey):
            variable = bt.as_text(variable)
        access = b.runtime.blackboard.client(b.path, reads=reads)
        return bt.Switch(b.name, b.children, variable, texts, access)


def _switch(cases: int) -> type[_Switch]:
    return type(
        f"Switch{cases}",
        (_Switch,),
        {
            "__module__": __name__,
            "name": f"Switch{cases}",
            "description": f"BT.CPP Switch{cases}: the child of the case equal to `variable`, else the last",
            "cases": cases,
            "Options": _switch_options(cases),
        },
    )


Switch2, Switch3, Switch4, Switch5, Switch6 = (_switch(n) for n in range(2, 7))


# -- decorators -----------------------------------------------------------------------------


class Inverter(botstage.Inverter):
    name = "Inverter"
    description = "BT.CPP Inverter: success becomes failure and failure success"


class ForceSuccess(botstage.ForceSuccess):
    name = "ForceSuccess"
    description = "BT.CPP ForceSuccess: a completed child is a success"


class ForceFailure(botstage.ForceFailure):
    name = "ForceFailure"
    description = "BT.CPP ForceFailure: a completed child is a failure"


class KeepRunningUntilFailure(botstage.KeepRunningUntilFailure):
    name = "KeepRunningUntilFailure"
    description = "BT.CPP KeepRunningUntilFailure: RUNNING while the child succeeds, FAILURE when it fails"


class RetryOptions(KindOptions):
    num_attempts: Count = Field(description="attempts in all; -1 forever")


class _Loop(DecoratorKind):
    """Retry and Repeat: tick the child again until it ends with ``until``, ``count`` times in all."""

    count: str
    until: Status

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        times = _required(b, self.count)
        return None if times is None else bt.Loop(b.name, b.child, times, until=self.until)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"{self.name} ×{node.times}"


class RetryUntilSuccessful(_Loop):
    name = "RetryUntilSuccessful"
    description = "BT.CPP RetryUntilSuccessful: tick the child again after a failure, num_attempts in all"
    Options = RetryOptions
    count, until = "num_attempts", Status.SUCCESS


class RepeatOptions(KindOptions):
    num_cycles: Count = Field(description="successes in all; -1 forever")


class Repeat(_Loop):
    name = "Repeat"
    description = "BT.CPP Repeat: tick the child again after a success, num_cycles in all; a failure ends it"
    Options = RepeatOptions
    count, until = "num_cycles", Status.FAILURE


class RunOnceOptions(KindOptions):
    then_skip: bool = Field(default=True, description="after the first run: skip (true) or repeat its result")


class RunOnce(DecoratorKind):
    name = "RunOnce"
    description = "BT.CPP RunOnce: run the child to completion once, then skip it (a success) or repeat its result"
    Options = RunOnceOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return bt.RunOnce(b.name, b.child, b.options.then_skip)


class TimeoutOptions(KindOptions):
    msec: Millis = Field(description="milliseconds of run time; 0: no timeout")


class Timeout(DecoratorKind):
    name = "Timeout"
    description = "BT.CPP Timeout: halt the running child and fail after msec of run time"
    Options = TimeoutOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        msec = _required(b, "msec")
        if msec is None:
            return None
        if msec == 0:
            return bt.PassThrough(name=b.name, child=b.child)
        node = ClockTimeout(name=b.name, child=b.child, duration=msec / 1000, runtime=b.runtime)
        node.path = b.path
        return node


class DelayOptions(KindOptions):
    delay_msec: Millis = Field(description="milliseconds of run time to wait before ticking the child")


class Delay(DecoratorKind):
    name = "Delay"
    description = "BT.CPP Delay: RUNNING for delay_msec of run time, then the child"
    Options = DelayOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        msec = _required(b, "delay_msec")
        return None if msec is None else bt.Delay(b.name, b.child, msec / 1000, b.runtime)


# -- leaves ---------------------------------------------------------------------------------


class _PortLeaf(LeafKind):
    """A leaf whose value is a mapping of its ports (``{Sleep: {msec: 500}}``)."""

    ports: ClassVar[dict[str, bool]] = {}  # port name -> required

    def _ports(self, b: NodeBuild) -> Mapping[str, Any] | None:
        value = {} if b.value is None else b.value
        if not isinstance(value, Mapping):
            b.problem(f"{self.name} takes a mapping of its ports ({', '.join(self.ports) or 'none'})", self.name)
            return None
        ok = True
        for port in value:
            if port not in self.ports:
                b.problem(f"{self.name} has no port {port!r}", self.name, port, hint=did_you_mean(port, self.ports))
                ok = False
        for port, required in self.ports.items():
            if required and port not in value:
                b.problem(f"{self.name} needs port {port!r}", self.name)
                ok = False
        return value if ok else None

    def written(self) -> str:
        return f"{self.name}: {{{', '.join(f'{p}: VALUE' for p in self.ports)}}}"


class AlwaysSuccess(_PortLeaf):
    name = "AlwaysSuccess"
    description = "BT.CPP AlwaysSuccess"
    shape = "condition"
    result: ClassVar[Status] = Status.SUCCESS

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if self._ports(b) is None:
            return None
        return bt.Constant(b.name, self.result)


class AlwaysFailure(AlwaysSuccess):
    name = "AlwaysFailure"
    description = "BT.CPP AlwaysFailure"
    result = Status.FAILURE


class Sleep(_PortLeaf):
    name = "Sleep"
    description = "BT.CPP Sleep: RUNNING for msec of run time, then SUCCESS"
    ports = {"msec": True}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = self._ports(b)
        if ports is None:
            return None
        msec = ports["msec"]
        if isinstance(msec, bool) or not isinstance(msec, int) or msec < 0:
            b.problem(f"msec of Sleep must be a whole number of milliseconds ≥ 0, got {msec!r}", self.name, "msec")
            return None
        return bt.Sleep(b.name, msec / 1000, b.runtime)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"Sleep {node.seconds * 1000:g} ms"


class SetBlackboard(_PortLeaf):
    name = "SetBlackboard"
    description = "BT.CPP SetBlackboard: write value (a literal or {key}) to output_key"
    ports = {"value": True, "output_key": True}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = self._ports(b)
        if ports is None:
            return None
        raw_key = parse_binding(ports["output_key"])
        key = b.builder.key(
            raw_key.key if isinstance(raw_key, KeyRef) else raw_key, b.spec_path + (self.name,), b.scope
        )
        value = _key_or_literal(b, ports["value"], "read", self.name, "value")
        if key is None or value is None:
            return None
        b.builder.use(key, "write", b.spec_path + (self.name, "output_key"), b.scope)
        reads = [value.key] if isinstance(value, bt.BoundKey) else []
        access = b.runtime.blackboard.client(b.path, reads=reads, writes=[key])
        return bt.SetBlackboard(b.name, value, key, access)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"SetBlackboard {node.output_key}"


__all__ = [
    "AlwaysFailure",
    "AlwaysSuccess",
    "Delay",
    "Fallback",
    "ForceFailure",
    "ForceSuccess",
    "IfThenElse",
    "Inverter",
    "KeepRunningUntilFailure",
    "Parallel",
    "ParallelAll",
    "ReactiveFallback",
    "ReactiveSequence",
    "Repeat",
    "RetryUntilSuccessful",
    "RunOnce",
    "Sequence",
    "SequenceWithMemory",
    "SetBlackboard",
    "Sleep",
    "Switch2",
    "Switch3",
    "Switch4",
    "Switch5",
    "Switch6",
    "Timeout",
    "WhileDoElse",
]
