"""A TreeNodesModel (Nav2's nav2_tree_nodes.xml, as Groot2 loads it) against botstage's node set.

Importing the model file itself gives no trees (``botstage.behaviors.btcpp.to_spec``); this says, for each
node it declares, whether botstage has a node of that ID (a skill or a kind) and whether their
ports agree: every declared port exists on botstage's node, in the same direction, with the same
default. That is the contract of the Nav2 node set: Nav2's XML written against the model runs here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from botstage.behaviors.btcpp.vocabulary import SCOPE
from botstage.behaviors.btcpp.xml_reader import Element, parse
from botstage.behaviors.kinds import NodeKinds
from botstage.robots.located_yaml import Location, Problem
from botstage.skills.base import MISSING
from botstage.skills.registry import Registry

DIRECTIONS = {"input_port": "input", "output_port": "output", "inout_port": "inout", "bidirectional_port": "inout"}


@dataclass
class ModelCheck:
    """What a TreeNodesModel declares that botstage has, lacks, or has differently."""

    implemented: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    problems: list[Problem] = field(default_factory=list)


def _same_default(text: str, ours: Any) -> bool:
    """A model's default text (``1.57``, ``"&quot;&quot;"``, ``false``) and botstage's default value."""
    text = text.strip().strip('"')
    if ours is None or ours is MISSING:
        return text == ""  # botstage leaves the port unset: Nav2's empty string
    if isinstance(ours, bool):
        return text.lower() == str(ours).lower()
    if isinstance(ours, int | float):
        if "infinity" in text:
            return math.isinf(ours)
        try:
            return math.isclose(float(text), float(ours))
        except ValueError:
            return False
    return text == str(ours)


def _skill_ports(cls: Any) -> dict[str, tuple[str, Any]]:
    ports = {name: ("input", port.default) for name, port in cls.inputs.items()}
    ports |= {name: ("output", None) for name in cls.outputs}
    return ports


def _kind_ports(kind: Any) -> dict[str, tuple[str, Any]]:
    fields = kind.Options.model_fields
    ports = {name: ("input", info.default if info.default is not None else None) for name, info in fields.items()}
    for name in getattr(kind, "ports", ()):
        ports.setdefault(name, ("input", None))
    for name, default in getattr(kind, "port_defaults", {}).items():
        ports[name] = ("input", default)
    for name in getattr(kind, "output_ports", ()):
        ports[name] = ("output", None)
    return {name: value for name, value in ports.items() if name not in ("name", "child")}


def check_models(path: Path, registry: Registry | None = None, kinds: NodeKinds | None = None) -> ModelCheck:
    """Compare every node the file's TreeNodesModel declares with botstage's node of that ID."""
    registry = registry or Registry.default()
    kinds = kinds or NodeKinds.default(SCOPE)
    result = ModelCheck()
    root = parse(path, result.problems)
    models: list[Element] = [
        m for e in (root.children if root else []) if e.tag == "TreeNodesModel" for m in e.children
    ]
    for model in models:
        node_id = model.attrs.get("ID", "")
        if node_id in registry:
            ours = _skill_ports(registry.get(node_id))
        elif node_id in kinds:
            ours = _kind_ports(kinds.get(node_id))
        else:
            result.missing.append(node_id)
            continue
        result.implemented.append(node_id)
        for port in model.children:
            name, direction = port.attrs.get("name", ""), DIRECTIONS.get(port.tag)
            where: Location = port.where
            if direction is None:
                continue
            if name not in ours:
                result.problems.append(Problem(where, f"{node_id}: botstage's node has no port {name!r}"))
                continue
            have, default = ours[name]
            if have != direction and direction != "inout":
                result.problems.append(Problem(where, f"{node_id}.{name}: declared {direction}, botstage's is {have}"))
            elif "default" in port.attrs and have == "input" and not _same_default(port.attrs["default"], default):
                result.problems.append(
                    Problem(where, f"{node_id}.{name}: default {port.attrs['default']!r}, botstage's is {default!r}")
                )
    return result
