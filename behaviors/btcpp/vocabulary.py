"""What BehaviorTree.CPP XML import and export share: the node set's scope, the names botstage
writes beyond BT.CPP's own nodes, and how a value is written as attribute text and read back
(BT.CPP's ``convertFromString``). Both directions import it; neither imports the other's reader."""

from __future__ import annotations

import json
from typing import Any, get_args, get_origin

from botstage.skills.base import plain_type

SCOPE = "btcpp"  # the node scope an XML file's trees are written in (BT.CPP's set, Nav2's set)
OWN_SET = "btcpp"  # the node set of BT.CPP's own nodes: the ones an XML file need not declare
NODE_MODELS = ("Action", "Condition", "Control", "Decorator")  # <Action ID="X"/>, BT.CPP v3's long form
# attributes BT.CPP and Groot2 write on any node that are not ports
IGNORED = frozenset({"_uid", "_fullpath", "_description"})
RENAMED = {("Precondition", "if"): "if_"}  # `if` is botstage's guard kind: a node names exactly one kind
MARKER = "_botstage"  # on a BT.CPP built-in's tag: the botstage kind it was written from
SETTINGS = "BotstageMission"  # the mission's settings besides its trees and machines
TOP_MACHINE_TREE = "mission"  # the BehaviorTree that holds an inline top-level machine
MACHINE_PREFIX = "machine:"  # BehaviorTree IDs of named machines
STATE_MACHINE, STATE = "StateMachine", "State"
SKILL_EXTRAS = ("success_on", "params")  # a skill node's options that are not ports: `_success_on`
# what is not a setting (`nodes`: an XML file's trees are always in BT.CPP's scope)
TREE_KEYS = ("trees", "machines", "machine", "root", "include", "nodes")
# the port a botstage decorator's argument is written to (plug-ins: "value")
ARGUMENT_PORTS = {"retry": "times", "repeat": "times", "timeout": "seconds", "delay": "seconds"}
ARGUMENT_PORTS |= {"while": "condition", "if": "condition"}
# botstage composites with BT.CPP's behaviour: (kind, memory) -> BT.CPP ID
COMPOSITES = {"sequence": "Sequence", "selector": "Fallback", "fallback": "Fallback"}
COMPOSITES |= {"reactive_sequence": "ReactiveSequence", "reactive_selector": "ReactiveFallback"}
COMPOSITES |= {"reactive_fallback": "ReactiveFallback"}
# botstage decorators that build BT.CPP's behaviour: kind -> (BT.CPP ID, its count port or None)
DECORATORS = {
    "inverter": ("Inverter", None),
    "force_success": ("ForceSuccess", None),
    "force_failure": ("ForceFailure", None),
    "keep_running_until_failure": ("KeepRunningUntilFailure", None),
    "retry": ("RetryUntilSuccessful", "num_attempts"),
    "repeat": ("Repeat", "num_cycles"),
    "timeout": ("Timeout", "msec"),
    "delay": ("Delay", "delay_msec"),
}
MILLISECOND_PORTS = frozenset({"msec", "delay_msec"})


class _Bad:
    """A value that could not be converted (its problem is reported)."""


_BAD: Any = _Bad()


def _bool(text: str | None) -> bool | None:
    """BT.CPP's convertFromString<bool>."""
    lowered = (text or "").strip().lower()
    return {"true": True, "1": True, "false": False, "0": False}.get(lowered)


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


def to_text(value: Any) -> str:
    """A value as a port's text: strings as they are, booleans as BT.CPP writes them, else JSON."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    return json.dumps(value, ensure_ascii=False)


def typed_text(value: Any, annotation: Any) -> str:
    """An option's text that ``from_text`` reads back to the same value for this annotation."""
    if plain_type(annotation) is str or not isinstance(value, str):
        return to_text(value)
    return value if from_text(value, annotation) == value else json.dumps(value, ensure_ascii=False)


def from_text(text: str, annotation: Any = Any) -> Any:
    """A port's text as the option's value: text for ``str``, else JSON where it parses (a plain
    word like ``forever`` stays text)."""
    if plain_type(annotation) is str:
        return text
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return json.loads(text)
    except ValueError:
        return text


def input_value(annotation: Any, text: str, exported: bool) -> Any:
    """A skill input's text as its value: BT.CPP's reading (``to_spec.convert``), lists of words
    split at ``;`` as BT.CPP splits a ``vector<string>``, and, in a file botstage wrote
    (``exported``), JSON for an input of any type."""
    if reads_beyond_btcpp(annotation, exported):
        if plain_type(annotation) is Any:
            return from_text(text)
        return [part for part in text.split(";") if part]
    return convert(annotation, text)


def reads_beyond_btcpp(annotation: Any, exported: bool) -> bool:
    """Is an input of this type read by ``input_value``'s own rules (not ``to_spec.convert``'s)?"""
    plain = plain_type(annotation)
    words = get_origin(plain) is list and [plain_type(a) for a in get_args(plain)] == [str]
    return words or (plain is Any and exported)


def split_outside_quotes(text: str, separator: str) -> list[str]:
    """``text`` cut at each ``separator`` that is not inside '…' or "…" (conditions hold strings)."""
    parts, start, quote, i = [], 0, "", 0
    while i < len(text):
        char = text[i]
        if quote:
            if char == "\\":
                i += 1
            elif char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif text.startswith(separator, i):
            parts.append(text[start:i])
            start = i + len(separator)
            i = start
            continue
        i += 1
    parts.append(text[start:])
    return parts
