"""Reads back what ``botstage.behaviors.btcpp.export`` writes beyond BT.CPP's own nodes: botstage kinds
(custom nodes of their own name, or BT.CPP built-ins marked ``_botstage``), a skill node's
``_success_on`` and ``_params``, ``<StateMachine>``/``<State>`` machines, named machines
(``<BehaviorTree ID="machine:NAME">``) and the ``<BotstageMission>`` settings.

``botstage.behaviors.btcpp.xml_format`` reads every file with this converter.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

from botstage.behaviors.btcpp.to_spec import Converter, SpecPath, _Tree
from botstage.behaviors.btcpp.vocabulary import (
    ARGUMENT_PORTS,
    COMPOSITES,
    DECORATORS,
    IGNORED,
    MACHINE_PREFIX,
    MARKER,
    MILLISECOND_PORTS,
    NODE_MODELS,
    SETTINGS,
    SKILL_EXTRAS,
    STATE,
    STATE_MACHINE,
    TOP_MACHINE_TREE,
    from_text,
    input_value,
    reads_beyond_btcpp,
    split_outside_quotes,
)
from botstage.behaviors.btcpp.xml_reader import Element
from botstage.behaviors.kinds import CompositeKind, DecoratorKind
from botstage.robots.located_yaml import Location
from botstage.robots.suggest import did_you_mean

_REF = re.compile(r"^\{@?[^{}]*\}$")
_TRANSITION = re.compile(r"^\s*(\S+)\s*->\s*(\S+)(?:\s+if\s+(.+))?\s*$", re.DOTALL)
OWN_LEAVES = frozenset({"skill", "subtree", "machine"})  # written as skills, SubTree, StateMachine


class ExportedConverter(Converter):
    """``to_spec.Converter`` that also reads what botstage's exporter writes."""

    exported = False  # the document holds <BotstageMission>: botstage wrote it

    # -- the document ---------------------------------------------------------------------------

    def document(self, root: Element, path: Path | None = None) -> dict[str, Any] | None:
        settings = [child for child in root.children if child.tag == SETTINGS]
        self.exported = bool(settings)
        rest = replace(root, children=[c for c in root.children if c.tag != SETTINGS])
        data = super().document(rest, path)
        if data is None:
            return None
        trees: dict[str, Any] = data["trees"]
        machines: dict[str, Any] = {}
        for tree_id in [t for t in trees if t.startswith(MACHINE_PREFIX)]:
            spec = trees.pop(tree_id)
            name = tree_id[len(MACHINE_PREFIX) :]
            if isinstance(spec, dict) and set(spec) == {"machine"} and isinstance(spec["machine"], dict):
                machines[name] = spec["machine"]
                self._move(("trees", tree_id, "machine"), ("machines", name))
            else:
                self.problem(self.elements[tree_id].where, f"BehaviorTree {tree_id!r} holds one <StateMachine>")
        if machines:
            data["machines"] = machines
        for element in settings[:1]:
            self._settings(element, data, trees)
        for extra in settings[1:]:
            self.problem(extra.where, f"one <{SETTINGS}> per file")
        return data

    def _settings(self, element: Element, data: dict[str, Any], trees: dict[str, Any]) -> None:
        values: dict[str, Any] = {}
        for key, text in element.attrs.items():
            values[key] = from_text(text)
            self.locations.by_path[(key,)] = element.value_at(key)
        top = values.pop("top_machine", None)
        root = values.pop("root", None)
        data.pop("root", None)
        if root is not None:
            data["root"] = root
        if top == TOP_MACHINE_TREE and isinstance(trees.get(top), dict) and "machine" in trees[top]:
            data["machine"] = trees.pop(top)["machine"]
            self._move(("trees", top, "machine"), ("machine",))
        elif isinstance(top, str) and top.startswith(MACHINE_PREFIX):
            data["machine"] = top[len(MACHINE_PREFIX) :]
        elif top is not None:
            self.problem(element.where, f"top_machine {top!r}: no machine there")
        data.update(values)

    def _move(self, old: SpecPath, new: SpecPath) -> None:
        """Locations recorded under a tree's path now belong to the machine it became."""
        for path in [p for p in self.locations.by_path if p[: len(old)] == old]:
            self.locations.by_path[new + path[len(old) :]] = self.locations.by_path.pop(path)

    # -- nodes ----------------------------------------------------------------------------------

    def node(self, element: Element, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        node_id = element.attrs.get("ID", "") if element.tag in NODE_MODELS else element.tag
        if MARKER in element.attrs:
            self.locations.by_path[path] = element.where
            return self._named(element, self.marked(element, node_id, path, tree))
        if node_id == STATE_MACHINE:
            self.locations.by_path[path] = element.where
            spec = self.machine(element, path + ("machine",), tree)
            if spec is None:
                return None
            node: dict[str, Any] = {"machine": spec}
            if "_success_on" in element.attrs:
                node["success_on"] = _names(element.attrs["_success_on"])
            return self._named(element, node)
        own = node_id in self.kinds and node_id not in self.native and node_id not in OWN_LEAVES
        if own and node_id not in self.registry:
            self.locations.by_path[path] = element.where
            return self._named(element, self.custom(element, node_id, path, tree))
        return super().node(element, path, tree)

    @staticmethod
    def _named(element: Element, spec: dict[str, Any] | None) -> dict[str, Any] | None:
        name = element.attrs.get("name")
        if spec is not None and name and "/" not in name:
            spec["name"] = name
        return spec

    def _attrs(self, element: Element, *known: str) -> dict[str, str] | None:
        """The node's ports (``name``, ``ID`` and Groot2's own attributes left out); None (and a
        problem) when one is not among ``known``."""
        attrs = {k: v for k, v in element.attrs.items() if k not in ("name", "ID", MARKER) and k not in IGNORED}
        for port in attrs:
            if port not in known:
                self.problem(element.where, f"<{element.tag}> has no port {port!r}", did_you_mean(port, known))
                return None
        return attrs

    def _child(self, element: Element, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        if len(element.children) != 1:
            self.problem(element.where, f"<{element.tag}> decorates exactly one node, found {len(element.children)}")
            return None
        return self.node(element.children[0], path, tree)

    def marked(self, element: Element, node_id: str, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        """A BT.CPP built-in written from a botstage kind: that kind again."""
        kind = element.attrs[MARKER]
        if COMPOSITES.get(kind) == node_id:
            if self._attrs(element) is None:
                return None
            if not element.children:
                self.problem(element.where, f"{node_id} needs children")
                return None
            built = [self.node(c, path + (kind, i), tree) for i, c in enumerate(element.children)]
            return None if any(b is None for b in built) else {kind: built}
        if kind not in DECORATORS or DECORATORS[kind][0] != node_id:
            self.problem(element.where, f'{MARKER}="{kind}" does not go with <{node_id}>')
            return None
        port = DECORATORS[kind][1]
        attrs = self._attrs(element, *([port] if port else []))
        if attrs is None:
            return None
        if port is None:
            child = self._child(element, path + (kind,), tree)
            return None if child is None else {kind: child}
        try:
            count = int(attrs[port])
        except (KeyError, ValueError):
            self.problem(element.where, f"{node_id}.{port}: expected a whole number, got {attrs.get(port)!r}")
            return None
        value: Any = count / 1000 if port in MILLISECOND_PORTS else count
        if kind == "repeat" and count == -1:
            value = "forever"
        child = self._child(element, path + ("child",), tree)
        return None if child is None else {kind: value, "child": child}

    def custom(self, element: Element, node_id: str, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        """A botstage kind written as a node of its own name: its argument and options are ports."""
        kind = self.kinds.get(node_id)
        fields = kind.Options.model_fields
        argument = None
        if isinstance(kind, DecoratorKind) and kind.argument is not None:
            argument = ARGUMENT_PORTS.get(node_id, "value")
        elif not isinstance(kind, CompositeKind | DecoratorKind):
            argument = node_id
        attrs = self._attrs(element, *fields, *([argument] if argument else []))
        if attrs is None:
            return None
        spec: dict[str, Any] = {}
        for option, text in attrs.items():
            if option != argument:
                spec[option] = from_text(text, fields[option].annotation)
                self.locations.by_path[path + (option,)] = element.where
        if isinstance(kind, CompositeKind):
            if not element.children:
                self.problem(element.where, f"{node_id} needs children")
                return None
            built = [self.node(c, path + (node_id, i), tree) for i, c in enumerate(element.children)]
            return None if any(b is None for b in built) else {node_id: built, **spec}
        if argument is not None and argument not in attrs:
            self.problem(element.where, f"<{node_id}> needs its port {argument!r}")
            return None
        if isinstance(kind, DecoratorKind):
            if kind.argument is None:
                child = self._child(element, path + (node_id,), tree)
                return None if child is None else {node_id: child, **spec}
            value = from_text(attrs[argument], kind.argument)  # type: ignore[index]
            child = self._child(element, path + ("child",), tree)
            return None if child is None else {node_id: value, "child": child, **spec}
        if element.children:
            self.problem(element.where, f"{node_id} is a leaf: it has no children")
            return None
        text = attrs[argument]  # type: ignore[index]
        return {node_id: text if node_id == "condition" else from_text(text), **spec}

    def skill(
        self, element: Element, skill_name: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        """As ``to_spec`` reads a skill, with ``_success_on``/``_params`` and inputs it leaves as
        text (lists of words, and in botstage's files inputs of any type)."""
        if self.exported:  # botstage wrote every input it had: no TreeNodesModel defaults added
            attrs = {port: text for port, text in attrs.items() if port in element.attrs}
        attrs = dict(attrs)
        extras = {extra: attrs.pop("_" + extra) for extra in SKILL_EXTRAS if "_" + extra in attrs}
        cls = self.registry.get(skill_name)
        own: dict[str, Any] = {}
        for port, text in list(attrs.items()):
            beyond = port in cls.inputs and reads_beyond_btcpp(cls.inputs[port].type, self.exported)
            if beyond and not _REF.match(text.strip()):
                own[port] = input_value(cls.inputs[port].type, text, self.exported)
                del attrs[port]
                self.locations.by_path[path + (skill_name, port)] = element.value_at(port)
        spec = super().skill(element, skill_name, attrs, path, tree)
        if spec is None:
            return None
        spec[skill_name] = {**spec[skill_name], **own}
        if "success_on" in extras:
            spec["success_on"] = _names(extras["success_on"])
        if "params" in extras:
            try:
                spec["params"] = json.loads(extras["params"])
            except ValueError as exc:
                self.problem(element.where, f"_params of {skill_name!r}: not JSON ({exc})")
                return None
        return spec

    def subtree(
        self, element: Element, tree_id: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        """A SubTree to a named machine is a ``machine`` node; any other is ``to_spec``'s."""
        if not tree_id.startswith(MACHINE_PREFIX):
            return super().subtree(element, tree_id, attrs, path, tree)
        if tree_id not in self.elements:
            self.problem(
                element.where, f"no BehaviorTree {tree_id!r} for this SubTree", did_you_mean(tree_id, self.elements)
            )
            return None
        if self.tree(tree_id, element.where) is None:
            return None
        spec: dict[str, Any] = {"machine": tree_id[len(MACHINE_PREFIX) :]}
        name = attrs.get("name")
        if name and "/" not in name:
            spec["name"] = name
        if "_success_on" in attrs:
            spec["success_on"] = _names(attrs["_success_on"])
        self.locations.by_path[path + ("machine",)] = element.where
        return spec

    # -- machines -------------------------------------------------------------------------------

    def machine(self, element: Element, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        ports = ("initial", "outcomes", "success_on", "preemptions", "machine_name", "_success_on")
        attrs = self._attrs(element, *ports)
        if attrs is None:
            return None
        self.locations.by_path[path] = element.where
        spec: dict[str, Any] = {}
        if "machine_name" in attrs:
            spec["name"] = attrs["machine_name"]
        if "initial" in attrs:
            spec["initial"] = attrs["initial"]
        if "outcomes" in attrs:
            spec["outcomes"] = [part for part in attrs["outcomes"].split(";") if part]
        if "success_on" in attrs:
            spec["success_on"] = _names(attrs["success_on"])
        if "preemptions" in attrs:
            preemptions = []
            for entry in _entries(attrs["preemptions"]):
                parts = split_outside_quotes(entry, "->")
                if len(parts) < 2 or not parts[-1].strip():
                    self.problem(element.where, f"preemption {entry.strip()!r}: expected CONDITION -> STATE")
                    return None
                preemptions.append({"when": "->".join(parts[:-1]).strip(), "to": parts[-1].strip()})
            spec["preemptions"] = preemptions
        if not element.children:
            self.problem(element.where, "a StateMachine needs its states as children")
            return None
        states: dict[str, Any] = {}
        for child in element.children:
            name = child.attrs.get("name", "")
            if child.tag != STATE or not name:
                self.problem(child.where, f'a StateMachine\'s children are <State name="…">, not <{child.tag}>')
                return None
            if name in states:
                self.problem(child.where, f"duplicate state {name!r}")
                return None
            state = self.state(child, path + ("states", name), tree)
            if state is None:
                return None
            states[name] = state
        spec["states"] = states
        return spec

    def state(self, element: Element, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        ports = ("transitions", "timeout", "on_enter", "on_exit", "skill", "tree", "machine")
        attrs = self._attrs(element, *ports)
        if attrs is None:
            return None
        self.locations.by_path[path] = element.where
        if len(element.children) != 1:
            self.problem(element.where, f"a State holds exactly one node, found {len(element.children)}")
            return None
        child = element.children[0]
        state: dict[str, Any] = {}
        if "skill" in attrs:
            node = self.node(child, path, tree)
            skill = attrs["skill"]
            if node is None:
                return None
            if skill not in node:
                self.problem(child.where, f"State skill={skill!r} holds a <{skill}> node")
                return None
            state["skill"] = skill
            if node[skill]:
                state["inputs"] = node[skill]
            state |= {k: node[k] for k in ("outputs", *SKILL_EXTRAS) if k in node}
        elif "tree" in attrs or "machine" in attrs:
            content = "tree" if "tree" in attrs else "machine"
            expected = attrs[content] if content == "tree" else MACHINE_PREFIX + attrs[content]
            if child.tag != "SubTree" or child.attrs.get("ID") != expected:
                self.problem(child.where, f'State {content}={attrs[content]!r} holds <SubTree ID="{expected}"/>')
                return None
            if self.node(child, path + (content,), tree) is None:
                return None
            state[content] = attrs[content]
        elif child.tag == STATE_MACHINE:
            machine = self.machine(child, path + ("machine",), tree)
            if machine is None:
                return None
            state["machine"] = machine
        else:
            node = self.node(child, path + ("tree",), tree)
            if node is None:
                return None
            state["tree"] = node
        if "transitions" in attrs:
            transitions = self._transitions(attrs["transitions"], element.where)
            if transitions is None:
                return None
            state["transitions"] = transitions
        if "timeout" in attrs:
            state["timeout"] = from_text(attrs["timeout"], float)
            if not isinstance(state["timeout"], int | float):
                self.problem(element.where, f"State timeout: expected seconds, got {attrs['timeout']!r}")
                return None
        for actions in ("on_enter", "on_exit"):
            if actions in attrs:
                try:
                    state[actions] = json.loads(attrs[actions])
                except ValueError as exc:
                    self.problem(element.where, f"State {actions}: not a JSON list of actions ({exc})")
                    return None
        return state

    def _transitions(self, text: str, where: Location) -> dict[str, Any] | None:
        """``outcome -> state [if condition]; …`` as transitions (one outcome's entries in order)."""
        transitions: dict[str, list[Any]] = {}
        for entry in _entries(text):
            found = _TRANSITION.match(entry)
            if found is None:
                self.problem(where, f"transition {entry.strip()!r}: expected OUTCOME -> STATE [if CONDITION]")
                return None
            outcome, target, guard = found.groups()
            transitions.setdefault(outcome, []).append(target if guard is None else {"to": target, "if": guard.strip()})
        return {outcome: targets[0] if len(targets) == 1 else targets for outcome, targets in transitions.items()}


def _entries(text: str) -> list[str]:
    return [part for part in split_outside_quotes(text, ";") if part.strip()]


def _names(text: str) -> str | list[str]:
    """``a`` or ``a;b``: one outcome name, or a list of them."""
    names = [part.strip() for part in text.split(";") if part.strip()]
    return names[0] if len(names) == 1 else names
