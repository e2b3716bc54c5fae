"""A skill node from what a tree leaf or a machine state writes: its ports bound to keys or
literals, its outputs to keys, its success outcomes and its parameters, each checked against
the skill's contract and reported where it was written."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from botstage.behaviors.skill_behaviour import KeyRef, SkillBehaviour
from botstage.robots.suggest import did_you_mean
from botstage.skills.base import MISSING, Skill, check_type
from botstage.skills.registry import UnknownSkillError

if TYPE_CHECKING:
    from botstage.behaviors.builder import Builder, Scope, SpecPath


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


class SkillBinder:
    """Binds one skill node for a builder; problems go to the builder, at their places."""

    def __init__(self, builder: Builder) -> None:
        self.b = builder

    def node(
        self,
        skill_name: Any,
        inputs: Any,
        outputs: Any,
        success_on: Any,
        params: Any,
        scope: Scope,
        inputs_path: SpecPath,
    ) -> SkillBehaviour | None:
        """The node, or None when anything is wrong (every problem is reported, not just the first)."""
        base = inputs_path[:-1]
        named_by_key = inputs_path[-1] != "inputs"  # `{wait: {...}}` rather than `skill: wait`
        skill_path = base + ((skill_name,) if named_by_key else ("skill",))
        if not isinstance(skill_name, str):
            self.b.problem(skill_path, f"a skill is named by a string, got {type(skill_name).__name__}")
            return None
        try:
            cls = self.b.runtime.registry.get(skill_name)
        except UnknownSkillError as exc:
            hint = f"did you mean {exc.suggestion!r}?" if exc.suggestion else ""
            self.b.problem(skill_path, str(exc).split(" (")[0], hint)
            return None
        self.b.skills_used.setdefault(skill_name, []).append(skill_path)
        if not isinstance(inputs, Mapping):
            self.b.problem(inputs_path, f"inputs of {skill_name!r} must be a mapping of port: value")
            return None
        bound = self.inputs(cls, inputs, scope, inputs_path)
        out = self.outputs(cls, outputs, scope, base + ("outputs",))
        success = self.b.success_on(success_on, cls.all_outcomes, base + ("success_on",), cls.success_outcomes)
        skill = self.skill(cls, params, base + ("params",))
        if bound is None or out is None or success is None or skill is None:
            return None
        return SkillBehaviour(scope.path.rsplit("/", 1)[-1], scope.path, skill, self.b.runtime, bound, out, success)

    def inputs(
        self, cls: type[Skill], inputs: Mapping[str, Any], scope: Scope, inputs_path: SpecPath
    ) -> dict[str, Any] | None:
        """Each port bound to a literal of its type or to a key; None if any is wrong."""
        ok = True
        bound: dict[str, Any] = {}
        # a key-naming port left at its default still names a key: the node needs access to it
        defaults = {
            n: p.default
            for n, p in cls.inputs.items()
            if p.names_key and isinstance(p.default, str) and n not in inputs
        }
        for port_name, raw in {**inputs, **defaults}.items():
            value = self._input(cls, port_name, raw, scope, inputs_path + (port_name,))
            if value is _WRONG:
                ok = False
            else:
                bound[port_name] = value
        for port_name, port in cls.inputs.items():
            if port.default is MISSING and port_name not in bound and port_name not in inputs:
                self.b.problem(inputs_path, f"skill {cls.name!r} needs input {port_name!r}")
                ok = False
        return bound if ok else None

    def _input(self, cls: type[Skill], port_name: str, raw: Any, scope: Scope, where: SpecPath) -> Any:
        port = cls.inputs.get(port_name)
        if port is None:
            self.b.problem(where, f"skill {cls.name!r} has no input {port_name!r}", did_you_mean(port_name, cls.inputs))
            return _WRONG
        value = parse_binding(raw)
        if isinstance(value, KeyRef):
            key = self.b.key(value.key, where, scope)
            if key is None:
                return _WRONG
            self.b.use(key, "read", where, scope, port.type)
            return KeyRef(key)
        try:
            value = check_type(port.type, value, finite=True)
        except TypeError as exc:
            self.b.problem(where, f"input {port_name!r} of {cls.name!r}: {exc}")
            return _WRONG
        if port.expression:
            if self.b.expression(value, where, scope) is None:
                return _WRONG
            return self.b.remapped_condition(value, scope)
        if port.names_key and isinstance(value, str):
            key = self.b.key(value, where, scope)
            if key is None:
                return _WRONG
            self.b.use(key, port.names_key, where, scope)
            return key
        return value

    def outputs(self, cls: type[Skill], outputs: Any, scope: Scope, where: SpecPath) -> dict[str, str] | None:
        """Each output port bound to the key it writes; None if any is wrong."""
        if not isinstance(outputs, Mapping):
            self.b.problem(where, "outputs must map output ports to blackboard keys")
            outputs = {}
        ok = True
        out: dict[str, str] = {}
        for port_name, raw in outputs.items():
            key = parse_output(raw)
            if port_name not in cls.outputs:
                hint = did_you_mean(port_name, cls.outputs)
                self.b.problem(where + (port_name,), f"skill {cls.name!r} has no output {port_name!r}", hint)
                ok = False
            elif key is None:
                self.b.problem(where + (port_name,), "an output binds to a key name")
                ok = False
            else:
                checked = self.b.key(key, where + (port_name,), scope)
                if checked is None:
                    ok = False
                    continue
                out[port_name] = checked
                self.b.use(checked, "write", where + (port_name,), scope, cls.outputs[port_name].type)
        return out if ok else None

    def skill(self, cls: type[Skill], params: Any, where: SpecPath) -> Skill | None:
        """The skill with the mission's parameters for it, overridden by the node's own."""
        merged = dict(self.b.skill_params.get(cls.name, {}))
        if params is not None:
            if not isinstance(params, Mapping):
                self.b.problem(where, "params must be a mapping")
                return None
            merged.update(params)
        try:
            return cls(merged)
        except ValidationError as exc:
            for err in exc.errors():
                self.b.problem(where + tuple(err["loc"]), f"parameter of {cls.name!r}: {err['msg']}")
            return None


class _Wrong:
    """A port that could not be bound (its problem is reported)."""


_WRONG: Any = _Wrong()


def success_outcomes(
    value: Any, outcomes: Iterable[str], default: Iterable[str]
) -> tuple[frozenset[str] | None, str, tuple[int, ...], str]:
    """``success_on`` as written: (the outcomes or None, a problem, where below it, a hint)."""
    if value is None:
        return frozenset(default), "", (), ""
    names = [value] if isinstance(value, str) else value
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return None, "success_on must be an outcome name or a list of them", (), ""
    known = set(outcomes)
    for index, outcome in enumerate(names):
        if outcome not in known:
            where = (index,) if isinstance(value, list) else ()
            hint = did_you_mean(outcome, known) or "known: " + ", ".join(sorted(known))
            return None, f"unknown outcome {outcome!r}", where, hint
    return frozenset(names), "", (), ""
