"""A botstage mission as BehaviorTree.CPP v4 XML: a file BT.CPP's parser accepts, Groot2 opens
(its ``TreeNodesModel`` declares every node that is not BT.CPP's own, with typed, described
ports), and ``botstage.behaviors.btcpp.to_spec`` reads back to the same mission.

- Each named tree is a ``<BehaviorTree ID>`` in BT.CPP's compact syntax (``<navigate goal=…/>``).
- botstage kinds that behave as a BT.CPP built-in are written under its tag, with ``_botstage``
  naming the botstage kind so the import restores exactly that kind (BT.CPP and Groot2 keep
  ``_``-attributes as non-port metadata; without it the node reads as BT.CPP's own, same behaviour).
- Other botstage kinds are custom nodes of their own name, their argument and options as ports.
- ``{subtree: t, remap: {a: b}}`` is ``<SubTree ID="t" a="{b}" _autoremap="true"/>``: botstage's
  subtrees share the blackboard, which is what ``_autoremap`` gives in BT.CPP.
- State machines are a ``<StateMachine>`` Control node whose children are ``<State>`` decorators,
  each holding what the state runs; transitions, timeouts, actions and preemptions are ports.
  A named machine is a ``<BehaviorTree ID="machine:NAME">`` that ``<SubTree>``s point to.
- The mission's other settings (robot, world, seed, keys, blackboard, …) are one
  ``<BotstageMission>`` element, each attribute a JSON value (a plain string as it is); BT.CPP
  only reads ``BehaviorTree``, ``TreeNodesModel`` and ``include`` under ``<root>``, so it skips it.
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, get_args, get_origin

from botstage.behaviors.btcpp.vocabulary import (
    ARGUMENT_PORTS,
    COMPOSITES,
    DECORATORS,
    MACHINE_PREFIX,
    MARKER,
    MILLISECOND_PORTS,
    OWN_SET,
    RENAMED,
    SCOPE,
    SETTINGS,
    SKILL_EXTRAS,
    STATE,
    STATE_MACHINE,
    TOP_MACHINE_TREE,
    TREE_KEYS,
    input_value,
    split_outside_quotes,
    to_text,
    typed_text,
)
from botstage.behaviors.kinds import CompositeKind, DecoratorKind, LeafKind, NodeKinds
from botstage.robots.located_yaml import Loaded, Location, Problem
from botstage.skills.base import plain_type, type_name
from botstage.skills.registry import Registry

SpecPath = tuple[str | int, ...]
CPP_TYPES = {
    "float": "double",
    "int": "int",
    "bool": "bool",
    "str": "std::string",
    "list[float]": "std::vector<double>",
}
_NAME = re.compile(r"^[^\W\d][\w.\-]*$")  # what may be an XML attribute (a port's name)
_WORD = re.compile(r"^[^\s;]+$")  # an outcome or state name inside a transitions port


class ExportError(Exception):
    """A mission that cannot be written as BT.CPP XML; each problem says what and where."""

    def __init__(self, problems: list[Problem]) -> None:
        super().__init__("\n".join(str(p) for p in problems))
        self.problems = problems


# -- values as attribute text, and back ----------------------------------------------------------


# -- one canonical spelling of each node ---------------------------------------------------------


def normal_form(data: Mapping[str, Any], registry: Registry | None = None) -> dict[str, Any]:
    """Mission data with each node and state in one spelling, where the builder reads several
    alike: ``{skill: X, inputs: I}`` is ``{X: I}``, a bare skill name is ``{X: {}}``, empty
    bindings are left out, a one-target transition list is its target, ``{to: s}`` is ``s``, one
    action is a list of one, ``success_on: [x]`` is ``x`` and ``repeat: -1`` is ``forever``.
    The exporter writes this form; the round trip returns it."""
    registry = registry or Registry.default()
    out = dict(data)
    if isinstance(out.get("trees"), Mapping):
        out["trees"] = {name: _normal_node(spec, registry) for name, spec in out["trees"].items()}
    if isinstance(out.get("machines"), Mapping):
        out["machines"] = {name: _normal_machine(spec, registry) for name, spec in out["machines"].items()}
    if isinstance(out.get("machine"), Mapping):
        out["machine"] = _normal_machine(out["machine"], registry)
    return out


def _one(value: Any) -> Any:
    return value[0] if isinstance(value, list) and len(value) == 1 else value


def _normal_node(spec: Any, registry: Registry) -> Any:
    if isinstance(spec, str) and spec in registry:
        return {spec: {}}
    if not isinstance(spec, Mapping):
        return spec
    spec = dict(spec)
    if isinstance(spec.get("skill"), str):
        name = spec.pop("skill")
        spec = {name: spec.pop("inputs", None) or {}, **spec}
    for key, value in list(spec.items()):
        if key in registry:
            spec[key] = value or {}
            if not spec.get("outputs"):
                spec.pop("outputs", None)
            if "success_on" in spec:
                spec["success_on"] = _one(spec["success_on"])
        elif key == "repeat" and value == -1:
            spec[key] = "forever"
        elif key == "machine" and isinstance(value, Mapping):
            spec[key] = _normal_machine(value, registry)
        elif key == "remap" and not value:
            del spec[key]
        elif key == "child" or (isinstance(value, Mapping) and key not in ("remap", "params", "outputs")):
            spec[key] = _normal_node(value, registry)
        elif isinstance(value, list) and key not in ("selected", "success_on"):
            spec[key] = [_normal_node(item, registry) for item in value]
    if "success_on" in spec and "machine" in spec:
        spec["success_on"] = _one(spec["success_on"])
    return spec


def _normal_machine(spec: Any, registry: Registry) -> Any:
    if not isinstance(spec, Mapping):
        return spec
    spec = dict(spec)
    if "success_on" in spec:
        spec["success_on"] = _one(spec["success_on"])
    states = spec.get("states")
    if isinstance(states, Mapping):
        spec["states"] = {name: _normal_state(state, registry) for name, state in states.items()}
    return spec


def _normal_state(state: Any, registry: Registry) -> Any:
    if not isinstance(state, Mapping):
        return state
    state = dict(state)
    for key in ("inputs", "outputs", "transitions", "on_enter", "on_exit"):
        if key in state and not state[key]:
            del state[key]
    if "success_on" in state:
        state["success_on"] = _one(state["success_on"])
    for key in ("on_enter", "on_exit"):
        if isinstance(state.get(key), Mapping):
            state[key] = [state[key]]
    if isinstance(state.get("transitions"), Mapping):
        state["transitions"] = {outcome: _normal_targets(t) for outcome, t in state["transitions"].items()}
    if "tree" in state and not isinstance(state["tree"], str):
        state["tree"] = _normal_node(state["tree"], registry)
    if isinstance(state.get("machine"), Mapping):
        state["machine"] = _normal_machine(state["machine"], registry)
    return state


def _normal_targets(targets: Any) -> Any:
    entries = targets if isinstance(targets, list) else [targets]
    plain = [e["to"] if isinstance(e, Mapping) and set(e) == {"to"} else e for e in entries]
    return plain[0] if len(plain) == 1 else plain


# -- the writer ----------------------------------------------------------------------------------


class Exporter:
    """One mission's data to an XML document; problems are collected with their mission locations."""

    def __init__(self, loaded: Loaded, registry: Registry | None = None, kinds: NodeKinds | None = None) -> None:
        self.loaded = loaded
        self.registry = registry or Registry.default()
        self.kinds = kinds or NodeKinds.default(SCOPE)
        # the scope's node sets (BT.CPP's, Nav2's) and plug-in kinds are written with their ports as they are
        self.native = {k for k in self.kinds if self.kinds.origin(k) != "builtin"}
        self.problems: list[Problem] = []
        self.models: dict[str, ET.Element] = {}  # node ID -> its TreeNodesModel entry
        self.data: dict[str, Any] = {}

    def problem(self, path: SpecPath, message: str, hint: str = "") -> None:
        self.problems.append(Problem(self.where(path), message, hint))

    def where(self, path: SpecPath) -> Location:
        return self.loaded.locations.find(path)

    # -- the document ---------------------------------------------------------------------------

    def document(self) -> str:
        raw = self.loaded.data
        if not isinstance(raw, Mapping):
            raise ExportError(self.loaded.problems or [Problem(self.loaded.locations.root, "no mission to export")])
        self.data = data = normal_form(raw, self.registry)
        trees = data.get("trees") or {}
        machines = data.get("machines") or {}
        top = data.get("machine")
        root = ET.Element("root", {"BTCPP_format": "4"})
        ids: dict[str, SpecPath] = {}
        for name in trees:
            self._tree_id(str(name), ("trees", name), ids)
        for name in machines:
            self._tree_id(MACHINE_PREFIX + str(name), ("machines", name), ids)
        if isinstance(top, Mapping):
            self._tree_id(TOP_MACHINE_TREE, ("machine",), ids)
        main = self._main(data, trees, machines)
        if main is not None:
            root.set("main_tree_to_execute", main)
        root.append(ET.Comment(" written by botstage export; BT.CPP and Groot2 skip <BotstageMission> "))
        root.append(self._settings(data, main))
        for name, spec in trees.items():
            root.append(self._behavior_tree(str(name), spec, ("trees", name)))
        for name, spec in machines.items():
            tree = ET.Element("BehaviorTree", {"ID": MACHINE_PREFIX + str(name)})
            tree.append(self.machine(spec, ("machines", name)))
            root.append(tree)
        if isinstance(top, Mapping):
            tree = ET.Element("BehaviorTree", {"ID": TOP_MACHINE_TREE})
            tree.append(self.machine(top, ("machine",)))
            root.append(tree)
        model = ET.SubElement(root, "TreeNodesModel")
        for node_id in sorted(self.models):
            model.append(self.models[node_id])
        if self.problems:
            raise ExportError(self.problems)
        ET.indent(root, space="  ")
        return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"

    def _tree_id(self, tree_id: str, path: SpecPath, ids: dict[str, SpecPath]) -> None:
        """BT.CPP refuses a BehaviorTree ID that names a registered node, or one given twice."""
        if tree_id in self.registry or tree_id in self.kinds or tree_id in (STATE_MACHINE, STATE, "SubTree"):
            what = "a skill" if tree_id in self.registry else "a node kind"
            self.problem(path, f"tree {tree_id!r} has the name of {what}: BT.CPP refuses such a BehaviorTree ID")
        elif tree_id in ids:
            self.problem(path, f"BehaviorTree ID {tree_id!r} is taken (by {'/'.join(map(str, ids[tree_id]))})")
        ids[tree_id] = path

    def _main(self, data: Mapping[str, Any], trees: Mapping[str, Any], machines: Mapping[str, Any]) -> str | None:
        top = data.get("machine")
        if isinstance(top, Mapping):
            return TOP_MACHINE_TREE
        if isinstance(top, str):
            if top not in machines:
                self.problem(("machine",), f"machine {top!r} is not one of the mission's machines")
            return MACHINE_PREFIX + top
        root = data.get("root")
        if isinstance(root, str):
            if root not in trees:
                self.problem(("root",), f"root {root!r} is not one of the mission's trees")
            return root
        if "main" in trees:
            return "main"
        if len(trees) == 1:
            return str(next(iter(trees)))
        self.problem(("trees",), "nothing to run: no machine, no root, no tree `main`")
        return None

    def _settings(self, data: Mapping[str, Any], main: str | None) -> ET.Element:
        element = ET.Element(SETTINGS)
        for key, value in data.items():
            if key not in TREE_KEYS:
                element.set(key, typed_text(value, Any))
        if "root" in data:
            element.set("root", typed_text(data["root"], Any))
        if data.get("machine") is not None and main is not None:
            element.set("top_machine", main)
        return element

    def _behavior_tree(self, tree_id: str, spec: Any, path: SpecPath) -> ET.Element:
        tree = ET.Element("BehaviorTree", {"ID": tree_id})
        node = self.node(spec, path)
        if node is not None:
            tree.append(node)
        return tree

    # -- nodes ----------------------------------------------------------------------------------

    def node(self, spec: Any, path: SpecPath) -> ET.Element | None:
        if not isinstance(spec, Mapping):
            self.problem(path, f"expected a node (a mapping), got {type(spec).__name__}")
            return None
        keys = [k for k in spec if isinstance(k, str) and (k in self.kinds or k in self.registry)]
        if len(keys) != 1:
            self.problem(path, "a node has exactly one kind" + (f", found {', '.join(keys)}" if keys else ""))
            return None
        key = keys[0]
        if key in self.registry and key not in self.kinds:
            element = self.skill(key, spec, path)
        elif key == "subtree":
            element = self.subtree(spec, path)
        elif key == "machine":
            element = self.machine_node(spec, path)
        elif key in self.native:
            element = self.btcpp_node(key, spec, path)
        elif key in COMPOSITES and set(spec) <= {key, "name"}:
            element = self.children(ET.Element(COMPOSITES[key], {MARKER: key}), spec[key], path + (key,))
        elif key in DECORATORS and self._same_decorator(key, spec):
            element = self.mapped_decorator(key, spec, path)
        else:
            element = self.custom(key, spec, path)
        if element is not None and isinstance(spec.get("name"), str):
            element.set("name", spec["name"])
        return element

    def children(self, element: ET.Element, items: Any, path: SpecPath) -> ET.Element | None:
        if not isinstance(items, list) or not items:
            self.problem(path, f"{element.tag} needs a non-empty list of children")
            return None
        for index, item in enumerate(items):
            child = self.node(item, path + (index,))
            if child is not None:
                element.append(child)
        return element

    def _same_decorator(self, key: str, spec: Mapping[str, Any]) -> bool:
        """Written as BT.CPP's node when it behaves the same: counts as they are, times whole ms."""
        _, port = DECORATORS[key]
        if set(spec) - {key, "name", "child"}:
            return False
        if port in MILLISECOND_PORTS:
            value = spec[key]
            ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
            return ok and abs(value * 1000 - round(value * 1000)) < 1e-9
        return True

    def mapped_decorator(self, key: str, spec: Mapping[str, Any], path: SpecPath) -> ET.Element | None:
        tag, port = DECORATORS[key]
        element = ET.Element(tag, {MARKER: key})
        if port is None:
            child_spec, child_path = spec[key], path + (key,)
        else:
            value = spec[key]
            if port in MILLISECOND_PORTS:
                value = round(value * 1000)
            elif value == "forever":
                value = -1
            element.set(port, to_text(value))
            child_spec, child_path = spec.get("child"), path + ("child",)
        child = self.node(child_spec, child_path)
        if child is not None:
            element.append(child)
        return element

    def btcpp_node(self, key: str, spec: Mapping[str, Any], path: SpecPath) -> ET.Element | None:
        """One of BT.CPP's own nodes written in a mission: its tag, its ports as they are."""
        kind = self.kinds.get(key)
        element = ET.Element(key)
        ports = {k: v for k, v in spec.items() if k not in (key, "name")}
        if isinstance(kind, LeafKind):
            ports = dict(spec[key] or {})
        for port, value in ports.items():
            written = {(b, a): c for (b, c), a in RENAMED.items()}.get((key, port), port)
            element.set(self._port_name(written, path + (port,)), to_text(value))
        if self.kinds.node_set(key) != OWN_SET:  # BT.CPP knows its own nodes; the rest are declared
            self._model_kind(key, kind, None)
        if isinstance(kind, CompositeKind):
            return self.children(element, spec[key], path + (key,))
        if isinstance(kind, DecoratorKind):
            child = self.node(spec[key], path + (key,))
            if child is not None:
                element.append(child)
        return element

    def custom(self, key: str, spec: Mapping[str, Any], path: SpecPath) -> ET.Element | None:
        """A botstage kind with no BT.CPP twin: a node of its own name, declared in the model."""
        kind = self.kinds.get(key)
        element = ET.Element(key)
        fields = kind.Options.model_fields
        argument_port = None
        if isinstance(kind, DecoratorKind) and kind.argument is not None:
            argument_port = ARGUMENT_PORTS.get(key, "value")
            element.set(argument_port, typed_text(spec[key], kind.argument))
        elif isinstance(kind, LeafKind):
            argument_port = key
            element.set(key, typed_text(spec[key], str if key == "condition" else Any))
        for option, value in spec.items():
            if option in (key, "name", "child") or value is None:
                continue
            if option not in fields:
                self.problem(path + (option,), f"unknown option {option!r} for {key!r}")
                continue
            element.set(option, typed_text(value, fields[option].annotation))
        self._model_kind(key, kind, argument_port)
        if isinstance(kind, CompositeKind):
            return self.children(element, spec[key], path + (key,))
        if isinstance(kind, DecoratorKind):
            child_path = path + ((key,) if kind.argument is None else ("child",))
            child = self.node(spec[key] if kind.argument is None else spec.get("child"), child_path)
            if child is not None:
                element.append(child)
        return element

    def skill(self, name: str, spec: Mapping[str, Any], path: SpecPath) -> ET.Element | None:
        cls = self.registry.get(name)
        element = ET.Element(name)
        inputs = spec.get(name) or {}
        outputs = spec.get("outputs") or {}
        if not isinstance(inputs, Mapping) or not isinstance(outputs, Mapping):
            self.problem(path, f"the inputs and outputs of {name!r} are mappings")
            return None
        for port, value in inputs.items():
            where = path + (name, port)
            if port not in cls.inputs:
                self.problem(where, f"skill {name!r} has no input {port!r}")
                continue
            text = self._input_text(value, cls.inputs[port].type)
            if text is None:
                self.problem(
                    where,
                    f"input {port!r} of {name!r}: {value!r} has no BT.CPP port text that reads back as it",
                    "set it on the blackboard and bind the port to that key",
                )
                continue
            element.set(self._port_name(port, where), text)
        for port, key in outputs.items():
            where = path + ("outputs", port)
            if port in inputs:
                self.problem(where, f"port {port!r} of {name!r} is bound as input and output: BT.CPP has one attribute")
            elif not isinstance(key, str):
                self.problem(where, f"output {port!r} of {name!r} binds to a key name")
            else:
                element.set(self._port_name(port, where), "{" + key + "}")
        if spec.get("success_on") is not None:
            element.set("_success_on", self._outcomes(spec["success_on"], path + ("success_on",)))
        if spec.get("params") is not None:
            element.set("_params", json.dumps(spec["params"], ensure_ascii=False))
        for option in spec:
            if option not in (name, "outputs", "name", *SKILL_EXTRAS):
                self.problem(path + (option,), f"unknown option {option!r} for skill {name!r}")
        self._model_skill(name)
        return element

    def _input_text(self, value: Any, annotation: Any) -> str | None:
        """A literal input as text ``input_value`` reads back to the same value, else None."""
        if isinstance(value, str) and re.match(r"^\{@?[^{}]*\}$", value.strip()):
            return value  # a key binding, read as one
        listed = get_origin(plain_type(annotation)) in (list, tuple)
        if listed and isinstance(value, list | tuple) and all(isinstance(v, str | int | float) for v in value):
            text = ";".join(to_text(v) for v in value)
        else:
            text = typed_text(value, annotation)
        back = input_value(annotation, text, exported=True)
        same = back == value and (type(back) is type(value) or (type(value) is int and type(back) is float))
        return text if same else None

    def _port_name(self, port: Any, where: SpecPath) -> str:
        if not isinstance(port, str) or not _NAME.match(port) or port in ("ID", "name"):
            self.problem(where, f"{port!r} cannot be a BT.CPP port: it is not an XML attribute name")
        return str(port)

    def subtree(self, spec: Mapping[str, Any], path: SpecPath) -> ET.Element:
        element = ET.Element("SubTree", {"ID": str(spec["subtree"])})
        if spec["subtree"] not in (self.data.get("trees") or {}):
            self.problem(path + ("subtree",), f"unknown tree {spec['subtree']!r}")
        remap = spec.get("remap") or {}
        if not isinstance(remap, Mapping):
            self.problem(path + ("remap",), "remap maps inner key names to outer ones")
            remap = {}
        for inner, outer in remap.items():
            element.set(self._port_name(inner, path + ("remap", inner)), "{" + str(outer) + "}")
        element.set("_autoremap", "true")
        for option in spec:
            if option not in ("subtree", "remap", "name"):
                self.problem(path + (option,), f"unknown option {option!r} for 'subtree'")
        return element

    # -- machines -------------------------------------------------------------------------------

    def machine_node(self, spec: Mapping[str, Any], path: SpecPath) -> ET.Element | None:
        value = spec["machine"]
        if isinstance(value, str):
            if value not in (self.data.get("machines") or {}):
                self.problem(path + ("machine",), f"unknown machine {value!r}")
            element = ET.Element("SubTree", {"ID": MACHINE_PREFIX + value})
        else:
            element = self.machine(value, path + ("machine",))
        if spec.get("success_on") is not None:
            element.set("_success_on", self._outcomes(spec["success_on"], path + ("success_on",)))
        return element

    def machine(self, spec: Any, path: SpecPath) -> ET.Element:
        element = ET.Element(STATE_MACHINE)
        self._model_machine()
        if not isinstance(spec, Mapping) or not isinstance(spec.get("states"), Mapping) or not spec["states"]:
            self.problem(path, "a machine is a mapping with `states`")
            return element
        if "name" in spec:
            element.set("machine_name", str(spec["name"]))
        if "initial" in spec:
            element.set("initial", str(spec["initial"]))
        if "outcomes" in spec:
            element.set("outcomes", self._words(spec["outcomes"], path + ("outcomes",)))
        if "success_on" in spec:
            element.set("success_on", self._outcomes(spec["success_on"], path + ("success_on",)))
        if spec.get("preemptions"):
            element.set("preemptions", self._preemptions(spec["preemptions"], path + ("preemptions",)))
        for option in spec:
            if option not in ("name", "initial", "outcomes", "success_on", "preemptions", "states"):
                self.problem(path + (option,), f"unknown machine option {option!r}")
        for name, state in spec["states"].items():
            element.append(self.state(str(name), state, path + ("states", name)))
        return element

    def state(self, name: str, spec: Any, path: SpecPath) -> ET.Element:
        element = ET.Element(STATE, {"name": name})
        if not isinstance(spec, Mapping):
            self.problem(path, f"state {name!r} must be a mapping with a skill, tree or machine")
            return element
        if spec.get("transitions"):
            element.set("transitions", self._transitions(spec["transitions"], path + ("transitions",)))
        if spec.get("timeout") is not None:
            element.set("timeout", to_text(spec["timeout"]))
        for actions in ("on_enter", "on_exit"):
            if spec.get(actions):
                element.set(actions, json.dumps(spec[actions], ensure_ascii=False))
        content: ET.Element | None = None
        if isinstance(spec.get("skill"), str):
            skill = spec["skill"]
            element.set("skill", skill)
            node = {skill: spec.get("inputs") or {}, **{k: spec[k] for k in ("outputs", *SKILL_EXTRAS) if k in spec}}
            if skill not in self.registry:
                self.problem(path + ("skill",), f"unknown skill {skill!r}")
            else:
                content = self.skill(skill, node, path)
        elif isinstance(spec.get("tree"), str):
            element.set("tree", spec["tree"])
            content = self.subtree({"subtree": spec["tree"]}, path + ("tree",))
        elif "tree" in spec:
            content = self.node(spec["tree"], path + ("tree",))
        elif isinstance(spec.get("machine"), str):
            element.set("machine", spec["machine"])
            content = self.machine_node({"machine": spec["machine"]}, path)
        elif "machine" in spec:
            content = self.machine(spec["machine"], path + ("machine",))
        else:
            self.problem(path, f"state {name!r} needs exactly one of skill, tree or machine")
        known = {"skill", "inputs", "outputs", "params", "success_on", "tree", "machine", "transitions", "timeout"}
        for option in spec:
            if option not in known | {"on_enter", "on_exit"}:
                self.problem(path + (option,), f"unknown state option {option!r}")
        if content is not None:
            element.append(content)
        return element

    def _outcomes(self, value: Any, path: SpecPath) -> str:
        """``success_on``: one outcome, or several as ``a;b``."""
        return value if isinstance(value, str) and _WORD.match(value) else self._words(value, path)

    def _words(self, value: Any, path: SpecPath) -> str:
        """A list of names as BT.CPP writes vectors: ``a;b``."""
        if not isinstance(value, list) or not all(isinstance(v, str) and _WORD.match(v) for v in value):
            self.problem(path, "expected a list of names (no spaces or ';')")
            return ""
        return ";".join(value)

    def _transitions(self, transitions: Any, path: SpecPath) -> str:
        """``outcome -> state; outcome -> state if condition; …`` (a list: one entry each, in order)."""
        if not isinstance(transitions, Mapping):
            self.problem(path, "transitions map outcomes to states")
            return ""
        entries = []
        for outcome, targets in transitions.items():
            for index, target in enumerate(targets if isinstance(targets, list) else [targets]):
                where = path + (outcome,) + ((index,) if isinstance(targets, list) else ())
                to, guard = (target.get("to"), target.get("if")) if isinstance(target, Mapping) else (target, None)
                if not (isinstance(outcome, str) and _WORD.match(outcome) and isinstance(to, str) and _WORD.match(to)):
                    self.problem(where, "a transition's outcome and target are names (no spaces or ';')")
                    continue
                if isinstance(target, Mapping) and set(target) - {"to", "if"}:
                    self.problem(where, "a guarded transition is {to: <state>, if: <condition>}")
                    continue
                entries.append(f"{outcome} -> {to}" + ("" if guard is None else f" if {self._condition(guard, where)}"))
        return "; ".join(entries)

    def _preemptions(self, preemptions: Any, path: SpecPath) -> str:
        """``condition -> state; …``."""
        if not isinstance(preemptions, list):
            self.problem(path, "preemptions is a list of {when: ..., to: ...}")
            return ""
        entries = []
        for index, item in enumerate(preemptions):
            if not isinstance(item, Mapping) or set(item) != {"when", "to"} or not _WORD.match(str(item["to"])):
                self.problem(path + (index,), "a preemption is {when: <condition>, to: <state or outcome>}")
                continue
            entries.append(f"{self._condition(item['when'], path + (index, 'when'))} -> {item['to']}")
        return "; ".join(entries)

    def _condition(self, condition: Any, path: SpecPath) -> str:
        text = str(condition).strip()
        if len(split_outside_quotes(text, ";")) > 1 or len(split_outside_quotes(text, "->")) > 1:
            self.problem(path, "a condition with ';' or '->' outside quotes cannot be written in this port")
        return text

    # -- the TreeNodesModel ---------------------------------------------------------------------

    def _model(self, node_type: str, node_id: str, description: str) -> ET.Element | None:
        if node_id in self.models:
            return None
        element = self.models[node_id] = ET.Element(node_type, {"ID": node_id})
        if description:
            metadata = ET.SubElement(element, "MetadataFields")
            ET.SubElement(metadata, "Metadata", {"description": description})
        return element

    def _model_skill(self, name: str) -> None:
        cls = self.registry.get(name)
        info = cls.describe()
        element = self._model("Condition" if cls.kind == "condition" else "Action", name, info["description"])
        if element is None:
            return
        for port, described in info["inputs"].items():
            direction = "inout_port" if port in info["outputs"] else "input_port"
            default = None if described["required"] else described.get("default")
            _port(element, direction, port, described["type"], described["doc"], default)
        for port, described in info["outputs"].items():
            if port not in info["inputs"]:
                _port(element, "output_port", port, described["type"], described["doc"], None)

    def _model_kind(self, key: str, kind: Any, argument_port: str | None) -> None:
        node_type = {CompositeKind: "Control", DecoratorKind: "Decorator"}
        found = next((t for base, t in node_type.items() if isinstance(kind, base)), "Action")
        element = self._model("Condition" if key == "condition" else found, key, kind.description)
        if element is None:
            return
        if argument_port is not None:
            help_text = getattr(kind, "argument_help", "") or kind.description
            _port(element, "input_port", argument_port, _annotation_name(getattr(kind, "argument", str)), help_text)
        for option, field in kind.Options.model_fields.items():
            _port(element, "input_port", option, _annotation_name(field.annotation), field.description or "")

    def _model_machine(self) -> None:
        machine = self._model(STATE_MACHINE, STATE_MACHINE, "a botstage state machine; its children are its states")
        if machine is not None:
            machine.tag = "Control"
            for port, doc in (
                ("initial", "the state it starts in (default: the first)"),
                ("outcomes", "its outcomes, separated by ';' (default: success;failure)"),
                ("success_on", "the outcomes that count as success, separated by ';'"),
                ("preemptions", "CONDITION -> STATE; …: checked every tick, at any depth below"),
                ("machine_name", "the machine's own name"),
            ):
                _port(machine, "input_port", port, "str", doc)
        state = self._model(STATE, STATE, "a state of a StateMachine: its child is what the state runs")
        if state is not None:
            state.tag = "Decorator"
            for port, doc in (
                ("transitions", "OUTCOME -> STATE [if CONDITION]; …"),
                ("timeout", "seconds in the state before its outcome is timeout"),
                ("on_enter", "actions on entry: a JSON list of {set: {...}} and {log: ...}"),
                ("on_exit", "actions on exit: a JSON list of {set: {...}} and {log: ...}"),
                ("skill", "the skill the state runs (its child)"),
                ("tree", "the named tree the state runs (its child SubTree)"),
                ("machine", "the named machine the state runs (its child SubTree)"),
            ):
                _port(state, "input_port", port, "str", doc)


def _annotation_name(annotation: Any) -> str:
    plain = plain_type(annotation)
    if get_origin(plain) is not None and type(None) in get_args(plain):
        plain = next(a for a in get_args(plain) if a is not type(None))
    return type_name(plain)


def _port(parent: ET.Element, direction: str, name: str, botstage_type: str, doc: str, default: Any = None) -> None:
    attrs = {"name": name, "type": CPP_TYPES.get(botstage_type, botstage_type)}
    if default is not None:
        attrs["default"] = to_text(default)
    port = ET.SubElement(parent, direction, attrs)
    port.text = doc or None


def export_loaded(loaded: Loaded, registry: Registry | None = None, kinds: NodeKinds | None = None) -> str:
    """A loaded mission (``botstage.missions.loader.load``'s result) as BT.CPP v4 XML text.

    Raises ``ExportError`` with every problem located in the mission's files."""
    if loaded.data is None or loaded.problems:
        raise ExportError(loaded.problems or [Problem(loaded.locations.root, "no mission to export")])
    return Exporter(loaded, registry, kinds).document()


def export_mission(
    path: str | Path,
    load: Callable[[Path], Loaded],
    registry: Registry | None = None,
    kinds: NodeKinds | None = None,
) -> str:
    """The mission at ``path`` as BT.CPP v4 XML text; ``load`` is ``botstage.missions.loader.load`` (passed
    in: behaviors never imports missions). Raises ``ExportError`` (located problems)."""
    return export_loaded(load(Path(path)), registry, kinds)
