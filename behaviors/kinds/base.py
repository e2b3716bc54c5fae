"""What a node kind is: the one place that says how a kind of tree node is written, checked,
built, drawn and described in the JSON Schema.

Built-in kinds (sequence, timeout, skill, ...) and plug-in kinds are the same thing: a subclass
of one of the three bases below, registered by name (BehaviorTree.CPP's factory registers its
own nodes the way users register theirs). A kind never parses a spec itself: the builder reads
the spec's shape (children, child, argument, options), validates it and hands the kind a
``NodeBuild`` with everything resolved; the kind only makes the py_trees behaviour.

The three shapes of a node spec::

    {sequence: [child, ...], memory: false}      # CompositeKind: the value is the children
    {inverter: child}                            # DecoratorKind without an argument
    {timeout: 5, child: child}                   # DecoratorKind with an argument
    {subtree: approach, remap: {...}}            # LeafKind: the value is the kind's own
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import py_trees
from pydantic import BaseModel, ConfigDict, TypeAdapter

if TYPE_CHECKING:
    from botstage.behaviors.runtime import Runtime
    from botstage.skills.expression import Expression
    from botstage.skills.registry import Registry

SpecPath = tuple[str | int, ...]
NODE_REF: dict[str, Any] = {"$ref": "#/$defs/node"}
MACHINE_REF: dict[str, Any] = {"$ref": "#/$defs/machine"}
CONDITION_SCHEMA: dict[str, Any] = {
    "type": "string",
    "description": "a condition, e.g. battery_pct > 20 and not estop",
}


class KindOptions(BaseModel):
    """Options written beside a node's kind; strict, so `memory: "yes"` is an error, not True."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class NoOptions(KindOptions):
    """A kind that takes no options besides `name`."""


@dataclass(frozen=True)
class Described:
    """How pictures show a node: its title, its shape and lines of detail."""

    title: str
    shape: str  # sequence, selector, parallel, decorator, skill or condition (how pictures draw it)
    details: list[str] = field(default_factory=list)


@dataclass
class NodeBuild:
    """Everything a kind needs to make its node, already checked by the builder."""

    kind: NodeKind
    key: str  # the kind's key as written: the kind's name, or a skill's name for `{wait: ...}`
    name: str  # the node's name (the last segment of its path)
    path: str  # its path in the trace, e.g. "root/patrol/timeout"
    spec: Mapping[str, Any]  # the node's whole spec, as written
    spec_path: SpecPath  # where the spec is, for located problems
    options: Any  # the kind's Options, validated
    runtime: Runtime
    builder: Any  # the Builder: leaf kinds that build other nodes (subtree, machine) use it
    scope: Any  # the builder's Scope of this node (its path, remapping, trees on the way)
    value: Any = None  # a decorator's argument (validated) or a leaf's value (as written)
    children: list[py_trees.behaviour.Behaviour] = field(default_factory=list)

    @property
    def child(self) -> py_trees.behaviour.Behaviour:
        return self.children[0]

    def problem(self, message: str, *where: str | int, hint: str = "") -> None:
        """Report a problem at this node's spec, or at ``where`` below it."""
        self.builder.problem(self.spec_path + where, message, hint)

    def expression(self, source: Any, *where: str | int) -> Expression | None:
        """Compile a condition written at ``where``, remapped and with its keys recorded as read."""
        return self.builder.expression(source, self.spec_path + where, self.scope)


class NodeKind:
    """One kind of tree node. Subclass CompositeKind, DecoratorKind or LeafKind."""

    name: ClassVar[str] = ""
    # other spellings still read as this kind but never listed: one concept, one listed name
    aliases: ClassVar[tuple[str, ...]] = ()
    description: ClassVar[str] = ""
    shape: ClassVar[str] = "decorator"
    Options: ClassVar[type[KindOptions]] = NoOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        """Make the behaviour; report problems with ``b.problem`` and return None instead."""
        raise NotImplementedError

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        """The node's title in pictures, from the behaviour as built."""
        return self.name.replace("_", " ")

    def describe(self, node: py_trees.behaviour.Behaviour) -> Described:
        return Described(self.title(node), self.shape)

    def default_name(self, spec: Mapping[str, Any]) -> str:
        """The node's name when the spec gives none (siblings get #2, #3 ...)."""
        return self.name

    def option_names(self) -> set[str]:
        return set(self.Options.model_fields)

    def written(self) -> str:
        """How a node of this kind is written, for listings: ``timeout: ARG, child: NODE``."""
        return f"{self.name}: VALUE"

    def schema_properties(self, registry: Registry) -> dict[str, Any]:
        """This kind's properties of the node object in the mission JSON Schema."""
        return {self.name: self.value_schema(registry), **_option_schemas(self.Options)}

    def value_schema(self, registry: Registry) -> dict[str, Any]:
        return {"description": self.description} if self.description else {}


class CompositeKind(NodeKind):
    """A node whose value is its list of children, built before ``build`` is called."""

    shape: ClassVar[str] = "sequence"

    def value_schema(self, registry: Registry) -> dict[str, Any]:
        return {"type": "array", "items": NODE_REF, **_described(self.description)}

    def written(self) -> str:
        return f"{self.name}: [NODE, ...]"


class DecoratorKind(NodeKind):
    """A node with one child. Without an ``argument`` type the value is the child
    (``{inverter: child}``); with one, the value is the argument, validated against that type,
    and the child is under ``child`` (``{timeout: 5, child: ...}``)."""

    shape: ClassVar[str] = "decorator"
    argument: ClassVar[Any] = None  # a type pydantic validates strictly, e.g. Annotated[float, Field(gt=0)]
    argument_help: ClassVar[str] = ""  # what the argument is, for errors: "a positive number of seconds"

    def option_names(self) -> set[str]:
        return super().option_names() | ({"child"} if self.argument is not None else set())

    def written(self) -> str:
        return f"{self.name}: NODE" if self.argument is None else f"{self.name}: ARG, child: NODE"

    def value_schema(self, registry: Registry) -> dict[str, Any]:
        if self.argument is None:
            return {**NODE_REF}
        return {**argument_adapter(self.argument).json_schema(), **_described(self.description)}

    def schema_properties(self, registry: Registry) -> dict[str, Any]:
        properties = super().schema_properties(registry)
        if self.argument is not None:
            properties["child"] = NODE_REF
        return properties


class LeafKind(NodeKind):
    """A node whose value means what the kind says (a skill's inputs, a tree's name ...)."""

    shape: ClassVar[str] = "skill"


_ADAPTERS: dict[int, TypeAdapter[Any]] = {}


def argument_adapter(tp: Any) -> TypeAdapter[Any]:
    """A strict validator for a decorator's argument type (cached: building one is slow)."""
    adapter = _ADAPTERS.get(id(tp))
    if adapter is None:
        adapter = _ADAPTERS[id(tp)] = TypeAdapter(tp, config=ConfigDict(strict=True, allow_inf_nan=False))
    return adapter


def _described(description: str) -> dict[str, Any]:
    return {"description": description} if description else {}


def _option_schemas(options: type[BaseModel]) -> dict[str, Any]:
    schema = options.model_json_schema()
    properties: dict[str, Any] = schema.get("properties", {})
    return {name: {k: v for k, v in prop.items() if k != "title"} for name, prop in properties.items()}


def merge_property(existing: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """Two kinds with an option of the same name: one schema that accepts either."""
    if existing == new:
        return existing
    if "enum" in existing and "enum" in new:
        return {**existing, "enum": list(dict.fromkeys([*existing["enum"], *new["enum"]]))}
    alternatives: Sequence[dict[str, Any]] = existing.get("anyOf", [existing])
    return {"anyOf": [*alternatives, new]}
