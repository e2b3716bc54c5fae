"""A BehaviorTree.CPP v4 XML file as a botstage mission: the data a mission YAML gives, with the
XML line and column of every node, so checking, running and pictures work on it unchanged.

- ``<BehaviorTree ID>`` become ``trees``; ``main_tree_to_execute`` (or the only tree) is ``root``.
- BT.CPP's built-in nodes become the kinds of the same name (``behaviors.btcpp.nodes``), their
  ports options converted to the port's type.
- A node whose ID is a botstage skill runs that skill: attributes naming its input ports are its
  inputs (literals converted by the port's type, ``{key}`` a blackboard key), those naming its
  output ports bind them to keys.
- ``<SubTree ID>`` is a ``subtree`` with ``remap``. BT.CPP gives every subtree a blackboard of its
  own; botstage has one, so each key a subtree uses that is not one of its ports (nor ``{@key}``,
  the root blackboard's) is remapped to a key private to that SubTree instance
  (``_<n>_<TreeID>/key``). ``_autoremap="true"`` shares them instead, ``port="{=}"`` shares one.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from behaviors.btcpp.xml_reader import Element, parse, parse_bytes
from behaviors.kinds import CompositeKind, DecoratorKind, NodeKinds
from behaviors.suggest import did_you_mean
from robots.located_yaml import Loaded, Location, Locations, Problem, display_name
from skills.base import plain_type
from skills.registry import Registry

SpecPath = tuple[str | int, ...]
NODE_MODELS = ("Action", "Condition", "Control", "Decorator")  # <Action ID="X"/>, BT.CPP v3's long form
# attributes BT.CPP and Groot2 write on any node that are not ports
IGNORED = frozenset({"_uid", "_fullpath", "_description"})
CONDITIONS = frozenset(
    {"_skipIf", "_failureIf", "_successIf", "_while", "_onSuccess", "_onFailure", "_onHalted", "_post"}
)
INT_PORTS = frozenset(
    {"num_attempts", "num_cycles", "msec", "delay_msec", "success_count", "failure_count", "max_failures"}
)
BOOL_PORTS = frozenset({"then_skip"})
KEY_PORTS = frozenset({("SetBlackboard", "output_key")})  # ports whose text is a key's name
_REF = re.compile(r"^\{(@?)([^{}]*)\}$")


def btcpp_kinds(kinds: NodeKinds) -> list[str]:
    """The kinds of BT.CPP's built-in node set (registered from ``behaviors.btcpp.nodes``)."""
    return [name for name in kinds if type(kinds.get(name)).__module__ == "behaviors.btcpp.nodes"]


@dataclass
class _Tree:
    spec: Any = None
    keys: set[tuple[str, bool]] = field(default_factory=set)  # (key, written {@key}) used inside


class Converter:
    """One XML document to mission data; problems are collected with their XML locations."""

    def __init__(self, name: str, registry: Registry | None = None, kinds: NodeKinds | None = None) -> None:
        self.name = name
        self.registry = registry or Registry.default()
        self.kinds = kinds or NodeKinds.default()
        self.btcpp = set(btcpp_kinds(self.kinds))
        self.problems: list[Problem] = []
        self.locations = Locations(root=Location(name, 1, 1))
        self.elements: dict[str, Element] = {}
        self.trees: dict[str, _Tree] = {}
        self.visiting: list[str] = []
        self.modelled: set[str] = set()  # IDs the TreeNodesModel declares
        self.instances = 0

    def problem(self, where: Location, message: str, hint: str = "") -> None:
        self.problems.append(Problem(where, message, hint))

    # -- the document ---------------------------------------------------------------------------

    def document(self, root: Element) -> dict[str, Any] | None:
        if root.tag != "root":
            self.problem(root.where, f"a BehaviorTree.CPP file has <root> at the top, not <{root.tag}>")
            return None
        version = root.attrs.get("BTCPP_format")
        if version is not None and version != "4":
            self.problem(
                root.where,
                f'BTCPP_format="{version}" is not supported: botstage reads version 4',
                "BT.CPP's tool convert_v3_to_v4.py converts version 3 files",
            )
            return None
        for element in root.children:
            if element.tag == "BehaviorTree":
                tree_id = element.attrs.get("ID")
                if not tree_id:
                    self.problem(element.where, "<BehaviorTree> needs an ID")
                elif tree_id in self.elements:
                    self.problem(element.where, f"duplicate BehaviorTree ID {tree_id!r}")
                else:
                    self.elements[tree_id] = element
            elif element.tag == "TreeNodesModel":
                self.modelled |= {m.attrs.get("ID", "") for m in element.children}
            elif element.tag == "include":
                self.problem(element.where, "<include> is not supported yet: put the trees in one file")
            else:
                self.problem(element.where, f"unexpected <{element.tag}> in <root>", "expected BehaviorTree")
        main = root.attrs.get("main_tree_to_execute")
        if main is not None and main not in self.elements:
            self.problem(root.where, f"main_tree_to_execute: no tree {main!r}", did_you_mean(main, self.elements))
            main = None
        elif main is None and len(self.elements) > 1:
            self.problem(
                root.where,
                "several trees and no main_tree_to_execute: say which runs",
                "trees: " + ", ".join(self.elements),
            )
        elif main is None and self.elements:
            main = next(iter(self.elements))
        if not self.elements:
            self.problem(root.where, "no <BehaviorTree> in the file")
        for tree_id in self.elements:
            self.tree(tree_id, self.elements[tree_id].where)
        trees = {tree_id: self.trees[tree_id].spec for tree_id in self.elements if self.trees[tree_id].spec is not None}
        self.locations.by_path[("trees",)] = root.where
        data: dict[str, Any] = {"trees": trees}
        if main is not None:
            data["root"] = main
            self.locations.by_path[("root",)] = root.where
        return data

    def tree(self, tree_id: str, used_at: Location) -> _Tree | None:
        """The converted tree (converted once), or None if it enters itself again."""
        if tree_id in self.visiting:
            chain = " -> ".join([*self.visiting[self.visiting.index(tree_id) :], tree_id])
            self.problem(used_at, f"subtree recursion: {chain}")
            return None
        if tree_id in self.trees:
            return self.trees[tree_id]
        element = self.elements[tree_id]
        self.visiting.append(tree_id)
        tree = _Tree()
        nodes = [c for c in element.children]
        path: SpecPath = ("trees", tree_id)
        self.locations.by_path[path] = element.where
        if len(nodes) != 1:
            self.problem(element.where, f"<BehaviorTree ID={tree_id!r}> holds exactly one node, found {len(nodes)}")
        else:
            tree.spec = self.node(nodes[0], path, tree)
        self.visiting.pop()
        self.trees[tree_id] = tree
        return tree

    # -- nodes ----------------------------------------------------------------------------------

    def node(self, element: Element, path: SpecPath, tree: _Tree) -> dict[str, Any] | None:
        self.locations.by_path[path] = element.where
        node_id = element.tag
        attrs = dict(element.attrs)
        if node_id in NODE_MODELS or (node_id == "SubTree" and "ID" in attrs):
            node_id = attrs.pop("ID", "")
            if not node_id:
                self.problem(element.where, f"<{element.tag}> needs an ID")
                return None
            if element.tag == "SubTree":
                return self.subtree(element, node_id, attrs, path, tree)
        for attr in list(attrs):
            if attr in IGNORED:
                del attrs[attr]
            elif attr in CONDITIONS:
                self.problem(element.where, f"{attr} (BT.CPP's pre/post conditions) is not supported yet")
                return None
        spec: dict[str, Any] = {}
        name = attrs.pop("name", None)
        if name and "/" not in name:
            spec["name"] = name
        if node_id in self.btcpp:
            built = self.builtin(element, node_id, attrs, path, tree)
        elif node_id in self.registry:
            built = self.skill(element, node_id, attrs, path, tree)
        else:
            self.unknown(element, node_id, path, tree)
            return None
        return None if built is None else {**built, **spec}

    def unknown(self, element: Element, node_id: str, path: SpecPath, tree: _Tree) -> None:
        """Report an unknown ID, and go on below it: every unknown node of the file is reported."""
        known = sorted({*self.btcpp, *self.registry, "SubTree"})
        declared = " (the TreeNodesModel declares it, but botstage has no node of that ID)" * (node_id in self.modelled)
        close = difflib.get_close_matches(node_id, known, n=1, cutoff=0.75)
        hint = f"did you mean {close[0]!r}?" if close else "known: `botstage nodes` and `botstage skills`"
        self.problem(element.where, f"unknown node {node_id!r}{declared}", hint)
        for index, child in enumerate(element.children):
            self.node(child, path + (node_id, index), tree)

    def builtin(
        self, element: Element, node_id: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        kind = self.kinds.get(node_id)
        ports: dict[str, Any] = {}
        for port, text in attrs.items():
            value = self.port_value(element, node_id, port, text, tree)
            if value is _BAD:
                return None
            ports[port] = value
            self.locations.by_path[path + (port,)] = element.where
        children = element.children
        if isinstance(kind, CompositeKind):
            if not children:
                self.problem(element.where, f"{node_id} needs children")
                return None
            built = [self.node(c, path + (node_id, i), tree) for i, c in enumerate(children)]
            if any(b is None for b in built):
                return None
            return {node_id: built, **ports}
        if isinstance(kind, DecoratorKind):
            if len(children) != 1:
                self.problem(element.where, f"{node_id} decorates exactly one node, found {len(children)}")
                return None
            child = self.node(children[0], path + (node_id,), tree)
            return None if child is None else {node_id: child, **ports}
        if children:
            self.problem(element.where, f"{node_id} is a leaf: it has no children")
            return None
        for port in ports:
            self.locations.by_path[path + (node_id, port)] = element.where
        return {node_id: ports}

    def port_value(self, element: Element, node_id: str, port: str, text: str, tree: _Tree) -> Any:
        """A built-in node's port: a number or boolean where BT.CPP's port is one, else the text
        (``{key}`` stays a reference, recorded as used)."""
        ref = _REF.match(text.strip())
        if ref is not None:
            if port in INT_PORTS or port in BOOL_PORTS:
                self.problem(element.where, f"{node_id}.{port}: a blackboard reference here is not supported yet")
                return _BAD
            key = port if ref.group(2) == "=" else ref.group(2).strip()
            tree.keys.add((key, bool(ref.group(1))))
            return "{" + key + "}"
        if (node_id, port) in KEY_PORTS:
            tree.keys.add((text.strip(), False))  # a key's name, written without braces
        if port in INT_PORTS:
            try:
                return int(text.strip())
            except ValueError:
                self.problem(element.where, f"{node_id}.{port}: expected a whole number, got {text!r}")
                return _BAD
        if port in BOOL_PORTS:
            value = _bool(text)
            if value is None:
                self.problem(element.where, f"{node_id}.{port}: expected true or false, got {text!r}")
                return _BAD
            return value
        return text

    def skill(
        self, element: Element, skill_name: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        cls = self.registry.get(skill_name)
        if element.children:
            self.problem(element.where, f"{skill_name} is a skill: it has no children")
            return None
        inputs: dict[str, Any] = {}
        outputs: dict[str, str] = {}
        ok = True
        for port, text in attrs.items():
            ref = _REF.match(text.strip())
            key = None
            if ref is not None:
                key = port if ref.group(2) == "=" else ref.group(2).strip()
                tree.keys.add((key, bool(ref.group(1))))
            if port in cls.outputs:
                if key is None:
                    self.problem(element.where, f"output {port!r} of {skill_name!r} binds to a key: write {{key}}")
                    ok = False
                else:
                    outputs[port] = key
                    self.locations.by_path[path + ("outputs", port)] = element.where
            elif port in cls.inputs:
                if key is not None:
                    inputs[port] = "{" + key + "}"
                else:
                    value = convert(cls.inputs[port].type, text)
                    if value is _BAD:
                        wanted = _type_name(cls.inputs[port].type)
                        self.problem(
                            element.where, f"input {port!r} of {skill_name!r}: cannot read {text!r} as {wanted}"
                        )
                        ok = False
                        continue
                    inputs[port] = value
                    if cls.inputs[port].names_key and isinstance(value, str):
                        tree.keys.add((value, False))
                self.locations.by_path[path + (skill_name, port)] = element.where
            else:
                known = [*cls.inputs, *cls.outputs]
                self.problem(element.where, f"skill {skill_name!r} has no port {port!r}", did_you_mean(port, known))
                ok = False
        if not ok:
            return None
        self.locations.by_path[path + (skill_name,)] = element.where
        spec: dict[str, Any] = {skill_name: inputs}
        if outputs:
            spec["outputs"] = outputs
        return spec

    def subtree(
        self, element: Element, tree_id: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        if element.children:
            self.problem(element.where, "<SubTree> has no children")
            return None
        if tree_id not in self.elements:
            self.problem(
                element.where, f"no BehaviorTree {tree_id!r} for this SubTree", did_you_mean(tree_id, self.elements)
            )
            return None
        inner = self.tree(tree_id, element.where)
        if inner is None:
            return None
        autoremap = _bool(attrs.pop("_autoremap", "false"))
        name = attrs.pop("name", None)
        for attr in list(attrs):
            if attr in IGNORED:
                del attrs[attr]
        remap: dict[str, str] = {}
        for port, text in attrs.items():
            ref = _REF.match(text.strip())
            if ref is None:
                self.problem(
                    element.where,
                    f"SubTree port {port}={text!r}: a literal value for a subtree port is not supported yet",
                    "set it with SetBlackboard before the SubTree",
                )
                return None
            outer = port if ref.group(2) == "=" else ref.group(2).strip()
            tree.keys.add((outer, bool(ref.group(1))))
            remap[port] = outer
        roots = {key for key, root in inner.keys if root}
        for key, root in sorted(inner.keys):
            if root or key in remap:
                continue
            if key in roots:
                self.problem(
                    element.where, f"{tree_id!r} uses both {{{key}}} and {{@{key}}}: botstage cannot keep them apart"
                )
                return None
            if autoremap:
                tree.keys.add((key, False))
            else:
                remap[key] = f"_{self.instances}_{_identifier(tree_id)}/{key}"
        tree.keys |= {(key, True) for key in roots}
        self.instances += 1
        spec: dict[str, Any] = {"subtree": tree_id}
        if remap:
            spec["remap"] = remap
        if name and "/" not in name:
            spec["name"] = name
        self.locations.by_path[path + ("subtree",)] = element.where
        return spec


class _Bad:
    """A value that could not be converted (its problem is reported)."""


_BAD: Any = _Bad()


def _bool(text: str | None) -> bool | None:
    """BT.CPP's convertFromString<bool>."""
    lowered = (text or "").strip().lower()
    return {"true": True, "1": True, "false": False, "0": False}.get(lowered)


def _identifier(text: str) -> str:
    cleaned = re.sub(r"\W", "_", text)
    return cleaned if cleaned[:1].isalpha() else "t" + cleaned


def _type_name(tp: Any) -> str:
    tp = plain_type(tp)
    return getattr(tp, "__name__", str(tp))


def convert(tp: Any, text: str) -> Any:
    """An attribute's text as a value of the port's type, as BT.CPP's convertFromString reads it:
    numbers, ``true``/``false``, and lists of numbers separated by ``;``. Anything else stays text."""
    plain = plain_type(tp)
    text = text.strip() if plain is not str else text
    try:
        if plain is bool:
            value = _bool(text)
            return _BAD if value is None else value
        if plain is int:
            return int(text)
        if plain is float:
            return float(text)
        origin = getattr(plain, "__origin__", None)
        args = getattr(plain, "__args__", ())
        if origin in (list, tuple) and args and all(plain_type(a) in (int, float) for a in args if a is not Ellipsis):
            numbers = [float(part) for part in text.split(";") if part.strip()]
            return numbers if origin is list else tuple(numbers)
    except ValueError:
        return _BAD
    return text


def load_xml(path: str | Path, registry: Registry | None = None, kinds: NodeKinds | None = None) -> Loaded:
    """A BT.CPP XML file as a loaded mission (data, locations, problems); never raises for bad input."""
    path = Path(path)
    name = display_name(path)
    problems: list[Problem] = []
    root = parse(path, problems)
    return _loaded(root, path, name, problems, registry, kinds)


def loads_xml(
    text: str, name: str = "<xml>", registry: Registry | None = None, kinds: NodeKinds | None = None
) -> Loaded:
    """XML text as a loaded mission (for tests and tools)."""
    problems: list[Problem] = []
    root = parse_bytes(text.encode(), name, problems)
    return _loaded(root, Path(name), name, problems, registry, kinds)


def _loaded(
    root: Element | None,
    path: Path,
    name: str,
    problems: list[Problem],
    registry: Registry | None,
    kinds: NodeKinds | None,
) -> Loaded:
    converter = Converter(name, registry, kinds)
    data = None
    if root is not None:
        data = converter.document(root)
    problems.extend(converter.problems)
    if data is not None:
        data = {"name": path.stem, **data}
    return Loaded(None if problems else data, converter.locations, problems, [path])
