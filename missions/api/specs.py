"""Plain spec data (a mission file's trees and machines) read back into the API's objects.

So a file loads into the same objects Python builds. A spec is read into objects only where
that changes nothing: anything odd (two kinds in one node, a null option) stays plain data, which
the API accepts anywhere, so the checker sees exactly what the file said.
"""

from __future__ import annotations

from typing import Any

from botstage.behaviors.kinds import CompositeKind, DecoratorKind, NodeKinds
from botstage.missions.api.machine import Preemption, State, StateMachine
from botstage.missions.api.nodes import BUILT_IN, Node


class _Reader:
    """Reads one mission's specs, with the node-kind registry's shapes looked up once: the
    option names, the composites and the decorators whose value is their child (so a kind
    added there, or by a plug-in, reads back without a change here)."""

    def __init__(self) -> None:
        kinds = NodeKinds.default()
        options = {"name"}
        composites, plain = set(), set()
        for name in kinds:
            kind = kinds.get(name)
            options |= kind.option_names()
            if isinstance(kind, CompositeKind):
                composites.add(name)
            elif isinstance(kind, DecoratorKind) and kind.argument is None:
                plain.add(name)
        self.options, self.composites, self.plain_decorators = (
            frozenset(options),
            frozenset(composites),
            frozenset(plain),
        )

    def node(self, spec: Any) -> Any:
        """A node spec as a Node (of the built-in kind's class), or the spec itself."""
        if not isinstance(spec, dict) or not all(isinstance(k, str) for k in spec):
            return spec
        kinds = [k for k in spec if k not in self.options]
        if len(kinds) != 1 or any(v is None for k, v in spec.items() if k != kinds[0]):
            return spec
        kind = kinds[0]
        value = spec[kind]
        if kind in self.composites and isinstance(value, list):
            value = [self.node(child) for child in value]
        elif kind in self.plain_decorators:
            value = self.node(value)
        elif kind == "machine":
            value = self.machine(value)
        options = {k: (self.node(v) if k == "child" else v) for k, v in spec.items() if k != kind}
        node = BUILT_IN.get(kind, Node).of(kind, value, options)
        node.order = tuple(spec)
        return node

    def machine(self, spec: Any) -> Any:
        """A machine spec as a StateMachine, or the spec itself."""
        if not _plain_mapping(spec) or not isinstance(spec.get("states"), dict) or not spec["states"]:
            return spec
        preemptions = spec.get("preemptions", [])
        if not isinstance(preemptions, list) or not all(isinstance(k, str) for k in spec["states"]):
            return spec
        states = {name: self.state(state) for name, state in spec["states"].items()}
        read = [
            Preemption(item["when"], item["to"], None)
            if isinstance(item, dict) and set(item) == {"when", "to"}
            else item
            for item in preemptions
        ]
        return StateMachine.of(spec, states, read)

    def state(self, spec: Any) -> Any:
        if not _plain_mapping(spec):
            return spec
        options = dict(spec)
        if "tree" in options and not isinstance(options["tree"], str):
            options["tree"] = self.node(options["tree"])
        if "machine" in options and not isinstance(options["machine"], str):
            options["machine"] = self.machine(options["machine"])
        return State(options, None)


def _plain_mapping(spec: Any) -> bool:
    return isinstance(spec, dict) and all(isinstance(k, str) for k in spec) and None not in spec.values()


def node_of(spec: Any) -> Any:
    """A node spec as a Node (of the built-in kind's class), or the spec itself."""
    return _Reader().node(spec)


def machine_of(spec: Any) -> Any:
    """A machine spec as a StateMachine, or the spec itself."""
    return _Reader().machine(spec)
