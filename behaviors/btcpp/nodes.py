"""BehaviorTree.CPP v4's built-in node set, registered as botstage node kinds under BT.CPP's IDs,
in the scope an XML file sees (``NODE_SET``, the entry point ``btcpp``).

Ports are options beside the kind, named as in BT.CPP (``{RetryUntilSuccessful: NODE,
num_attempts: 3}``, ``{Parallel: [...], success_count: 2}``); leaves take their ports as their
value (``{Sleep: {msec: 500}}``). The XML importer (``botstage.behaviors.btcpp.to_spec``) writes exactly
this. Where an existing botstage node has BT.CPP's semantics it is reused (Inverter, ForceSuccess,
ForceFailure, KeepRunningUntilFailure, the mission-clock Timeout); the rest are in
``botstage.behaviors.btcpp.behaviours``.

Scripts (``botstage.behaviors.btcpp.script``) are compiled when the tree is built, their names bound to
keys like ``{key}``: ``{Script: {code: "n := n + 1"}}``, ``{ScriptCondition: {code: ...}}``,
``{Precondition: NODE, if_: "...", else: SKIPPED}`` (``if_``: ``if`` is botstage's own guard
kind) and ``{PrePostConditions: NODE, _skipIf: "...", _post: "..."}``, which carries BT.CPP's
pre/post-condition attributes of the node it wraps. Number ports (``num_attempts``, ``msec``,
...) take ``{key}`` too, read when the node starts.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Annotated, Any, ClassVar, Literal

import py_trees
from py_trees.common import Status
from pydantic import Field, PlainValidator, WithJsonSchema, create_model

from botstage.behaviors.btcpp import behaviours as bt
from botstage.behaviors.btcpp.script import ScriptError, compile_script
from botstage.behaviors.btcpp.vocabulary import SCOPE
from botstage.behaviors.decorators import ClockTimeout
from botstage.behaviors.kinds import decorators as botstage
from botstage.behaviors.kinds.base import CompositeKind, DecoratorKind, Described, KindOptions, LeafKind, NodeBuild
from botstage.behaviors.kinds.registry import NodeSet
from botstage.behaviors.skill_behaviour import KeyRef
from botstage.behaviors.skill_binding import parse_binding
from botstage.robots.suggest import did_you_mean


class LiteralType:
    """Annotation metadata: how the XML importer reads a literal written for this port (a port
    typed ``int | str`` takes ``{key}`` as its str, so its literals are whole numbers)."""

    def __init__(self, tp: Any) -> None:
        self.literal_type = tp


KEY_TEXT = re.compile(r"^\{@?[^{}]+\}$")


def _number_or_key(low: int, high: int, what: str) -> Any:
    """A number port that may name a key instead (``{key}``, read when the node starts), as BT.CPP allows."""

    def check(value: Any) -> Any:
        if isinstance(value, str) and KEY_TEXT.match(value):
            return value
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"expected {what} or a {{key}}, got {value!r}")
        if not low <= value <= high:
            raise ValueError(f"must be from {low} to {high:,}, got {value}")
        return value

    schema = {
        "anyOf": [{"type": "integer", "minimum": low, "maximum": high}, {"type": "string", "pattern": KEY_TEXT.pattern}]
    }
    return Annotated[int | str, PlainValidator(check), WithJsonSchema(schema), LiteralType(int)]


Count = _number_or_key(-1000, 1_000_000, "a whole number")
Threshold = Annotated[int, Field(ge=-1000, le=1_000_000)]  # Parallel's counts: literals only
Millis = _number_or_key(0, 1_000_000_000, "a whole number of milliseconds")


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


def _number(b: NodeBuild, raw: Any, *where: str | int) -> bt.Number | None:
    """A number port: the literal, or ``{key}`` read when the node starts."""
    if raw is None:
        return None
    value = _key_or_literal(b, raw, "read", *where)
    if value is None:
        return None
    if isinstance(value, bt.BoundKey):
        return bt.Number(value, b.runtime.blackboard.client(b.path, reads=[value.key]))
    return bt.Number(value)


def bind_script(b: NodeBuild, source: Any, *where: str | int) -> bt.BoundScript | None:
    """A BT.CPP script written at ``where``, compiled, its names bound to (remapped) keys and
    recorded as read or written; None (and a problem) if it does not parse."""
    label = ".".join(str(w) for w in where) or b.key
    if not isinstance(source, str):
        b.problem(f"{label}: expected a script (a string), got {type(source).__name__}", *where)
        return None
    try:
        script = compile_script(source)
    except ScriptError as exc:
        b.problem(f"{label}: {exc.message} at column {exc.column} of {source!r}", *where)
        return None
    keys: dict[str, str] = {}
    for name in sorted(script.keys):
        key = b.builder.key(name.removeprefix("@"), b.spec_path + where, b.scope)
        if key is None:
            return None
        keys[name] = key
    for name in sorted(script.reads):
        b.builder.use(keys[name], "read", b.spec_path + where, b.scope)
    for name in sorted(script.writes):
        b.builder.use(keys[name], "write", b.spec_path + where, b.scope)
    access = b.runtime.blackboard.client(
        b.path, reads=[keys[n] for n in script.reads], writes=[keys[n] for n in script.writes]
    )
    return bt.BoundScript(script, keys, access)


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
    success_count: Threshold = Field(default=-1, description="successes needed; -1 all children, -2 all but one ...")
    failure_count: Threshold = Field(default=1, description="failures that fail it; -1 all children ...")


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
    max_failures: Threshold = Field(default=1, description="failures that make it fail once all completed; -1 all")


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
        times = _number(b, _required(b, self.count), self.count)
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
        if isinstance(msec, str):
            number = _number(b, msec, "msec")
            return None if number is None else bt.KeyedTimeout(b.name, b.child, number, b.runtime)
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
        msec = _number(b, _required(b, "delay_msec"), "delay_msec")
        return None if msec is None else bt.Delay(b.name, b.child, msec, b.runtime)


# -- leaves ---------------------------------------------------------------------------------


class _PortLeaf(LeafKind):
    """A leaf whose value is a mapping of its ports (``{Sleep: {msec: 500}}``)."""

    ports: ClassVar[dict[str, bool]] = {}  # port name -> required
    port_types: ClassVar[dict[str, Any]] = {}  # port name -> the type a literal is read as (str if absent)

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
    port_types = {"msec": Millis}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = self._ports(b)
        if ports is None:
            return None
        msec = ports["msec"]
        if isinstance(msec, str) and isinstance(parse_binding(msec), KeyRef):
            number = _number(b, msec, self.name, "msec")
            return None if number is None else bt.Sleep(b.name, number, b.runtime)
        if isinstance(msec, bool) or not isinstance(msec, int) or msec < 0:
            b.problem(f"msec of Sleep must be a whole number of milliseconds ≥ 0, got {msec!r}", self.name, "msec")
            return None
        return bt.Sleep(b.name, bt.Number(msec), b.runtime)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"Sleep {node.msec} ms"


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


class Script(_PortLeaf):
    name = "Script"
    description = "BT.CPP Script: run `code` (BT.CPP's script language) on the blackboard; SUCCESS"
    shape = "condition"
    ports = {"code": True}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = self._ports(b)
        code = None if ports is None else bind_script(b, ports["code"], self.name, "code")
        return None if code is None else self.behaviour(b.name, code)

    behaviour: ClassVar[type[bt.Script]] = bt.Script

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        source = node.code.source
        return f"{self.name}: {source if len(source) <= 40 else source[:39] + '…'}"


class ScriptCondition(Script):
    name = "ScriptCondition"
    description = "BT.CPP ScriptCondition: SUCCESS if `code` is true, else FAILURE"
    behaviour = bt.ScriptCondition


class UnsetBlackboard(_PortLeaf):
    name = "UnsetBlackboard"
    description = "BT.CPP UnsetBlackboard: remove `key` from the blackboard; SUCCESS"
    shape = "condition"
    ports = {"key": True}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = self._ports(b)
        if ports is None:
            return None
        raw = parse_binding(ports["key"])
        key = b.builder.key(raw.key if isinstance(raw, KeyRef) else raw, b.spec_path + (self.name, "key"), b.scope)
        if key is None:
            return None
        b.builder.use(key, "write", b.spec_path + (self.name, "key"), b.scope)
        return bt.UnsetBlackboard(b.name, key, b.runtime.blackboard.client(b.path, writes=[key]))

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"UnsetBlackboard {node.key}"


class _Aliased(DecoratorKind):
    """A kind whose options are written under names Python cannot use (``if``, ``_skipIf``)."""

    def option_names(self) -> set[str]:
        return {field.alias or name for name, field in self.Options.model_fields.items()}


ELSE = {"SUCCESS": Status.SUCCESS, "FAILURE": Status.FAILURE, "RUNNING": Status.RUNNING, "SKIPPED": bt.SKIPPED}


class PreconditionOptions(KindOptions):
    # written `if_`: `if` is botstage's own guard kind, and a node names exactly one kind
    if_: str = Field(description="BT.CPP's `if`: a script; the child starts only if it is true")
    else_: Literal["SUCCESS", "FAILURE", "RUNNING", "SKIPPED"] = Field(
        default="FAILURE", alias="else", description="the status when `if` is false (SKIPPED: a skipped success)"
    )


class Precondition(_Aliased):
    name = "Precondition"
    description = "BT.CPP Precondition: tick the child if `if` holds when it starts, else return `else`"
    Options = PreconditionOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        source = _required(b, "if_")
        condition = None if source is None else bind_script(b, source, "if_")
        if condition is None:
            return None
        return bt.Precondition(b.name, b.child, condition, ELSE[b.options.else_])

    def describe(self, node: py_trees.behaviour.Behaviour) -> Described:
        return Described(f"Precondition if {node.condition.source}", self.shape)


PRE_POST = ("_skipIf", "_failureIf", "_successIf", "_while", "_onSuccess", "_onFailure", "_onHalted", "_post")


class PrePostOptions(KindOptions):
    skip_if: str | None = Field(None, alias="_skipIf", description="skip the node (SKIPPED) if true when it starts")
    failure_if: str | None = Field(None, alias="_failureIf", description="FAILURE without ticking, if true at start")
    success_if: str | None = Field(None, alias="_successIf", description="SUCCESS without ticking, if true at start")
    while_: str | None = Field(None, alias="_while", description="skip it if false at start, halt it if false later")
    on_success: str | None = Field(None, alias="_onSuccess", description="a script run when it succeeds")
    on_failure: str | None = Field(None, alias="_onFailure", description="a script run when it fails")
    on_halted: str | None = Field(None, alias="_onHalted", description="a script run when it is halted")
    post: str | None = Field(None, alias="_post", description="a script run after every tick of it")


class PrePostConditions(_Aliased):
    """BT.CPP's pre- and post-condition attributes of a node, as a decorator around that node
    (the importer puts it there): pictures show the node under a box listing its scripts."""

    name = "PrePostConditions"
    description = "BT.CPP's _skipIf, _failureIf, _successIf, _while, _onSuccess, _onFailure, _onHalted, _post"
    Options = PrePostOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        scripts: dict[str, bt.BoundScript] = {}
        ok = True
        for field_name, field in PrePostOptions.model_fields.items():
            source = getattr(b.options, field_name, None)
            if source is None:
                continue
            script = bind_script(b, source, field.alias or field_name)
            ok = ok and script is not None
            if script is not None:
                scripts[field.alias or field_name] = script
        if not scripts and ok:
            b.problem(f"{self.name} needs at least one of {', '.join(PRE_POST)}")
            return None
        return bt.PrePost(b.name, b.child, scripts) if ok else None

    def describe(self, node: py_trees.behaviour.Behaviour) -> Described:
        details = [f"{attr}: {node.scripts[attr].source}" for attr in PRE_POST if attr in node.scripts]
        return Described("pre/post conditions", self.shape, details)


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
    "PrePostConditions",
    "Precondition",
    "ReactiveFallback",
    "ReactiveSequence",
    "Repeat",
    "RetryUntilSuccessful",
    "RunOnce",
    "Script",
    "ScriptCondition",
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
    "UnsetBlackboard",
    "WhileDoElse",
]

# registered through the entry point `btcpp` of `botstage.nodes`, as any third party's set is;
# only an XML file's scope sees these IDs, so a YAML mission never meets `Sequence` beside `sequence`
NODE_SET = NodeSet(
    "btcpp",
    SCOPE,
    tuple(globals()[name] for name in __all__),
    "BehaviorTree.CPP v4's built-in nodes, under their BT.CPP IDs",
)
