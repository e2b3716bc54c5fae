"""Trees and machines from plain dict specs (what the mission YAML maps onto).

A node spec is a mapping with one *kind* key and optional options beside it::

    {"sequence": [ ...children... ], "name": "patrol", "memory": False}
    {"wait": {"duration": 5}}                      # a skill, inputs as the value
    {"skill": "wait", "inputs": {"duration": 5}}   # the same, spelled out
    {"timeout": 10, "child": {...}}                # decorators with an argument take `child`
    {"inverter": {...}}                            # ... those without take the child directly
    {"while": "battery_pct > 20", "child": {...}}  # eternal guard
    {"subtree": "approach", "remap": {"target": "crowd_centre"}}
    {"machine": "docking"}                         # a named (or inline) state machine

Inputs are literals, or blackboard keys written ``"{key}"`` (YAML's ``{key}`` also works).
Every problem is collected with the spec path where it was found, then raised together.
"""

from __future__ import annotations

import ast
import difflib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import py_trees
from pydantic import ValidationError

from behaviors.blackboard import BlackboardError, normalise_key
from behaviors.decorators import ClockTimeout, Guard
from behaviors.machine import (
    Action,
    Level,
    MachineBehaviour,
    MachinePlan,
    StateInfo,
    Target,
    Unresolved,
    plan_access,
    resolve_outcome,
    resolve_target,
)
from behaviors.skill_behaviour import KeyRef, SkillBehaviour
from skills.base import MISSING, check_type
from skills.expression import Expression, ExpressionError, compile_expression, key_of
from skills.registry import UnknownSkillError

if TYPE_CHECKING:
    from behaviors.engine import Engine

SpecPath = tuple[str | int, ...]

COMPOSITES = {
    "sequence": ("sequence", True),
    "selector": ("selector", True),
    "fallback": ("selector", True),
    "reactive_sequence": ("sequence", False),
    "reactive_selector": ("selector", False),
    "reactive_fallback": ("selector", False),
    "parallel": ("parallel", False),
}
# decorators whose value is the child itself
PLAIN_DECORATORS = {
    "inverter": py_trees.decorators.Inverter,
    "force_success": py_trees.decorators.FailureIsSuccess,
    "force_failure": py_trees.decorators.SuccessIsFailure,
    "one_shot": None,
}
# decorators whose value is an argument and whose child is under `child`
ARG_DECORATORS = ("retry", "repeat", "timeout", "while", "if")
LEAVES = ("skill", "condition", "subtree", "machine")
KEYWORDS = frozenset(COMPOSITES) | frozenset(PLAIN_DECORATORS) | frozenset(ARG_DECORATORS) | frozenset(LEAVES)
COMMON_OPTIONS = {"name"}
OPTIONS: dict[str, set[str]] = {
    "sequence": {"memory"},
    "selector": {"memory"},
    "parallel": {"policy", "synchronise", "selected"},
    "skill": {"inputs", "outputs", "success_on", "params"},
    "condition": set(),
    "subtree": {"remap"},
    "machine": {"success_on"},
    "one_shot": {"policy"},
    "decorator": set(),
    "arg_decorator": {"child"},
}
PARALLEL_POLICIES = ("success_on_all", "success_on_one", "success_on_selected")
STATE_KEYS = {
    "skill",
    "inputs",
    "outputs",
    "params",
    "tree",
    "machine",
    "transitions",
    "timeout",
    "on_enter",
    "on_exit",
    "success_on",
}
MACHINE_KEYS = {"initial", "states", "outcomes", "preemptions", "success_on", "name"}


@dataclass(frozen=True)
class KeyUsage:
    """A node reads or writes a blackboard key, at this place of the spec, through a port of this type."""

    key: str
    mode: str  # read or write
    spec_path: SpecPath
    type: Any = Any
    node: str = ""


@dataclass(frozen=True)
class SpecProblem:
    path: SpecPath
    message: str
    hint: str = ""

    def __str__(self) -> str:
        where = "/".join(str(p) for p in self.path) or "<root>"
        return f"{where}: {self.message}" + (f" ({self.hint})" if self.hint else "")


class SpecError(ValueError):
    def __init__(self, problems: Sequence[SpecProblem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


def did_you_mean(name: str, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(str(name), sorted(known), n=1, cutoff=0.6)
    return f"did you mean {close[0]!r}?" if close else ""


def parse_binding(value: Any) -> Any:
    """``"{key}"`` and YAML's ``{key}`` (a one-entry mapping with no value) bind to a key."""
    if isinstance(value, str) and len(value) > 2 and value[0] == "{" and value[-1] == "}":
        return KeyRef(value[1:-1].strip())
    if isinstance(value, Mapping) and len(value) == 1:
        ((key, inner),) = value.items()
        if inner is None and isinstance(key, str):
            return KeyRef(key)
    return value


def parse_output(value: Any) -> str | None:
    ref = parse_binding(value)
    if isinstance(ref, KeyRef):
        return ref.key
    return value if isinstance(value, str) else None


@dataclass
class _Scope:
    path: str  # trace path of the node being built
    spec_path: SpecPath
    remap: Mapping[str, str] = field(default_factory=dict)
    subtrees: tuple[str, ...] = ()

    def key(self, key: str) -> str:
        return remap_key(key, self.remap)

    def child(self, segment: str, *spec: str | int) -> _Scope:
        return _Scope(
            f"{self.path}/{segment}" if self.path else segment, self.spec_path + spec, self.remap, self.subtrees
        )


class Builder:
    """Builds trees and machines for one engine; problems are collected, then raised as SpecError."""

    def __init__(
        self,
        engine: Engine,
        trees: Mapping[str, Any] | None = None,
        machines: Mapping[str, Any] | None = None,
        skill_params: Mapping[str, Mapping[str, Any]] | None = None,
        spec_root: SpecPath = (),
    ) -> None:
        self.engine = engine
        self.trees = dict(trees or {})
        self.machines = dict(machines or {})
        self.skill_params = dict(skill_params or {})
        self.spec_root = spec_root
        self.problems: list[SpecProblem] = []
        self.usages: list[KeyUsage] = []
        self.plans: list[MachinePlan] = []  # every machine planned, even one with problems

    # -- public -----------------------------------------------------------------------------

    def tree(self, spec: Any, name: str = "root", spec_path: SpecPath | None = None) -> py_trees.behaviour.Behaviour:
        scope = _Scope(name, spec_path if spec_path is not None else self.spec_root)
        node = self._node(spec, scope)
        self._raise_problems()
        assert node is not None
        return node

    def named_tree(self, name: str) -> py_trees.behaviour.Behaviour:
        if name not in self.trees:
            raise SpecError([SpecProblem((), f"unknown tree {name!r}", did_you_mean(name, self.trees))])
        scope = _Scope(name, ("trees", name), subtrees=(name,))
        node = self._node(self.trees[name], scope)
        self._raise_problems()
        assert node is not None
        return node

    def machine(self, spec: Any, name: str = "machine", spec_path: SpecPath | None = None) -> MachineBehaviour:
        scope = _Scope(name, spec_path if spec_path is not None else self.spec_root)
        node = self._machine(spec, scope, name)
        self._raise_problems()
        assert node is not None
        return node

    # -- helpers ----------------------------------------------------------------------------

    def _raise_problems(self) -> None:
        if self.problems:
            problems, self.problems = self.problems, []
            raise SpecError(problems)

    def _problem(self, spec_path: SpecPath, message: str, hint: str = "") -> None:
        self.problems.append(SpecProblem(spec_path, message, hint))

    def _key(self, raw: Any, spec_path: SpecPath, scope: _Scope) -> str | None:
        """A blackboard key as written, checked and remapped; None (and a problem) if malformed."""
        try:
            return scope.key(normalise_key(raw))
        except BlackboardError as exc:
            self._problem(spec_path, str(exc))
            return None

    def _use(self, key: str, mode: str, spec_path: SpecPath, scope: _Scope, tp: Any = Any) -> None:
        self.usages.append(KeyUsage(key, mode, spec_path, tp, scope.path))

    @staticmethod
    def _unique(names: list[str], name: str) -> str:
        if name not in names:
            names.append(name)
            return name
        n = 2
        while f"{name}#{n}" in names:
            n += 1
        names.append(f"{name}#{n}")
        return f"{name}#{n}"

    def _kind_of(self, spec: Mapping[str, Any], scope: _Scope) -> str | None:
        registry = self.engine.registry
        kinds = [k for k in spec if k in KEYWORDS or (isinstance(k, str) and k in registry)]
        if len(kinds) == 1:
            return kinds[0]
        if not kinds:
            unknown = [k for k in spec if k not in COMMON_OPTIONS]
            shown = unknown[0] if unknown else None
            if shown is not None:
                self._problem(
                    scope.spec_path + (shown,),
                    f"unknown node or skill {shown!r}",
                    did_you_mean(shown, [*KEYWORDS, *registry]),
                )
            else:
                self._problem(scope.spec_path, "a node needs a kind (a skill, sequence, selector, ...)")
            return None
        self._problem(scope.spec_path, f"a node has exactly one kind, found {', '.join(map(repr, kinds))}")
        return None

    def _check_options(self, spec: Mapping[str, Any], kind: str, allowed: set[str], scope: _Scope) -> None:
        for key in spec:
            if key != kind and key not in allowed and key not in COMMON_OPTIONS:
                self._problem(
                    scope.spec_path + (key,),
                    f"unknown option {key!r} for {kind!r}",
                    did_you_mean(key, allowed | COMMON_OPTIONS),
                )

    # -- nodes ------------------------------------------------------------------------------

    def _node(self, spec: Any, scope: _Scope) -> py_trees.behaviour.Behaviour | None:
        if isinstance(spec, str) and spec in self.engine.registry:
            spec = {spec: None}  # a bare skill name with no inputs
        if not isinstance(spec, Mapping):
            self._problem(scope.spec_path, f"expected a node (a mapping), got {type(spec).__name__}")
            return None
        kind = self._kind_of(spec, scope)
        if kind is None:
            return None
        if kind in COMPOSITES:
            node = self._composite(spec, kind, scope)
        elif kind in PLAIN_DECORATORS or kind in ARG_DECORATORS:
            node = self._decorator(spec, kind, scope)
        elif kind == "subtree":
            node = self._subtree(spec, scope)
        elif kind == "machine":
            self._check_options(spec, kind, OPTIONS["machine"], scope)
            node = self._machine_ref(spec, scope)
        elif kind == "condition":
            self._check_options(spec, kind, OPTIONS["condition"], scope)
            condition = {"condition": spec["condition"]}
            node = self._skill_node("check", condition, {}, None, None, scope, scope.spec_path + ("condition",))
        else:
            node = self._skill_spec(spec, kind, scope)
        if node is not None and not hasattr(node, "path"):
            node.path = scope.path
        return node

    def _children(self, items: Any, scope: _Scope, key: str) -> list[py_trees.behaviour.Behaviour]:
        if not isinstance(items, list) or not items:
            self._problem(scope.spec_path + (key,), f"{key!r} needs a non-empty list of children")
            return []
        built, names = [], []
        explicit: dict[str, int] = {}
        for index, item in enumerate(items):
            given = item.get("name") if isinstance(item, Mapping) else None
            if isinstance(given, str):
                if given in explicit:
                    self._problem(
                        scope.spec_path + (key, index, "name"),
                        f"duplicate node name {given!r}",
                        f"sibling {explicit[given]} has it too; names identify nodes in traces",
                    )
                explicit.setdefault(given, index)
            default = self._default_name(item)
            segment = self._unique(names, default)
            child_scope = _Scope(f"{scope.path}/{segment}", scope.spec_path + (key, index), scope.remap, scope.subtrees)
            node = self._node(item, child_scope)
            if node is not None:
                node.name = segment
                built.append(node)
        return built

    def _default_name(self, spec: Any) -> str:
        if isinstance(spec, str):
            return spec
        if not isinstance(spec, Mapping):
            return "node"
        name = spec.get("name")
        if isinstance(name, str) and name and "/" not in name:
            return name
        for key in spec:
            if key in KEYWORDS or (isinstance(key, str) and key in self.engine.registry):
                if key == "skill" and isinstance(spec.get("skill"), str):
                    return spec["skill"]
                if key in ("subtree", "machine") and isinstance(spec.get(key), str):
                    return spec[key]
                return str(key)
        return "node"

    def _composite(self, spec: Mapping[str, Any], kind: str, scope: _Scope) -> py_trees.behaviour.Behaviour:
        base, default_memory = COMPOSITES[kind]
        self._check_options(spec, kind, OPTIONS[base], scope)
        name = scope.path.rsplit("/", 1)[-1]
        children = self._children(spec[kind], scope, kind)
        if base == "parallel":
            return self._parallel(spec, name, children, scope)
        memory = spec.get("memory", default_memory)
        if not isinstance(memory, bool):
            self._problem(scope.spec_path + ("memory",), "memory must be true or false")
            memory = default_memory
        cls = py_trees.composites.Sequence if base == "sequence" else py_trees.composites.Selector
        return cls(name=name, memory=memory, children=children)

    def _parallel(
        self, spec: Mapping[str, Any], name: str, children: list[py_trees.behaviour.Behaviour], scope: _Scope
    ) -> py_trees.behaviour.Behaviour:
        policy_name = spec.get("policy", "success_on_all")
        synchronise = spec.get("synchronise", True)
        if not isinstance(synchronise, bool):
            self._problem(scope.spec_path + ("synchronise",), "synchronise must be true or false")
            synchronise = True
        policies = py_trees.common.ParallelPolicy
        if policy_name == "success_on_all":
            policy: Any = policies.SuccessOnAll(synchronise=synchronise)
        elif policy_name == "success_on_one":
            policy = policies.SuccessOnOne()
        elif policy_name == "success_on_selected":
            wanted = spec.get("selected")
            by_name = {c.name: c for c in children}
            if not isinstance(wanted, list) or not wanted:
                self._problem(
                    scope.spec_path + ("selected",), "success_on_selected needs `selected`: a list of child names"
                )
                wanted = []
            chosen = []
            for index, child_name in enumerate(wanted):
                if child_name not in by_name:
                    self._problem(
                        scope.spec_path + ("selected", index),
                        f"no child named {child_name!r}",
                        did_you_mean(str(child_name), by_name),
                    )
                else:
                    chosen.append(by_name[child_name])
            policy = policies.SuccessOnSelected(children=chosen, synchronise=synchronise)
        else:
            self._problem(
                scope.spec_path + ("policy",),
                f"unknown parallel policy {policy_name!r}",
                did_you_mean(str(policy_name), PARALLEL_POLICIES) or "one of " + ", ".join(PARALLEL_POLICIES),
            )
            policy = policies.SuccessOnAll()
        return py_trees.composites.Parallel(name=name, policy=policy, children=children)

    def _decorator(self, spec: Mapping[str, Any], kind: str, scope: _Scope) -> py_trees.behaviour.Behaviour | None:
        name = scope.path.rsplit("/", 1)[-1]
        if kind in PLAIN_DECORATORS:
            self._check_options(spec, kind, OPTIONS["one_shot" if kind == "one_shot" else "decorator"], scope)
            child_spec, child_key = spec[kind], kind
        else:
            self._check_options(spec, kind, OPTIONS["arg_decorator"], scope)
            if "child" not in spec:
                self._problem(scope.spec_path, f"{kind!r} needs a `child` node")
                return None
            child_spec, child_key = spec["child"], "child"
        child_scope = _Scope(
            f"{scope.path}/{self._default_name(child_spec)}",
            scope.spec_path + (child_key,),
            scope.remap,
            scope.subtrees,
        )
        child = self._node(child_spec, child_scope)
        if child is None:
            return None
        child.name = child_scope.path.rsplit("/", 1)[-1]
        value = spec[kind]
        arg_path = scope.spec_path + (kind,)
        decorators = py_trees.decorators
        if kind == "one_shot":
            policy = spec.get("policy", "on_success")
            policies = {
                "on_success": py_trees.common.OneShotPolicy.ON_SUCCESSFUL_COMPLETION,
                "on_completion": py_trees.common.OneShotPolicy.ON_COMPLETION,
            }
            if not isinstance(policy, str) or policy not in policies:
                self._problem(scope.spec_path + ("policy",), "one_shot policy must be on_success or on_completion")
                policy = "on_success"
            return decorators.OneShot(name=name, child=child, policy=policies[policy])
        if kind in PLAIN_DECORATORS:
            return PLAIN_DECORATORS[kind](name=name, child=child)  # type: ignore[misc]
        if kind in ("retry", "repeat"):
            if value in ("forever", -1) and kind == "repeat":
                return decorators.Repeat(name=name, child=child, num_success=-1)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                self._problem(
                    arg_path,
                    f"{kind} needs a whole number of times >= 1"
                    + (" (or 'forever')" if kind == "repeat" else "")
                    + f", got {value!r}",
                )
                return None
            if kind == "retry":
                return decorators.Retry(name=name, child=child, num_failures=value)
            return decorators.Repeat(name=name, child=child, num_success=value)
        if kind == "timeout":
            if not isinstance(value, int | float) or isinstance(value, bool) or value <= 0:
                self._problem(arg_path, f"timeout needs a positive number of seconds, got {value!r}")
                return None
            node = ClockTimeout(name=name, child=child, duration=float(value), engine=self.engine)
            node.path = scope.path
            return node
        condition = self._expression(value, arg_path, scope)
        if condition is None:
            return None
        return Guard(name=name, child=child, condition=condition, mode=kind, engine=self.engine, path=scope.path)

    def _expression(self, value: Any, spec_path: SpecPath, scope: _Scope) -> Expression | None:
        if not isinstance(value, str):
            self._problem(spec_path, f"expected a condition (a string), got {type(value).__name__}")
            return None
        try:
            expression = compile_expression(value)
        except ExpressionError as exc:
            self._problem(spec_path, str(exc))
            return None
        if scope.remap and any(scope.key(k) != k for k in expression.keys):
            expression = compile_expression(remap_condition(expression.source, scope.remap))
        for key in sorted(expression.keys):
            self._use(key, "read", spec_path, scope)
        return expression

    def _subtree(self, spec: Mapping[str, Any], scope: _Scope) -> py_trees.behaviour.Behaviour | None:
        self._check_options(spec, "subtree", OPTIONS["subtree"], scope)
        name = spec["subtree"]
        if not isinstance(name, str) or name not in self.trees:
            self._problem(scope.spec_path + ("subtree",), f"unknown tree {name!r}", did_you_mean(str(name), self.trees))
            return None
        if name in scope.subtrees:
            cycle = " -> ".join((*scope.subtrees, name))
            self._problem(scope.spec_path + ("subtree",), f"subtree cycle: {cycle}")
            return None
        remap = spec.get("remap", {})
        if not isinstance(remap, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in remap.items()
        ):
            self._problem(scope.spec_path + ("remap",), "remap must map inner key names to outer key names")
            remap = {}
        merged = {k: scope.key(v) for k, v in remap.items()}
        for key, value in scope.remap.items():
            merged.setdefault(key, value)
        inner = _Scope(scope.path, ("trees", name), merged, (*scope.subtrees, name))
        return self._node(self.trees[name], inner)

    # -- skills -----------------------------------------------------------------------------

    def _skill_spec(self, spec: Mapping[str, Any], kind: str, scope: _Scope) -> py_trees.behaviour.Behaviour | None:
        self._check_options(spec, kind, OPTIONS["skill"], scope)
        if kind == "skill":
            skill_name = spec["skill"]
            if not isinstance(skill_name, str):
                self._problem(scope.spec_path + ("skill",), "skill must be a skill name")
                return None
            inputs, inputs_path = spec.get("inputs") or {}, scope.spec_path + ("inputs",)
        else:
            if "inputs" in spec:
                self._problem(
                    scope.spec_path + ("inputs",), f"give the inputs of {kind!r} as its value, or use `skill: {kind}`"
                )
            skill_name, inputs, inputs_path = kind, spec[kind] or {}, scope.spec_path + (kind,)
        return self._skill_node(
            skill_name,
            inputs,
            spec.get("outputs") or {},
            spec.get("success_on"),
            spec.get("params"),
            scope,
            inputs_path,
        )

    def _skill_node(
        self,
        skill_name: str,
        inputs: Any,
        outputs: Any,
        success_on: Any,
        params: Any,
        scope: _Scope,
        inputs_path: SpecPath,
    ) -> SkillBehaviour | None:
        """Resolve and check everything a skill node needs; shared by tree leaves and machine states."""
        skill_path = inputs_path[:-1] + (("skill",) if inputs_path[-1] == "inputs" else (skill_name,))
        if not isinstance(skill_name, str):
            self._problem(skill_path, f"a skill is named by a string, got {type(skill_name).__name__}")
            return None
        try:
            cls = self.engine.registry.get(skill_name)
        except UnknownSkillError as exc:
            self._problem(
                inputs_path[:-1] + ("skill",) if inputs_path[-1] == "inputs" else inputs_path[:-1] + (skill_name,),
                str(exc).split(" (")[0],
                f"did you mean {exc.suggestion!r}?" if exc.suggestion else "",
            )
            return None
        ok = True
        if not isinstance(inputs, Mapping):
            self._problem(inputs_path, f"inputs of {skill_name!r} must be a mapping of port: value")
            return None
        bound: dict[str, Any] = {}
        # a key-naming port left at its default still names a key: the node needs access to it
        defaults = {
            n: p.default
            for n, p in cls.inputs.items()
            if p.names_key and isinstance(p.default, str) and n not in inputs
        }
        for port_name, raw in {**inputs, **defaults}.items():
            port = cls.inputs.get(port_name)
            if port is None:
                self._problem(
                    inputs_path + (port_name,),
                    f"skill {skill_name!r} has no input {port_name!r}",
                    did_you_mean(str(port_name), cls.inputs),
                )
                ok = False
                continue
            value = parse_binding(raw)
            if isinstance(value, KeyRef):
                key = self._key(value.key, inputs_path + (port_name,), scope)
                if key is None:
                    ok = False
                    continue
                value = KeyRef(key)
                self._use(key, "read", inputs_path + (port_name,), scope, port.type)
            else:
                try:
                    value = check_type(port.type, value)
                except TypeError as exc:
                    self._problem(inputs_path + (port_name,), f"input {port_name!r} of {skill_name!r}: {exc}")
                    ok = False
                    continue
                if port.expression:
                    expression = self._expression(value, inputs_path + (port_name,), scope)
                    if expression is None:
                        ok = False
                    elif scope.remap:
                        value = remap_condition(value, scope.remap)
                elif port.names_key and isinstance(value, str):
                    value = self._key(value, inputs_path + (port_name,), scope)
                    if value is None:
                        ok = False
                        continue
                    self._use(value, port.names_key, inputs_path + (port_name,), scope)
            bound[port_name] = value
        for port_name, port in cls.inputs.items():
            if port.default is MISSING and port_name not in bound and port_name not in inputs:
                self._problem(inputs_path, f"skill {skill_name!r} needs input {port_name!r}")
                ok = False
        if not isinstance(outputs, Mapping):
            self._problem(inputs_path[:-1] + ("outputs",), "outputs must map output ports to blackboard keys")
            outputs = {}
        out: dict[str, str] = {}
        for port_name, raw in outputs.items():
            key = parse_output(raw)
            if port_name not in cls.outputs:
                self._problem(
                    inputs_path[:-1] + ("outputs", port_name),
                    f"skill {skill_name!r} has no output {port_name!r}",
                    did_you_mean(str(port_name), cls.outputs),
                )
                ok = False
            elif key is None:
                self._problem(inputs_path[:-1] + ("outputs", port_name), "an output binds to a key name")
                ok = False
            else:
                checked = self._key(key, inputs_path[:-1] + ("outputs", port_name), scope)
                if checked is None:
                    ok = False
                    continue
                out[port_name] = checked
                self._use(
                    checked, "write", inputs_path[:-1] + ("outputs", port_name), scope, cls.outputs[port_name].type
                )
        success = self._success_on(
            success_on, cls.all_outcomes, inputs_path[:-1] + ("success_on",), default=cls.success_outcomes
        )
        merged = dict(self.skill_params.get(skill_name, {}))
        if params is not None:
            if not isinstance(params, Mapping):
                self._problem(inputs_path[:-1] + ("params",), "params must be a mapping")
                return None
            merged.update(params)
        try:
            skill = cls(merged)
        except ValidationError as exc:
            for err in exc.errors():
                self._problem(inputs_path[:-1] + ("params", *err["loc"]), f"parameter of {skill_name!r}: {err['msg']}")
            return None
        if not ok or success is None:
            return None
        return SkillBehaviour(scope.path.rsplit("/", 1)[-1], scope.path, skill, self.engine, bound, out, success)

    def _success_on(
        self, value: Any, outcomes: Iterable[str], spec_path: SpecPath, default: Iterable[str] = ("success",)
    ) -> frozenset[str] | None:
        if value is None:
            return frozenset(default)
        names = [value] if isinstance(value, str) else value
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            self._problem(spec_path, "success_on must be an outcome name or a list of them")
            return None
        known = set(outcomes)
        for index, outcome in enumerate(names):
            if outcome not in known:
                self._problem(
                    spec_path + ((index,) if isinstance(value, list) else ()),
                    f"unknown outcome {outcome!r}",
                    did_you_mean(outcome, known) or "known: " + ", ".join(sorted(known)),
                )
                return None
        return frozenset(names)

    # -- machines ---------------------------------------------------------------------------

    def _machine_ref(self, spec: Mapping[str, Any], scope: _Scope) -> MachineBehaviour | None:
        ref = spec["machine"]
        spec_path = scope.spec_path + ("machine",)
        if isinstance(ref, str):
            if ref not in self.machines:
                self._problem(spec_path, f"unknown machine {ref!r}", did_you_mean(ref, self.machines))
                return None
            entry = f"machine {ref}"
            if entry in scope.subtrees:
                self._problem(spec_path, f"machine cycle: {' -> '.join((*scope.subtrees, entry))}")
                return None
            ref_scope = _Scope(scope.path, ("machines", ref), scope.remap, (*scope.subtrees, entry))
            return self._machine(self.machines[ref], ref_scope, scope.path.rsplit("/", 1)[-1])
        return self._machine(
            ref, _Scope(scope.path, spec_path, scope.remap, scope.subtrees), scope.path.rsplit("/", 1)[-1]
        )

    def _machine(self, spec: Any, scope: _Scope, name: str) -> MachineBehaviour | None:
        states: dict[str, StateInfo] = {}
        preemptions: list[tuple[Expression, str]] = []
        level = self._machine_level(spec, scope, "", states, preemptions)
        if level is None:
            return None
        initial, outcomes = level.initial, level.outcomes
        top = [level.full(n) for n in [*outcomes, *level.names]]
        self._resolve_outcomes(states, preemptions, scope)
        # By default a machine succeeds on `success`, or else on the first outcome it declares.
        default = "success" if "success" in outcomes else outcomes[0]
        success_on = self._success_on(spec.get("success_on", default), outcomes, scope.spec_path + ("success_on",))
        if success_on is None:
            success_on = frozenset({default})
        reads, writes = plan_access(states, preemptions)
        plan = MachinePlan(
            initial=initial,
            states=states,
            top=top,
            outcomes=outcomes,
            preemptions=preemptions,
            level=level,
            success_on=success_on,
            reads=reads,
            writes=writes,
        )
        self.plans.append(plan)
        if self.problems:
            return None
        return MachineBehaviour(name, scope.path, plan, self.engine)

    def _resolve_outcomes(
        self, states: dict[str, StateInfo], preemptions: list[tuple[Expression, list[Target]]], scope: _Scope
    ) -> None:
        """Turn targets that are outcomes of nested machines into direct transitions."""
        local = {path: dict(info.transitions) for path, info in states.items()}
        for path, info in states.items():
            for outcome in list(info.transitions):
                try:
                    info.transitions[outcome] = resolve_outcome(states, local, path, outcome)
                except Unresolved as exc:
                    self._problem(states[exc.state].spec_path, str(exc))
                    info.transitions[outcome] = []
        levels = [(None, preemptions)] + [(p, i.preemptions) for p, i in states.items() if i.preemptions]
        for _, items in levels:
            for index, (condition, targets) in enumerate(items):
                try:
                    step = (f"preempt {condition.source!r}",)
                    direct = [d for t in targets for d in resolve_target(states, local, t, step)]
                except Unresolved as exc:
                    self._problem(states[exc.state].spec_path, str(exc))
                    direct = []
                items[index] = (condition, direct)

    def _machine_level(
        self,
        spec: Any,
        scope: _Scope,
        prefix: str,
        states: dict[str, StateInfo],
        preemptions: list[tuple[Expression, str]],
    ) -> Level | None:
        """Add one level's states (and their nested levels) under ``prefix``."""
        if not isinstance(spec, Mapping):
            self._problem(scope.spec_path, f"a machine is a mapping with `states`, got {type(spec).__name__}")
            return None
        for key in spec:
            if key not in MACHINE_KEYS:
                self._problem(
                    scope.spec_path + (key,), f"unknown machine option {key!r}", did_you_mean(str(key), MACHINE_KEYS)
                )
        state_specs = spec.get("states")
        if not isinstance(state_specs, Mapping) or not state_specs:
            self._problem(scope.spec_path + ("states",), "a machine needs `states`: a mapping of name: state")
            return None
        outcomes = spec.get("outcomes", ["success", "failure"])
        if not isinstance(outcomes, list) or not outcomes or not all(isinstance(o, str) for o in outcomes):
            self._problem(scope.spec_path + ("outcomes",), "outcomes must be a non-empty list of names")
            outcomes = ["success", "failure"]
        names = list(state_specs)
        for name in names:
            if not isinstance(name, str) or not name.isidentifier() or name.startswith("__"):
                self._problem(
                    scope.spec_path + ("states", str(name)),
                    f"state name {name!r} must be an identifier (letters, digits, _)",
                )
                return None
            if name in outcomes:
                self._problem(
                    scope.spec_path + ("states", name), f"state {name!r} has the name of one of the machine's outcomes"
                )
        initial = spec.get("initial", names[0])
        if not isinstance(initial, str) or initial not in state_specs:
            self._problem(
                scope.spec_path + ("initial",),
                f"initial state {initial!r} is not a state",
                did_you_mean(str(initial), names),
            )
            initial = names[0]

        level = Level(prefix, scope.spec_path, "", outcomes, names)
        level.initial = level.full(initial)
        full = level.full
        parent = prefix or None
        for outcome in outcomes:
            states[full(outcome)] = StateInfo(full(outcome), parent, outcome=outcome, kind="outcome")
        for name, state_spec in state_specs.items():
            self._state(name, state_spec, scope.child(name, "states", name), full, names, outcomes, states, parent)
        preemption_specs = spec.get("preemptions") or []
        if not isinstance(preemption_specs, list):
            self._problem(scope.spec_path + ("preemptions",), "preemptions is a list of {when: ..., to: ...}")
            preemption_specs = []
        for index, item in enumerate(preemption_specs):
            item_path = scope.spec_path + ("preemptions", index)
            if not isinstance(item, Mapping) or set(item) != {"when", "to"}:
                self._problem(item_path, "a preemption is {when: <condition>, to: <state or outcome>}")
                continue
            condition = self._expression(item["when"], item_path + ("when",), scope)
            target = item["to"]
            if not isinstance(target, str) or (target not in state_specs and target not in outcomes):
                self._problem(
                    item_path + ("to",),
                    f"unknown state or outcome {target!r}",
                    did_you_mean(str(target), [*names, *outcomes]),
                )
                continue
            level.preemptions.append((str(item["when"]), str(target)))
            if condition is not None:
                preemptions.append((condition, [Target(full(target))]))
        return level

    def _state(
        self,
        name: str,
        spec: Any,
        scope: _Scope,
        full: Any,
        siblings: list[str],
        outcomes: list[str],
        states: dict[str, StateInfo],
        parent: str | None,
    ) -> None:
        path = full(name)
        info = StateInfo(path, parent, spec_path=scope.spec_path)
        states[path] = info
        if not isinstance(spec, Mapping):
            self._problem(scope.spec_path, f"state {name!r} must be a mapping with a skill, tree or machine")
            return
        for key in spec:
            if key not in STATE_KEYS:
                self._problem(
                    scope.spec_path + (key,), f"unknown state option {key!r}", did_you_mean(str(key), STATE_KEYS)
                )
        contents = [k for k in ("skill", "tree", "machine") if k in spec]
        if len(contents) != 1:
            self._problem(scope.spec_path, f"state {name!r} needs exactly one of skill, tree or machine")
            return
        possible: set[str] = {"success", "failure"}
        if "skill" not in spec:
            for key in ("inputs", "outputs", "params", "success_on"):
                if key in spec:
                    self._problem(
                        scope.spec_path + (key,),
                        f"only a skill state takes {key!r}",
                        "give it to the skill inside the tree or machine",
                    )
        if "skill" in spec:
            node = self._skill_node(
                spec["skill"],
                spec.get("inputs") or {},
                spec.get("outputs") or {},
                spec.get("success_on"),
                spec.get("params"),
                scope,
                scope.spec_path + ("inputs",),
            )
            info.kind, info.label = "skill", str(spec["skill"])
            if node is not None:
                info.content = node
                possible = set(type(node.skill).all_outcomes)
        elif "tree" in spec:
            tree = spec["tree"]
            info.kind, info.label = "tree", tree if isinstance(tree, str) else ""
            if isinstance(tree, str):
                if tree not in self.trees:
                    self._problem(scope.spec_path + ("tree",), f"unknown tree {tree!r}", did_you_mean(tree, self.trees))
                    return
                if tree in scope.subtrees:
                    cycle = " -> ".join((*scope.subtrees, tree))
                    self._problem(scope.spec_path + ("tree",), f"tree cycle: {cycle}")
                    return
                tree_scope = _Scope(f"{scope.path}/{tree}", ("trees", tree), scope.remap, (*scope.subtrees, tree))
                info.content = self._node(self.trees[tree], tree_scope)
            else:
                info.content = self._node(tree, scope.child("tree", "tree"))
            if info.content is not None:
                info.content.name = info.content.path.rsplit("/", 1)[-1]
        else:
            nested = spec["machine"]
            nested_scope = _Scope(scope.path, scope.spec_path + ("machine",), scope.remap, scope.subtrees)
            if isinstance(nested, str):
                if nested not in self.machines:
                    self._problem(
                        scope.spec_path + ("machine",),
                        f"unknown machine {nested!r}",
                        did_you_mean(nested, self.machines),
                    )
                    return
                entry = f"machine {nested}"
                if entry in scope.subtrees:
                    cycle = " -> ".join((*scope.subtrees, entry))
                    self._problem(scope.spec_path + ("machine",), f"machine cycle: {cycle}")
                    return
                nested_scope = _Scope(scope.path, ("machines", nested), scope.remap, (*scope.subtrees, entry))
                nested = self.machines[nested]
            info.kind, info.label = "machine", spec["machine"] if isinstance(spec["machine"], str) else ""
            level = self._machine_level(nested, nested_scope, path, states, info.preemptions)
            if level is None:
                return
            info.level, info.initial = level, level.initial
            possible = set(level.outcomes)
        timeout = spec.get("timeout")
        if timeout is not None:
            if not isinstance(timeout, int | float) or isinstance(timeout, bool) or timeout <= 0:
                self._problem(scope.spec_path + ("timeout",), "timeout needs a positive number of seconds")
            else:
                info.timeout = float(timeout)
                possible.add("timeout")
        info.possible = frozenset(possible)
        info.on_enter = self._actions(spec.get("on_enter"), scope.spec_path + ("on_enter",), scope)
        info.on_exit = self._actions(spec.get("on_exit"), scope.spec_path + ("on_exit",), scope)
        transitions = spec.get("transitions") or {}
        if not isinstance(transitions, Mapping):
            self._problem(scope.spec_path + ("transitions",), "transitions map outcomes to states")
            return
        for outcome, targets in transitions.items():
            t_path = scope.spec_path + ("transitions", outcome)
            if outcome not in possible:
                self._problem(
                    t_path,
                    f"state {name!r} never ends with outcome {outcome!r}",
                    did_you_mean(str(outcome), possible) or "possible: " + ", ".join(sorted(possible)),
                )
                continue
            entries = targets if isinstance(targets, list) else [targets]
            resolved = []
            written = info.written.setdefault(outcome, [])
            for index, entry in enumerate(entries):
                e_path = t_path + ((index,) if isinstance(targets, list) else ())
                guard = None
                if isinstance(entry, Mapping):
                    if "to" not in entry or set(entry) - {"to", "if"}:
                        self._problem(e_path, "a guarded transition is {to: <state>, if: <condition>}")
                        continue
                    if "if" in entry:
                        guard = self._expression(entry["if"], e_path + ("if",), scope)
                    entry = entry["to"]
                if not isinstance(entry, str) or (entry not in siblings and entry not in outcomes):
                    self._problem(
                        e_path,
                        f"transition to unknown state {entry!r}",
                        did_you_mean(str(entry), [*siblings, *outcomes]),
                    )
                    continue
                resolved.append(Target(full(entry), (guard,) if guard is not None else ()))
                written.append((str(entry), guard.source if guard is not None else ""))
            info.transitions[outcome] = resolved

    def _actions(self, value: Any, spec_path: SpecPath, scope: _Scope) -> list[Action]:
        if value is None:
            return []
        items = value if isinstance(value, list) else [value]
        actions = []
        for index, item in enumerate(items):
            item_path = spec_path + ((index,) if isinstance(value, list) else ())
            if isinstance(item, Mapping) and set(item) == {"set"} and isinstance(item["set"], Mapping):
                for key, val in item["set"].items():
                    checked = self._key(key, item_path + ("set", key), scope)
                    if checked is not None:
                        actions.append(Action("set", checked, val))
                        self._use(checked, "write", item_path + ("set", key), scope)
            elif isinstance(item, Mapping) and set(item) == {"log"}:
                actions.append(Action("log", value=str(item["log"])))
            else:
                self._problem(item_path, "an action is {set: {key: value, ...}} or {log: message}")
        return actions


def remap_key(key: str, remap: Mapping[str, str]) -> str:
    """A subtree's remapping renames a key, or a whole namespace: {robot: r2} maps robot/mode too."""
    best = ""
    for inner in remap:
        if (key == inner or key.startswith(inner + "/")) and len(inner) > len(best):
            best = inner
    return remap[best] + key[len(best) :] if best else key


def remap_condition(source: str, remap: Mapping[str, str]) -> str:
    """Rewrite the key names of a condition through a subtree's remapping."""

    def as_expr(key: str) -> ast.expr:
        parts = key.split("/")
        expr: ast.expr = ast.Name(parts[0], ast.Load())
        for part in parts[1:]:
            expr = ast.Attribute(expr, part, ast.Load())
        return expr

    class _Rename(ast.NodeTransformer):
        def _swap(self, node: ast.expr) -> ast.AST:
            key = key_of(node)
            if key is None:
                return self.generic_visit(node)
            mapped = remap_key(key, remap)
            return ast.copy_location(as_expr(mapped), node) if mapped != key else node

        visit_Name = _swap
        visit_Attribute = _swap

    return ast.unparse(_Rename().visit(ast.parse(source.strip(), mode="eval")))
