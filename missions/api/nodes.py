"""Tree nodes built in Python, as py_trees' composites and decorators are built.

Each node lowers to exactly the spec mapping its YAML spelling loads as: ``Timeout(10, child)`` is
``{timeout: 10, child: ...}``. ``Node(kind, value, **options)`` is the general form, so a plug-in
node kind is used like a built-in one; the rest are shorthands for the built-in kinds.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, ClassVar

from botstage.missions.api.lowering import Lowering, Part, SpecPath, in_order
from botstage.missions.api.where import caller
from botstage.missions.loader import Location

NodeLike = Any  # a Node, a StateMachine (run as a node), a spec mapping, or a skill's name


def key(name: str) -> str:
    """A blackboard key bound to an input: ``key("battery_pct")`` is ``"{battery_pct}"``."""
    if not isinstance(name, str) or not name:
        raise TypeError(f"a key is named by a non-empty string, got {name!r}")
    return "{" + name + "}"


def as_node(value: NodeLike) -> Any:
    """What may stand where a tree node is expected, or a TypeError at the line that put it there."""
    if isinstance(value, Part):
        return value.as_node()
    if isinstance(value, str | Mapping):
        return value
    hint = " (pass children one by one: Sequence(a, b), or Sequence(*nodes))" if isinstance(value, list | tuple) else ""
    raise TypeError(
        "a tree node is a Node (Sequence(...), Skill(...), ...), a StateMachine, a spec mapping or a "
        f"skill's name; got {type(value).__name__}{hint}"
    )


class Node(Part):
    """Any node: ``{kind: value, **options}``; options left None are not written."""

    KIND: ClassVar[str] = ""

    def __init__(self, kind: str, value: Any = None, /, **options: Any) -> None:
        if not isinstance(kind, str) or not kind:
            raise TypeError(f"a node's kind is a name (sequence, wait, ...), got {kind!r}")
        self.kind = kind
        self.value = value
        self.options = {name: option for name, option in options.items() if option is not None}
        self.where: Location | None = caller()
        self.order: tuple[str, ...] | None = None  # a file's key order

    @classmethod
    def of(cls, kind: str, value: Any, options: dict[str, Any], where: Location | None = None) -> Node:
        """A node of this class from parts already checked (a file's), without recording a caller."""
        node = cls.__new__(cls)
        node.kind, node.value, node.options, node.where, node.order = kind, value, options, where, None
        return node

    def lower(self, low: Lowering, path: SpecPath) -> dict[str, Any]:
        data = {self.kind: low.value(self.value, path + (self.kind,))}
        for name, option in self.options.items():
            data[name] = low.value(option, path + (name,))
        return in_order(data, self.order)

    def as_node(self) -> Node:
        return self

    def __repr__(self) -> str:
        where = f" at {self.where}" if self.where is not None else ""
        return f"<{type(self).__name__} {self.kind}{where}>"


# -- composites -------------------------------------------------------------------------------


class _Composite(Node):
    def __init__(self, *children: NodeLike, name: str | None = None, memory: bool | None = None) -> None:
        super().__init__(self.KIND, [as_node(child) for child in children], name=name, memory=memory)

    @property
    def children(self) -> list[Any]:
        return self.value if isinstance(self.value, list) else []


class Sequence(_Composite):
    """Children in order until one fails; with memory, a running child is resumed."""

    KIND = "sequence"


class Selector(_Composite):
    """Children in order until one succeeds (a fallback); with memory by default."""

    KIND = "selector"


class Fallback(_Composite):
    """The same node as Selector, spelled as BehaviorTree.CPP spells it."""

    KIND = "fallback"


class ReactiveSequence(_Composite):
    """A sequence without memory: earlier children (conditions) are re-checked every tick."""

    KIND = "reactive_sequence"


class ReactiveSelector(_Composite):
    """A selector without memory: a higher-priority child that now succeeds preempts."""

    KIND = "reactive_selector"


class ReactiveFallback(_Composite):
    KIND = "reactive_fallback"


class Parallel(_Composite):
    """Children ticked together; ``policy`` success_on_all (default), success_on_one or
    success_on_selected with ``selected`` child names."""

    KIND = "parallel"

    def __init__(
        self,
        *children: NodeLike,
        policy: str | None = None,
        synchronise: bool | None = None,
        selected: Iterable[str] | None = None,
        name: str | None = None,
    ) -> None:
        Node.__init__(
            self,
            self.KIND,
            [as_node(child) for child in children],
            policy=policy,
            synchronise=synchronise,
            selected=list(selected) if selected is not None else None,
            name=name,
        )


# -- decorators -------------------------------------------------------------------------------


class _PlainDecorator(Node):
    """A decorator whose value is its child."""

    def __init__(self, child: NodeLike, *, name: str | None = None) -> None:
        super().__init__(self.KIND, as_node(child), name=name)

    @property
    def child(self) -> Any:
        return self.value


class Inverter(_PlainDecorator):
    KIND = "inverter"


class ForceSuccess(_PlainDecorator):
    KIND = "force_success"


class ForceFailure(_PlainDecorator):
    KIND = "force_failure"


class OneShot(_PlainDecorator):
    """Runs its child once; ``policy`` on_success (default) or on_completion."""

    KIND = "one_shot"

    def __init__(self, child: NodeLike, *, policy: str | None = None, name: str | None = None) -> None:
        Node.__init__(self, self.KIND, as_node(child), policy=policy, name=name)


class _ArgDecorator(Node):
    """A decorator whose value is an argument and whose child is under ``child``."""

    def __init__(self, argument: Any, child: NodeLike, *, name: str | None = None) -> None:
        super().__init__(self.KIND, argument, child=as_node(child), name=name)

    @property
    def child(self) -> Any:
        return self.options.get("child")


class Retry(_ArgDecorator):
    """``Retry(3, child)``: try the child up to 3 times while it fails."""

    KIND = "retry"


class Repeat(_ArgDecorator):
    """``Repeat(3, child)`` or ``Repeat("forever", child)``: run the child again while it succeeds."""

    KIND = "repeat"


class Timeout(_ArgDecorator):
    """``Timeout(10, child)``: fail, halting the child, after 10 s of mission time."""

    KIND = "timeout"


class While(_ArgDecorator):
    """``While("battery_pct > 20", child)``: an eternal guard, checked every tick."""

    KIND = "while"


class If(_ArgDecorator):
    """``If("greeted", child)``: checked only before the child starts."""

    KIND = "if"


# -- leaves -----------------------------------------------------------------------------------


class Condition(Node):
    """``Condition("battery_pct > 20 and not estop")``: the ``check`` skill."""

    KIND = "condition"

    def __init__(self, condition: str, *, name: str | None = None) -> None:
        super().__init__(self.KIND, condition, name=name)


class Skill(Node):
    """A skill: ``Skill("wait", duration=2)``; inputs are keywords (or ``inputs=`` for names the
    keywords below take), literals or keys (``key("x")``). ``name`` names the node in the tree."""

    KIND = "skill"

    def __init__(
        self,
        skill: str,
        /,
        *,
        name: str | None = None,
        inputs: Mapping[str, Any] | None = None,
        outputs: Mapping[str, str] | None = None,
        success_on: str | Iterable[str] | None = None,
        params: Mapping[str, Any] | None = None,
        **more_inputs: Any,
    ) -> None:
        merged = {**(inputs or {}), **more_inputs}
        super().__init__(
            self.KIND,
            skill,
            inputs=merged or None,
            outputs=dict(outputs) if outputs is not None else None,
            success_on=success_on if success_on is None or isinstance(success_on, str) else list(success_on),
            params=dict(params) if params is not None else None,
            name=name,
        )

    @property
    def skill(self) -> Any:
        return self.value

    @property
    def inputs(self) -> Any:
        return self.options.get("inputs", {})


class Subtree(Node):
    """A named tree of the mission, its keys renamed by ``remap`` ({inner: outer})."""

    KIND = "subtree"

    def __init__(self, tree: str, *, remap: Mapping[str, str] | None = None, name: str | None = None) -> None:
        super().__init__(self.KIND, tree, remap=dict(remap) if remap is not None else None, name=name)


class MachineRef(Node):
    """A state machine as a node: a named machine of the mission, or a StateMachine itself."""

    KIND = "machine"

    def __init__(self, machine: Any, *, success_on: str | Iterable[str] | None = None, name: str | None = None) -> None:
        super().__init__(
            self.KIND,
            machine,
            success_on=success_on if success_on is None or isinstance(success_on, str) else list(success_on),
            name=name,
        )


BUILT_IN: dict[str, type[Node]] = {
    cls.KIND: cls
    for cls in (
        Sequence,
        Selector,
        Fallback,
        ReactiveSequence,
        ReactiveSelector,
        ReactiveFallback,
        Parallel,
        Inverter,
        ForceSuccess,
        ForceFailure,
        OneShot,
        Retry,
        Repeat,
        Timeout,
        While,
        If,
        Condition,
        Skill,
        Subtree,
        MachineRef,
    )
}
COMPOSITES = frozenset(k for k, c in BUILT_IN.items() if issubclass(c, _Composite))
PLAIN_DECORATORS = frozenset(k for k, c in BUILT_IN.items() if issubclass(c, _PlainDecorator))
