"""A run's trees and machines as Groot2 sees them: BT.CPP v4 XML with ``_uid`` attributes, and
the trace's events as status changes of those uids.

Uids are numbered from 1 in depth-first order, parent before children, as BT.CPP's factory
numbers the nodes it creates (``Tree::getUID`` pre-increments a counter that starts at 0), so
the same mission always gets the same uids. Subtrees are inlined (botstage has one blackboard
per mission, not one per subtree), so the XML holds one ``<BehaviorTree>``, named after the
mission.

A state machine is a ``StateMachine`` Control node with a ``State`` Decorator node per state (in
the order written; a machine's outcomes are not nodes) whose child is what the state runs: a
tree, a skill, or its nested machine (a ``StateMachine`` node of its own), the shape
``behaviors/btcpp/export.py`` writes. The machine node has its own status (it is a tree node like
any other: RUNNING while a state is active, then SUCCESS or FAILURE with its outcome); a state is
RUNNING while it is on the active path, and when it is left it becomes SUCCESS if it ended with
outcome ``success``, FAILURE with ``failure``, and IDLE otherwise (other outcomes, timeouts,
preemptions and halts). A nested machine's node changes with its state's.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any, get_args, get_origin

import py_trees

from botstage.behaviors.machine import Level, MachineBehaviour, MachinePlan
from botstage.behaviors.skill_behaviour import KeyRef, SkillBehaviour
from botstage.missions.groot2.protocol import FAILURE, IDLE, IDLE_FROM, PY_TREES, RUNNING, SUCCESS

MAX_UID = 0xFFFF
MACHINE_TAG = "StateMachine"
STATE_TAG = "State"

# botstage's kinds by the names BT.CPP gives the same semantics
_BTCPP_NAMES = {
    "sequence": "Sequence",
    "reactive_sequence": "ReactiveSequence",
    "selector": "Fallback",
    "fallback": "Fallback",
    "reactive_selector": "ReactiveFallback",
    "reactive_fallback": "ReactiveFallback",
    "parallel": "Parallel",
    "inverter": "Inverter",
    "force_success": "ForceSuccess",
    "force_failure": "ForceFailure",
    "retry": "RetryUntilSuccessful",
    "repeat": "Repeat",
    "timeout": "Timeout",
    "delay": "Delay",
    "keep_running_until_failure": "KeepRunningUntilFailure",
    "one_shot": "RunOnce",
}
# BT.CPP's built-in nodes: Groot2 knows their models, so the XML need not carry them
BUILTIN = frozenset(
    {
        *_BTCPP_NAMES.values(),
        "SequenceWithMemory",
        "ParallelAll",
        "IfThenElse",
        "WhileDoElse",
        "Switch2",
        "Switch3",
        "Switch4",
        "Switch5",
        "Switch6",
        "Sleep",
        "AlwaysSuccess",
        "AlwaysFailure",
        "SetBlackboard",
        "SubTree",
    }
)


@dataclass
class GrootNode:
    """One node of the XML: a tree node, a machine or a state."""

    uid: int
    tag: str  # the registration ID: the element's name in the XML
    model: str  # Action, Condition, Control or Decorator
    name: str
    path: str  # a node's path in the trace; a state's is "<machine path>/<state path>"
    behaviour: py_trees.behaviour.Behaviour | None  # what runs when it starts (None: a state holding a machine)
    attributes: dict[str, str] = field(default_factory=dict)
    children: list[GrootNode] = field(default_factory=list)
    ports: list[tuple[str, str, str, str]] = field(default_factory=list)  # (direction, name, type, doc)
    is_state: bool = False


class GrootTree:
    """The picture of one built root: its nodes by uid, the XML, and where trace events land."""

    def __init__(self, root: py_trees.behaviour.Behaviour, tree_id: str) -> None:
        self.tree_id = tree_id
        self.nodes: list[GrootNode] = []
        self.by_path: dict[str, int] = {}  # a tree node's trace path -> uid
        self.states: dict[str, dict[str, int]] = {}  # machine path -> state path -> uid
        self.nested: dict[int, int] = {}  # a state's uid -> the uid of the machine it holds
        self.root = self._node(root)

    # -- building ---------------------------------------------------------------------------

    def _new(self, **fields: Any) -> GrootNode:
        if len(self.nodes) >= MAX_UID:
            raise ValueError(f"more than {MAX_UID} nodes: Groot2's uids are 16 bits")
        node = GrootNode(uid=len(self.nodes) + 1, **fields)
        self.nodes.append(node)
        return node

    def _node(self, behaviour: py_trees.behaviour.Behaviour) -> GrootNode:
        path = getattr(behaviour, "path", behaviour.name)
        if isinstance(behaviour, MachineBehaviour):
            node = self._new(tag=MACHINE_TAG, model="Control", name=behaviour.name, path=path, behaviour=behaviour)
            self.by_path.setdefault(path, node.uid)
            self.states[path] = {}
            node.children = self._level(behaviour.plan, behaviour.plan.level, path)
            return node
        tag, model = _tag_and_model(behaviour)
        node = self._new(tag=tag, model=model, name=behaviour.name, path=path, behaviour=behaviour)
        self.by_path.setdefault(path, node.uid)
        if isinstance(behaviour, SkillBehaviour):
            node.attributes = _ports_written(behaviour)
            node.ports = _ports_declared(behaviour)
        node.children = [self._node(child) for child in behaviour.children]
        return node

    def _level(self, plan: MachinePlan, level: Level, machine_path: str) -> list[GrootNode]:
        states = []
        for name in level.names:
            info = plan.states[level.full(name)]
            path = f"{machine_path}/{info.path}"
            state = self._new(
                tag=STATE_TAG, model="Decorator", name=name, path=path, behaviour=info.content, is_state=True
            )
            self.states[machine_path][info.path] = state.uid
            if info.content is not None:
                state.children = [self._node(info.content)]
            elif info.level is not None:  # its machine is a node of its own, in step with the state
                nested = self._new(tag=MACHINE_TAG, model="Control", name=name, path=f"{path}#machine", behaviour=None)
                self.nested[state.uid] = nested.uid
                nested.children = self._level(plan, info.level, machine_path)
                state.children = [nested]
            states.append(state)
        return states

    # -- the XML ----------------------------------------------------------------------------

    def xml(self) -> str:
        """What BT.CPP's ``WriteTreeToXML(tree, add_metadata=true, add_builtin_models=false)`` writes
        for this tree: the tree with ``_uid`` on every node, then the models of non-built-in nodes."""
        root = ET.Element("root", BTCPP_format="4")
        tree = ET.SubElement(root, "BehaviorTree", ID=self.tree_id, _fullpath="")
        self._element(self.root, tree)
        models = ET.SubElement(root, "TreeNodesModel")
        seen: dict[str, GrootNode] = {}
        for node in self.nodes:
            if node.tag not in BUILTIN:
                seen.setdefault(node.tag, node)
        for tag in sorted(seen):
            node = seen[tag]
            model = ET.SubElement(models, node.model, ID=tag)
            for direction, name, type_name, doc in node.ports:
                port = ET.SubElement(model, direction, name=name)
                if type_name:
                    port.set("type", type_name)
                if doc:
                    port.text = doc
        ET.indent(root, space="  ")
        return ET.tostring(root, encoding="unicode")

    def _element(self, node: GrootNode, parent: ET.Element) -> None:
        element = ET.SubElement(parent, node.tag, name=node.name, _uid=str(node.uid))
        for key, value in node.attributes.items():
            element.set(key, value)
        for child in node.children:
            self._element(child, element)

    # -- where events land -------------------------------------------------------------------

    def changes(self, record: Mapping[str, Any]) -> Iterator[tuple[int, int]]:
        """The (uid, BT.CPP status) changes a trace event stands for, in the order they happened."""
        kind = record["ev"]
        if kind == "status":
            uid = self.by_path.get(record["node"])
            if uid is not None:
                yield uid, PY_TREES.get(record["new"], IDLE)
        elif kind == "transition":
            states = self.states.get(record["machine"])
            if states is None:
                return
            source, dest = _chain(record["source"]), _chain(record["dest"])
            outcomes = _outcomes(record["trigger"])
            for path in reversed([p for p in source if p not in dest]):  # left, innermost first
                if path in states:
                    outcome = outcomes.get(path)
                    status = SUCCESS if outcome == "success" else FAILURE if outcome == "failure" else IDLE
                    yield from self._state(states[path], status)
            for path in dest:
                if path not in source and path in states:  # entered, outermost first
                    yield from self._state(states[path], RUNNING)

    def _state(self, uid: int, status: int) -> Iterator[tuple[int, int]]:
        yield uid, status
        if uid in self.nested:
            yield self.nested[uid], status


class StatusBuffer:
    """The STATUS reply: for every node its uint16 uid and uint8 status, with "idle after X"
    written 10 + X as BT.CPP's ``Groot2Publisher::callback`` writes it."""

    def __init__(self, tree: GrootTree) -> None:
        self.current = {node.uid: IDLE for node in tree.nodes}
        self.buffer = bytearray()
        self._offset: dict[int, int] = {}
        for node in tree.nodes:
            self.buffer += node.uid.to_bytes(2, "little") + bytes((IDLE,))
            self._offset[node.uid] = len(self.buffer) - 1

    def set(self, uid: int, status: int) -> int:
        """Record a change; returns the status it had."""
        previous = self.current[uid]
        self.current[uid] = status
        self.buffer[self._offset[uid]] = IDLE_FROM + previous if status == IDLE else status
        return previous


def _chain(state: str) -> list[str]:
    """A state path and its enclosing states', outermost first: ``a/b`` -> ``[a, a/b]``."""
    if not state:
        return []
    parts = state.split("/")
    return ["/".join(parts[: i + 1]) for i in range(len(parts))]


def _outcomes(trigger: str) -> dict[str, str]:
    """The outcome each state ended with, from a transition's trigger (``work/place:success >
    work:done``); preemptions, starts and halts name none."""
    found = {}
    for step in trigger.split(" > "):
        state, colon, outcome = step.rpartition(":")
        if colon and state:
            found[state] = outcome
    return found


def _tag_and_model(behaviour: py_trees.behaviour.Behaviour) -> tuple[str, str]:
    if isinstance(behaviour, SkillBehaviour):
        return behaviour.skill.name, "Condition" if behaviour.skill.kind == "condition" else "Action"
    kind = getattr(behaviour, "node_kind", None)
    name = kind.name if kind is not None else type(behaviour).__name__
    memory = getattr(behaviour, "memory", True)
    if name in ("sequence", "selector", "fallback") and not memory:
        name = "reactive_" + name
    tag = _BTCPP_NAMES.get(name) or (name if name[:1].isupper() else _camel(name))
    shape = getattr(kind, "shape", "")
    if shape in ("sequence", "selector", "parallel") or len(behaviour.children) > 1:
        return tag, "Control"
    if shape == "decorator" or behaviour.children:
        return tag, "Decorator"
    return tag, "Condition" if shape == "condition" else "Action"


def _camel(name: str) -> str:
    return "".join(part[:1].upper() + part[1:] for part in name.split("_")) or "Node"


def _ports_written(node: SkillBehaviour) -> dict[str, str]:
    """A skill node's bindings as BT.CPP attributes: literals as text, keys as ``{key}``."""
    written = {}
    for port, value in node.inputs.items():
        if isinstance(value, KeyRef):
            written[port] = str(value)
        else:
            written[port] = value if isinstance(value, str) else json.dumps(value, default=repr)
    for port, key in node.outputs.items():
        written.setdefault(port, "{" + key + "}")
    return written


def _ports_declared(node: SkillBehaviour) -> list[tuple[str, str, str, str]]:
    skill = type(node.skill)
    ports = []
    for direction, declared in (("input_port", skill.inputs), ("output_port", skill.outputs)):
        for name, port in declared.items():
            ports.append((direction, name, _type_name(port.type), port.doc))
    return ports


def _type_name(tp: Any) -> str:
    if get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    if tp is Any:
        return ""
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")
