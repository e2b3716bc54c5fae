"""The built-in leaves: skills, conditions, subtrees and machines.

They are registered like any other kind; their building is the builder's own work (binding
ports, resolving trees and planning machines), which they ask of it through ``b.builder``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import py_trees
from pydantic import Field

from botstage.behaviors.kinds.base import (
    CONDITION_SCHEMA,
    MACHINE_REF,
    NODE_REF,
    Described,
    KindOptions,
    LeafKind,
    NodeBuild,
)
from botstage.behaviors.skill_behaviour import KeyRef, SkillBehaviour
from botstage.skills.registry import Registry

SUCCESS_ON_SCHEMA: dict[str, Any] = {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}]}


class SkillOptions(KindOptions):
    """A skill node's bindings; each is checked against the skill's contract when built."""

    inputs: Any = Field(default=None, description="input ports: literals or {key}")
    outputs: Any = Field(default=None, description="output ports to blackboard keys")
    success_on: Any = Field(default=None, description="the outcomes that count as success")
    params: Any = Field(default=None, description="the skill's parameters")


class Skill(LeafKind):
    """``{skill: wait, inputs: {...}}``, or ``{wait: {...}}`` with the skill's name as the key."""

    name = "skill"
    description = "run a skill"
    Options = SkillOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        spec = b.spec
        if b.key == "skill":
            skill_name = spec["skill"]
            if not isinstance(skill_name, str):
                b.problem("skill must be a skill name", "skill")
                return None
            inputs, inputs_path = spec.get("inputs") or {}, b.spec_path + ("inputs",)
        else:
            if "inputs" in spec:
                b.problem(f"give the inputs of {b.key!r} as its value, or use `skill: {b.key}`", "inputs")
            skill_name, inputs, inputs_path = b.key, spec[b.key] or {}, b.spec_path + (b.key,)
        return b.builder.skill_node(
            skill_name,
            inputs,
            spec.get("outputs") or {},
            spec.get("success_on"),
            spec.get("params"),
            b.scope,
            inputs_path,
        )

    def default_name(self, spec: Mapping[str, Any]) -> str:
        return spec["skill"] if isinstance(spec.get("skill"), str) else self.name

    def written(self) -> str:
        return "skill: NAME, inputs: {...}  or  NAME: {inputs}"

    def describe(self, node: py_trees.behaviour.Behaviour) -> Described:
        return describe_skill(node)

    def schema_properties(self, registry: Registry) -> dict[str, Any]:
        return {
            "skill": {"enum": list(registry)},
            "inputs": {"type": "object"},
            "outputs": {"type": "object", "additionalProperties": {"type": "string"}},
            "success_on": SUCCESS_ON_SCHEMA,
            "params": {"type": "object"},
        }


class Condition(LeafKind):
    """A condition on the blackboard: success if it holds, else failure (the `check` skill)."""

    name = "condition"
    description = "succeed if the condition holds, else fail"
    shape = "condition"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        return b.builder.skill_node(
            "check", {"condition": b.value}, {}, None, None, b.scope, b.spec_path + ("condition",)
        )

    def describe(self, node: py_trees.behaviour.Behaviour) -> Described:
        return describe_skill(node)

    def value_schema(self, registry: Registry) -> dict[str, Any]:
        return CONDITION_SCHEMA

    def written(self) -> str:
        return "condition: CONDITION"


class SubtreeOptions(KindOptions):
    remap: Any = Field(default=None, description="inner key names to outer key names")


class Subtree(LeafKind):
    """A named tree of the mission, its keys optionally remapped: ``{subtree: t, remap: {...}}``."""

    name = "subtree"
    description = "run a named tree of the mission"
    Options = SubtreeOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        return b.builder.subtree(b.spec, b.scope)

    def default_name(self, spec: Mapping[str, Any]) -> str:
        return spec["subtree"] if isinstance(spec.get("subtree"), str) else self.name

    def written(self) -> str:
        return "subtree: TREE"

    def schema_properties(self, registry: Registry) -> dict[str, Any]:
        return {"subtree": {"type": "string"}, "remap": {"type": "object", "additionalProperties": {"type": "string"}}}


class MachineOptions(KindOptions):
    success_on: Any = Field(default=None, description="the machine outcomes that count as success")


class Machine(LeafKind):
    """A state machine in a tree: a named machine of the mission, or one written inline."""

    name = "machine"
    description = "run a state machine"
    Options = MachineOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        return b.builder.machine_ref(b.spec, b.scope)

    def default_name(self, spec: Mapping[str, Any]) -> str:
        return spec["machine"] if isinstance(spec.get("machine"), str) else self.name

    def value_schema(self, registry: Registry) -> dict[str, Any]:
        return {"anyOf": [{"type": "string"}, MACHINE_REF]}

    def written(self) -> str:
        return "machine: NAME or {states: ...}"


def describe_skill(node: py_trees.behaviour.Behaviour) -> Described:
    """A skill node's title (its name, or `name: skill`), port bindings and success outcomes."""
    assert isinstance(node, SkillBehaviour)
    skill = node.skill
    plain = node.name == skill.name or (node.name == "condition" and skill.kind == "condition")
    title = skill.name if plain else f"{node.name}: {skill.name}"
    details = [f"{port}={_value(value)}" for port, value in node.inputs.items()]
    details += [f"{port} → {{{key}}}" for port, key in node.outputs.items()]
    if node.success_on != frozenset(skill.success_outcomes):
        details.append("success on " + ", ".join(sorted(node.success_on)))
    return Described(title, "condition" if skill.kind == "condition" else "skill", details)


def _value(value: Any) -> str:
    if isinstance(value, KeyRef):
        return str(value)
    text = json.dumps(value) if isinstance(value, str | int | float | bool | type(None) | list | dict) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


__all__ = ["NODE_REF", "Condition", "Machine", "Skill", "Subtree", "describe_skill"]
