"""A BehaviorTree.CPP v4 XML file as a botstage mission: the data a mission YAML gives, with the
XML line and column of every node, so checking, running and pictures work on it unchanged.

- ``<BehaviorTree ID>`` become ``trees``; ``main_tree_to_execute`` (or the only tree) is ``root``.
- BT.CPP's built-in nodes become the kinds of the same name (``botstage.behaviors.btcpp.nodes``), their
  ports options converted to the port's type.
- A node whose ID is a botstage skill runs that skill: attributes naming its input ports are its
  inputs (literals converted by the port's type, ``{key}`` a blackboard key), those naming its
  output ports bind them to keys.
- ``<SubTree ID>`` is a ``subtree`` with ``remap``. BT.CPP gives every subtree a blackboard of its
  own; botstage has one, so each key a subtree uses that is not one of its ports (nor ``{@key}``,
  the root blackboard's) is remapped to a key private to that SubTree instance
  (``_<n>_<TreeID>/key``). ``_autoremap="true"`` shares them instead, ``port="{=}"`` shares one.
  A literal for a SubTree port is that private key's initial value (``blackboard``), as BT.CPP
  sets it into the subtree's blackboard when the tree is created.
- Scripts (``Script``, ``ScriptCondition``, ``Precondition``'s ``if`` and the pre/post-condition
  attributes ``_skipIf`` ... ``_post``) are parsed here, so a syntax error is located at its
  attribute's line and column; their names are keys like ``{key}``. The attributes of a node
  become a ``PrePostConditions`` decorator around it.
- ``<include path>`` reads another file's trees (relative to the including file);
  ``<TreeNodesModel>`` port types and defaults apply to the nodes it declares.
"""

from __future__ import annotations

import difflib
import re
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, get_args, get_origin

from botstage.behaviors.btcpp.script import ScriptError, compile_script
from botstage.behaviors.btcpp.vocabulary import _BAD, IGNORED, NODE_MODELS, RENAMED, SCOPE, _bool, convert
from botstage.behaviors.btcpp.xml_reader import Element, parse
from botstage.behaviors.kinds import CompositeKind, DecoratorKind, NodeKinds
from botstage.robots import limits
from botstage.robots.located_yaml import Location, Locations, Problem, display_name
from botstage.robots.suggest import did_you_mean
from botstage.skills.base import plain_type
from botstage.skills.registry import Registry

SpecPath = tuple[str | int, ...]
CONDITIONS = ("_skipIf", "_failureIf", "_successIf", "_while", "_onSuccess", "_onFailure", "_onHalted", "_post")
WRAPPER = "PrePostConditions"  # the kind that carries a node's CONDITIONS (botstage.behaviors.btcpp.nodes)
KEY_PORTS = frozenset({("SetBlackboard", "output_key"), ("UnsetBlackboard", "key")})  # text is a key's name
SCRIPT_PORTS = frozenset({("Script", "code"), ("ScriptCondition", "code"), ("Precondition", "if")})
# TreeNodesModel port types (C++ type names) and the Python type their literals are read as
MODEL_TYPES: dict[str, Any] = {
    **dict.fromkeys(["int", "unsigned", "unsigned int", "long", "int8_t", "int16_t", "int32_t", "int64_t"], int),
    **dict.fromkeys(["uint8_t", "uint16_t", "uint32_t", "uint64_t", "size_t", "std::chrono::milliseconds"], int),
    **dict.fromkeys(["double", "float"], float),
    "bool": bool,
}
_REF = re.compile(r"^\{(@?)([^{}]*)\}$")


@dataclass
class _Tree:
    spec: Any = None
    keys: set[tuple[str, bool]] = field(default_factory=set)  # (key, written {@key}) used inside
    types: dict[str, Any] = field(default_factory=dict)  # key -> the type of a typed port bound to it


@dataclass
class _Port:
    """A port a TreeNodesModel declares: the type its literals are read as, its default's text."""

    type: Any = str
    default: str | None = None


class Converter:
    """One XML document to mission data; problems are collected with their XML locations."""

    def __init__(self, name: str, registry: Registry | None = None, kinds: NodeKinds | None = None) -> None:
        self.name = name
        self.registry = registry or Registry.default()
        self.kinds = kinds or NodeKinds.default(SCOPE)
        # the scope's node sets (BT.CPP's, Nav2's) and plug-in kinds: their ports are attributes as they are
        self.native = {name for name in self.kinds if self.kinds.origin(name) != "builtin"}
        self.problems: list[Problem] = []
        self.locations = Locations(root=Location(name, 1, 1))
        self.elements: dict[str, Element] = {}
        self.trees: dict[str, _Tree] = {}
        self.visiting: list[str] = []
        self.modelled: set[str] = set()  # IDs the TreeNodesModel declares
        self.models: dict[str, dict[str, _Port]] = {}  # ID -> its declared input ports
        self.instances = 0
        self.initial: dict[str, Any] = {}  # blackboard values: literals given to SubTree ports
        self.files: list[Path] = []  # files read through <include>

    def problem(self, where: Location, message: str, hint: str = "") -> None:
        self.problems.append(Problem(where, message, hint))

    # -- the document ---------------------------------------------------------------------------

    def document(self, root: Element, path: Path | None = None) -> dict[str, Any] | None:
        if not self.gather(root, path, ()):
            return None
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
        # a file of only a TreeNodesModel (a node set's model file) is a library of node models,
        # not a tree: it imports with no trees
        if not self.elements and not self.modelled:
            self.problem(root.where, "no <BehaviorTree> in the file")
        for tree_id in self.elements:
            self.tree(tree_id, self.elements[tree_id].where)
        trees = {tree_id: self.trees[tree_id].spec for tree_id in self.elements if self.trees[tree_id].spec is not None}
        self.locations.by_path[("trees",)] = root.where
        data: dict[str, Any] = {"trees": trees}
        if self.initial:
            data["blackboard"] = dict(self.initial)
            self.locations.by_path[("blackboard",)] = root.where
        if main is not None:
            data["root"] = main
            self.locations.by_path[("root",)] = root.where
        return data

    def gather(self, root: Element, path: Path | None, stack: tuple[Path, ...]) -> bool:
        """The trees, models and includes of one file (the main one or an included one)."""
        if root.tag != "root":
            self.problem(root.where, f"a BehaviorTree.CPP file has <root> at the top, not <{root.tag}>")
            return False
        version = root.attrs.get("BTCPP_format")
        if version is not None and version != "4":
            self.problem(
                root.where,
                f'BTCPP_format="{version}" is not supported: botstage reads version 4',
                "BT.CPP's tool convert_v3_to_v4.py converts version 3 files",
            )
            return False
        if path is not None:
            stack = (*stack, path.resolve())
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
                self.model(element)
            elif element.tag == "include":
                self.include(element, path, stack)
            else:
                self.problem(element.where, f"unexpected <{element.tag}> in <root>", "expected BehaviorTree")
        return True

    def include(self, element: Element, path: Path | None, stack: tuple[Path, ...]) -> None:
        """BT.CPP's ``<include path="...">``: another file's trees, the path relative to this file."""
        if "ros_pkg" in element.attrs:
            self.problem(
                element.where,
                "<include ros_pkg=...> looks in a ROS package, which botstage cannot",
                "give a path relative to this file",
            )
            return
        relative = element.attrs.get("path", "").strip()
        if not relative:
            self.problem(element.where, '<include> needs a path="..." (relative to this file)')
            return
        target = ((path.parent if path is not None else Path()) / relative).resolve()
        if target in stack:
            chain = " -> ".join(display_name(p) for p in (*stack[stack.index(target) :], target))
            self.problem(element.where, f"include cycle: {chain}")
            return
        if not target.is_file():
            self.problem(element.where, f"included file {relative!r} not found (looked for {display_name(target)})")
            return
        if target in self.files:
            return  # included again along another path: its trees are here already
        if len(self.files) >= limits.MAX_INCLUDED_FILES:
            self.problem(element.where, f"more than {limits.MAX_INCLUDED_FILES} included files")
            return
        self.files.append(target)
        problems: list[Problem] = []
        root = parse(target, problems)
        self.problems.extend(problems)
        if root is not None:
            self.gather(root, target, stack)

    def model(self, element: Element) -> None:
        """A TreeNodesModel: the IDs it declares, and their input ports' types and defaults."""
        for node in element.children:
            node_id = node.attrs.get("ID", "")
            self.modelled.add(node_id)
            ports = self.models.setdefault(node_id, {})
            for port in node.children:
                name = port.attrs.get("name")
                if port.tag in ("input_port", "inout_port") and name:
                    tp = MODEL_TYPES.get(port.attrs.get("type", "").strip(), str)
                    ports[name] = _Port(tp, port.attrs.get("default"))

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
        conditions: dict[str, str] = {}
        for attr in list(attrs):
            if attr in IGNORED:
                del attrs[attr]
            elif attr in CONDITIONS:
                conditions[attr] = attrs.pop(attr)
        if conditions:
            ok = all([self.script(element, attr, code, tree) for attr, code in conditions.items()])
            inner = self.plain_node(element, node_id, attrs, path + (WRAPPER,), tree)
            if inner is None or not ok:
                return None
            for attr in conditions:
                self.locations.by_path[path + (attr,)] = element.value_at(attr)
            return {WRAPPER: inner, **{attr: conditions[attr] for attr in CONDITIONS if attr in conditions}}
        return self.plain_node(element, node_id, attrs, path, tree)

    def plain_node(
        self, element: Element, node_id: str, attrs: dict[str, str], path: SpecPath, tree: _Tree
    ) -> dict[str, Any] | None:
        """A node without its pre/post-condition attributes."""
        self.locations.by_path[path] = element.where
        if element.tag == "SubTree" and "ID" in element.attrs:
            return self.subtree(element, node_id, attrs, path, tree)
        for port, declared in self.models.get(node_id, {}).items():
            if port not in attrs and declared.default is not None:
                attrs[port] = declared.default  # BT.CPP: a port left out takes the model's default
        spec: dict[str, Any] = {}
        name = attrs.pop("name", None)
        if name and "/" not in name:
            spec["name"] = name
        if node_id in self.native:
            built = self.builtin(element, node_id, attrs, path, tree)
        elif node_id in self.registry:
            built = self.skill(element, node_id, attrs, path, tree)
        else:
            self.unknown(element, node_id, path, tree)
            return None
        return None if built is None else {**built, **spec}

    def script(self, element: Element, attr: str, code: str, tree: _Tree) -> bool:
        """Parse a script written in ``attr`` (a syntax error located at its column) and record
        its keys as used; False if it does not parse."""
        try:
            script = compile_script(code)
        except ScriptError as exc:
            self.problem(element.value_at(attr, exc.column - 1), f"{attr}: {exc.message}", f"in {code!r}")
            return False
        for name in script.keys:
            tree.keys.add((name.removeprefix("@"), name.startswith("@")))
        return True

    def unknown(self, element: Element, node_id: str, path: SpecPath, tree: _Tree) -> None:
        """Report an unknown ID, and go on below it: every unknown node of the file is reported."""
        known = sorted({*self.native, *self.registry, "SubTree"})
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
            value = self.port_value(element, node_id, kind, port, text, tree)
            if value is _BAD:
                return None
            written = RENAMED.get((node_id, port), port)
            ports[written] = value
            self.locations.by_path[path + (written,)] = element.value_at(port)
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
        for port in attrs:
            self.locations.by_path[path + (node_id, RENAMED.get((node_id, port), port))] = element.value_at(port)
        return {node_id: ports}

    def port_type(self, node_id: str, kind: Any, port: str) -> tuple[Any, bool]:
        """The type a port's literal is read as, and whether ``{key}`` may be written there.

        The kind's own declaration comes first (a leaf's ``port_types``, else its Options field of
        that name or alias), then the TreeNodesModel's, else text: plug-in node sets (Nav2's) are
        read the same way as BT.CPP's own."""
        declared: Any = getattr(kind, "port_types", {}).get(port)
        if declared is None:
            for name, info in kind.Options.model_fields.items():
                if port in (name, info.alias):
                    # pydantic keeps an Annotated field's metadata beside its annotation
                    declared = Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
                    break
        if declared is None or declared is Any:
            model = self.models.get(node_id, {}).get(port)
            return (model.type if model is not None else str), True
        return literal_type(declared), takes_text(declared)

    def port_value(self, element: Element, node_id: str, kind: Any, port: str, text: str, tree: _Tree) -> Any:
        """A built-in node's port: a literal read as the port's type, or ``{key}`` (recorded as
        used) where the port takes one."""
        literal, keyed = self.port_type(node_id, kind, port)
        ref = _REF.match(text.strip())
        if ref is not None:
            if not keyed:
                self.problem(
                    element.value_at(port),
                    f"{node_id}.{port}: BT.CPP's {node_id} takes no blackboard reference here",
                    f"write a {_type_name(literal)}",
                )
                return _BAD
            key = port if ref.group(2) == "=" else ref.group(2).strip()
            tree.keys.add((key, bool(ref.group(1))))
            if literal is not str:
                tree.types.setdefault(key, literal)
            return "{" + key + "}"
        if (node_id, port) in KEY_PORTS:
            tree.keys.add((text.strip(), False))  # a key's name, written without braces
        if (node_id, port) in SCRIPT_PORTS:
            return text if self.script(element, port, text, tree) else _BAD
        value = convert(literal, text)
        if value is _BAD:
            wanted = {int: "a whole number", float: "a number", bool: "true or false"}.get(literal, _type_name(literal))
            self.problem(element.value_at(port), f"{node_id}.{port}: expected {wanted}, got {text!r}")
        return value

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
                    tree.types.setdefault(key, cls.inputs[port].type)
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
        literals: dict[str, Any] = {}
        for port, text in attrs.items():
            ref = _REF.match(text.strip())
            if ref is None:
                # BT.CPP sets a literal into the subtree's own blackboard when the tree is created:
                # here, the initial value of the key private to this SubTree instance
                tp = inner.types.get(port, str)
                value = convert(tp, text)
                if value is _BAD:
                    wanted = _type_name(tp)
                    self.problem(element.value_at(port), f"SubTree port {port}: cannot read {text!r} as {wanted}")
                    return None
                literals[port] = value
                continue
            outer = port if ref.group(2) == "=" else ref.group(2).strip()
            tree.keys.add((outer, bool(ref.group(1))))
            remap[port] = outer
        roots = {key for key, root in inner.keys if root}
        for port, value in literals.items():
            remap[port] = f"_{self.instances}_{_identifier(tree_id)}/{port}"
            self.initial[remap[port]] = value
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


def _metadata(tp: Any) -> tuple[Any, ...]:
    return tuple(get_args(tp)[1:]) if get_origin(tp) is Annotated else ()


def _members(tp: Any) -> tuple[Any, ...]:
    """The types of a union (``int | str``, ``Optional[float]``), without None; else the type."""
    tp = plain_type(tp)
    if get_origin(tp) in (typing.Union, types.UnionType):
        return tuple(plain_type(a) for a in get_args(tp) if a is not type(None))
    return (tp,)


def literal_type(tp: Any) -> Any:
    """How an attribute's text for a port of type ``tp`` is read: a ``literal_type`` the port's
    annotation names (``botstage.behaviors.btcpp.nodes.LiteralType``), else the type; a union with
    ``str`` or ``Literal[...]`` is text, a union of numbers a float."""
    for meta in _metadata(tp):
        if hasattr(meta, "literal_type"):
            return meta.literal_type
    members = _members(tp)
    if len(members) == 1:
        member = members[0]
        return str if member is Any or get_origin(member) is Literal else member
    if str in members or Any in members:
        return str
    return float if all(m in (int, float) for m in members) else str


def takes_text(tp: Any) -> bool:
    """Does a port of this type take text, hence a ``{key}`` (whose value is read when it runs)?"""
    if any(hasattr(meta, "literal_type") for meta in _metadata(tp)):
        return True
    return any(m is str or m is Any or get_origin(m) is Literal for m in _members(tp))


def _identifier(text: str) -> str:
    cleaned = re.sub(r"\W", "_", text)
    return cleaned if cleaned[:1].isalpha() else "t" + cleaned


def _type_name(tp: Any) -> str:
    tp = plain_type(tp)
    return getattr(tp, "__name__", str(tp))
