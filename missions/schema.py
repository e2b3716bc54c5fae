"""The mission file format: pydantic models for the top level, and its JSON Schema.

Trees and machines are validated by the engine's builder (which knows every skill and reports
each problem at its place); here they are plain mappings for validation, but the JSON Schema
describes them fully (every node kind, every registered skill with its inputs), so editors
complete and check mission files as they are typed.
"""

from __future__ import annotations

import re
import unicodedata
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, WithJsonSchema, field_validator

from botstage.behaviors.kinds import NodeKinds
from botstage.behaviors.kinds.base import CONDITION_SCHEMA, MACHINE_REF, NODE_REF, merge_property
from botstage.robots.limits import MAX_NAME_BYTES, MAX_SECONDS
from botstage.robots.sim.scenery import Gathering, VoiceSettings, Walk
from botstage.skills.registry import Registry

SCHEMA_ID = "https://botstage.dev/schema/mission.json"
# every model refuses NaN and infinities: `until: .nan` would end a run at once, `time: .inf` never
_CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False)
_DAYS = f"at most {MAX_SECONDS:,.0f} s (about {MAX_SECONDS / 86400:.0f} days)"


class KeySpec(BaseModel):
    """A declared blackboard key: its type (checked on every write) and an optional default."""

    model_config = _CONFIG
    type: str = Field(description="float, int, bool, str, any, list[float], dict[str, int], float | None, ...")
    default: Any = None
    doc: str = ""


# pydantic resolves "$ref"s it is handed, so fields point at markers replaced after generation
_NODE_MARK = {"$comment": "botstage:node"}
_MACHINE_MARK = {"$comment": "botstage:machine"}
TreesField = Annotated[
    dict[str, Any],
    WithJsonSchema({"type": "object", "additionalProperties": _NODE_MARK, "description": "named trees"}),
]
MachinesField = Annotated[
    dict[str, Any],
    WithJsonSchema({"type": "object", "additionalProperties": _MACHINE_MARK, "description": "named machines"}),
]
MachineField = Annotated[Any, WithJsonSchema(_MACHINE_MARK)]


class Mission(BaseModel):
    """A botstage mission."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, title="botstage mission")

    name: str = Field(
        default="",
        description="names the run folder: letters of any script, digits, '_', '-' and '.' "
        f"(at most {MAX_NAME_BYTES} bytes in UTF-8); defaults to the file name",
    )
    description: str = ""
    nodes: str = Field(
        default="botstage",
        description="the node scope its trees are written in: botstage's kinds, or btcpp (BehaviorTree.CPP's "
        "and Nav2's node IDs, as an XML file sees them; `botstage import` writes it)",
    )
    robot: str | None = Field(default=None, description="a robot profile name or a path to a profile YAML")
    world: str | None = Field(default=None, description="the simulated world: a shipped map's name or a map YAML")
    start: str | list[float] | None = Field(
        default=None, description="where the robot starts: a named place of the map, or [x, y] or [x, y, yaw]"
    )
    people: int = Field(default=0, ge=0, le=500, description="simulated people walking on the map (simulation only)")
    gatherings: list[Gathering] = Field(
        default_factory=list, description="groups the simulated people form on cue (scenario tests, demos)"
    )
    walks: list[Walk] = Field(
        default_factory=list,
        max_length=100,
        description="people who walk a given path (simulation only; e.g. across a face tracker's view)",
    )
    voices: VoiceSettings = Field(
        default_factory=VoiceSettings, description="how the simulated people speak to the robot"
    )
    seed: int = 0
    rate_hz: float = Field(default=10.0, gt=0, le=10_000, description="ticks per second")
    until: float | None = Field(
        default=None, gt=0, le=MAX_SECONDS, description=f"stop after this many seconds of mission time; {_DAYS}"
    )
    include: list[str] | str | None = Field(default=None, description="files with shared trees, machines, keys")
    keys: dict[str, KeySpec | str] = Field(default_factory=dict, description="declared blackboard keys and types")
    blackboard: dict[str, Any] = Field(default_factory=dict, description="initial blackboard values")
    skill_params: dict[str, dict[str, Any]] = Field(
        default_factory=dict, description="parameter overrides per skill name"
    )
    trees: TreesField = Field(default_factory=dict)
    machines: MachinesField = Field(default_factory=dict)
    machine: MachineField = Field(default=None, description="the top-level state machine")
    root: str | None = Field(default=None, description="the tree to run when there is no machine")
    counters: list[str] = Field(default_factory=list, description="blackboard keys reported in summary.json")

    @field_validator("name")
    @classmethod
    def _name(cls, value: str) -> str:
        """The name names the run folder: letters of any script (電池テスト), never a separator,
        a space or a character a file system refuses."""
        if value and not all(_name_char(c) for c in value):
            raise ValueError(
                "a mission name uses letters (of any script), digits, '_', '-' and '.' only (it names the run folder)"
            )
        if len(value.encode("utf-8")) > MAX_NAME_BYTES:
            raise ValueError(f"a mission name has at most {MAX_NAME_BYTES} bytes in UTF-8 (it names the run folder)")
        return value


def _name_char(char: str) -> bool:
    return char.isalnum() or char in "_-." or unicodedata.category(char).startswith("M")


def key_spec(value: KeySpec | str) -> KeySpec:
    return value if isinstance(value, KeySpec) else KeySpec(type=value)


_TYPE_NAMES: dict[str, Any] = {
    "any": Any,
    "str": str,
    "int": int,
    "float": float,
    "bool": bool,
    "list": list,
    "dict": dict,
    "none": type(None),
    "None": type(None),
}
_TOKEN = re.compile(r"\s*(?:([A-Za-z_]+)|(.))")
_MAX_TYPE_DEPTH = 10  # list[dict[str, list[float]]] is 3


def parse_type(text: str) -> Any:
    """``float``, ``list[float]``, ``dict[str, int]``, ``float | None`` -> a Python type.

    A tiny grammar on purpose: types in mission files are data, never evaluated as code.
    """
    tokens = [(m.group(1), m.group(2)) for m in _TOKEN.finditer(text.strip())]
    depth = deepest = 0
    for _, symbol in tokens:
        depth += (symbol == "[") - (symbol == "]")
        deepest = max(deepest, depth)
    if deepest > _MAX_TYPE_DEPTH:  # parsed recursively: refuse before
        raise ValueError(f"type {text[:40]!r}... is nested more than {_MAX_TYPE_DEPTH} levels deep")
    position = 0

    def peek() -> tuple[str | None, str | None]:
        return tokens[position] if position < len(tokens) else (None, None)

    def take(symbol: str) -> None:
        nonlocal position
        if peek()[1] != symbol:
            raise ValueError(f"expected {symbol!r} in type {text!r}")
        position += 1

    def single() -> Any:
        nonlocal position
        name, symbol = peek()
        if name is None and symbol is None:
            raise ValueError(f"type {text!r} ends too early")
        if name is None or name not in _TYPE_NAMES:
            known = ", ".join(k for k in _TYPE_NAMES if k != "None")
            raise ValueError(f"unknown type {name or symbol!r} in {text!r} (known: {known})")
        position += 1
        base = _TYPE_NAMES[name]
        if peek()[1] != "[":
            return base
        take("[")
        args = [union()]
        while peek()[1] == ",":
            take(",")
            args.append(union())
        take("]")
        if base is list and len(args) == 1:
            return list[args[0]]
        if base is dict and len(args) == 2:
            return dict[args[0], args[1]]
        raise ValueError(f"{name}[...] takes {'one type' if base is list else 'two types'} in {text!r}")

    def union() -> Any:
        result = single()
        while peek()[1] == "|":
            take("|")
            result = result | single()
        return result

    parsed = union()
    if position != len(tokens):
        raise ValueError(f"unexpected {''.join(t or s or '' for t, s in tokens[position:])!r} in type {text!r}")
    return parsed


# -- JSON Schema --------------------------------------------------------------------------

_JSON_TYPES = {"float": "number", "int": "integer", "bool": "boolean", "str": "string"}


def _port_schema(port_info: dict[str, Any]) -> dict[str, Any]:
    described: dict[str, Any] = {"description": port_info["doc"] or port_info["type"]}
    json_type = _JSON_TYPES.get(port_info["type"])
    if json_type:
        # a port also accepts a blackboard reference "{key}"
        described["anyOf"] = [{"type": json_type}, {"type": "string", "pattern": r"^\{.+\}$"}, {"type": "object"}]
    return described


def _swap_marks(value: Any) -> Any:
    if isinstance(value, dict):
        mark = value.get("$comment")
        if mark in ("botstage:node", "botstage:machine"):
            ref = NODE_REF if mark == "botstage:node" else MACHINE_REF
            return {**{k: v for k, v in value.items() if k not in ("$comment", "default")}, **ref}
        return {k: _swap_marks(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_swap_marks(v) for v in value]
    return value


def node_properties(registry: Registry, kinds: NodeKinds) -> dict[str, Any]:
    """The properties of a node object: every registered kind's, merged where options share a name."""
    properties: dict[str, Any] = {"name": {"type": "string"}}
    for name in kinds:
        for prop, schema in kinds.get(name).schema_properties(registry).items():
            properties[prop] = merge_property(properties[prop], schema) if prop in properties else schema
    return properties


def json_schema(registry: Registry | None = None, kinds: NodeKinds | None = None) -> dict[str, Any]:
    """The schema of mission files for these skills and node kinds (default: all installed)."""
    registry = registry or Registry.default()
    schema = _swap_marks(Mission.model_json_schema())
    schema["$id"] = SCHEMA_ID
    defs = schema.setdefault("$defs", {})
    condition = CONDITION_SCHEMA
    node_props = node_properties(registry, kinds or NodeKinds.default())
    for name in registry:
        info = registry.get(name).describe()
        node_props[name] = {
            "description": info["description"],
            "anyOf": [
                {"type": "null"},
                {
                    "type": "object",
                    "properties": {p: _port_schema(i) for p, i in info["inputs"].items()},
                    "additionalProperties": False,
                },
            ],
        }
    defs["node"] = {"anyOf": [{"type": "string"}, {"type": "object", "properties": node_props}]}
    target = {
        "anyOf": [{"type": "string"}, {"type": "object", "properties": {"to": {"type": "string"}, "if": condition}}]
    }
    action = {"type": "object", "properties": {"set": {"type": "object"}, "log": {"type": "string"}}}
    defs["state"] = {
        "type": "object",
        "properties": {
            "skill": {"enum": list(registry)},
            "inputs": {"type": "object"},
            "outputs": {"type": "object"},
            "params": {"type": "object"},
            "success_on": node_props["success_on"],
            "tree": {"anyOf": [{"type": "string"}, NODE_REF]},
            "machine": {"anyOf": [{"type": "string"}, MACHINE_REF]},
            "transitions": {
                "type": "object",
                "additionalProperties": {"anyOf": [target, {"type": "array", "items": target}]},
            },
            "timeout": {"type": "number", "exclusiveMinimum": 0},
            "on_enter": {"anyOf": [action, {"type": "array", "items": action}]},
            "on_exit": {"anyOf": [action, {"type": "array", "items": action}]},
        },
        "additionalProperties": False,
    }
    defs["machine"] = {
        "type": "object",
        "properties": {
            "name": {"type": "string"},
            "initial": {"type": "string"},
            "outcomes": {"type": "array", "items": {"type": "string"}},
            "success_on": node_props["success_on"],
            "states": {"type": "object", "additionalProperties": {"$ref": "#/$defs/state"}},
            "preemptions": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {"when": condition, "to": {"type": "string"}},
                    "required": ["when", "to"],
                },
            },
        },
        "required": ["states"],
        "additionalProperties": False,
    }
    return schema
