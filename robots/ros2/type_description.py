"""REP 2016 type descriptions and their RIHS01 hashes, for messages, services and actions.

ROS 2 names every type on the wire by a hash of its *type description*: the type's fields and,
sorted by name, those of every type it refers to. rosidl builds it from the IDL it generates out
of ``.msg``, ``.srv`` and ``.action`` files; rmw_zenoh puts the hash in every key expression and
liveliness token, so a peer that hashes differently never meets botstage.

rosbags hashes messages only, and hashes a ``.msg`` ``char`` as CHAR where rosidl hashes it as
UINT8 (rosidl_adapter turns ``char`` into IDL ``uint8``): its hash of service_msgs/ServiceEventInfo,
part of every service, differs from ROS 2's. So the description is built here, from the field
definitions rosbags parsed, the way rosidl_generator_type_description lays it out:

- a message: its fields;
- a service ``pkg/srv/S``: ``request_message``, ``response_message`` and ``event_message``,
  nested types ``S_Request``, ``S_Response`` and ``S_Event``;
- an action ``pkg/action/A``: ``goal``, ``result``, ``feedback``, ``send_goal_service``,
  ``get_result_service`` and ``feedback_message``, nested types ``A_Goal``, ``A_Result``,
  ``A_Feedback``, the services ``A_SendGoal`` and ``A_GetResult``, and ``A_FeedbackMessage``.

The hash is ``RIHS01_`` and the SHA-256 of the description as JSON (``json.dumps`` defaults),
without default values.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from hashlib import sha256
from typing import Any

from rosbags.interfaces import Nodetype

# type_description_interfaces/msg/FieldType
FIELD_TYPE_NESTED_TYPE = 1
_SCALAR_TYPE_IDS = {
    "int8": 2,
    "uint8": 3,
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "float128": 12,
    "char": 13,
    "wchar": 14,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "wstring": 18,
    "bounded_string": 21,
    "bounded_wstring": 22,
}
_ARRAY_OFFSET, _BOUNDED_SEQUENCE_OFFSET, _UNBOUNDED_SEQUENCE_OFFSET = 48, 96, 144
# What rosidl_adapter makes of a .msg primitive in the IDL that gets hashed (only char differs).
_MSG_TO_IDL = {"char": "uint8"}
# The member rosidl gives a structure without fields (it is in the CDR too: one byte).
EMPTY_STRUCTURE_FIELD = ("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))

Field = tuple[str, Any]  # (name, rosbags field description)
Lookup = Callable[[str], Sequence[Field]]  # a type's fields by full type name


def nested(type_name: str) -> Any:
    """A rosbags field description of one nested ``type_name``."""
    return (Nodetype.NAME, type_name)


def field_type(description: Any) -> dict[str, Any]:
    """The FieldType of one rosbags field description (``nested_type_name`` for nested types)."""
    offset, capacity = 0, 0
    if description[0] == Nodetype.ARRAY:
        offset, capacity = _ARRAY_OFFSET, description[1][1]
        description = description[1][0]
    elif description[0] == Nodetype.SEQUENCE:
        bound = description[1][1]
        offset, capacity = (_BOUNDED_SEQUENCE_OFFSET, bound) if bound else (_UNBOUNDED_SEQUENCE_OFFSET, 0)
        description = description[1][0]
    kind, detail = description
    string_capacity, nested_name = 0, ""
    if kind == Nodetype.NAME:
        type_id, nested_name = FIELD_TYPE_NESTED_TYPE, detail
    else:
        primitive, bound = detail
        primitive = _MSG_TO_IDL.get(primitive, primitive)
        if primitive in ("string", "wstring") and bound:
            primitive, string_capacity = f"bounded_{primitive}", bound
        if primitive not in _SCALAR_TYPE_IDS:
            raise ValueError(f"field type {primitive!r} has no REP 2016 type id")
        type_id = _SCALAR_TYPE_IDS[primitive]
    return {
        "type_id": type_id + offset,
        "capacity": capacity,
        "string_capacity": string_capacity,
        "nested_type_name": nested_name,
    }


def individual_description(type_name: str, fields: Sequence[Field]) -> dict[str, Any]:
    """One type's IndividualTypeDescription (a type without fields gets rosidl's placeholder)."""
    return {
        "type_name": type_name,
        "fields": [{"name": name, "type": field_type(desc)} for name, desc in (fields or [EMPTY_STRUCTURE_FIELD])],
    }


def describe(type_name: str, lookup: Lookup) -> dict[str, Any]:
    """The TypeDescription of ``type_name``: it and every type it refers to, sorted by name."""
    found: dict[str, dict[str, Any]] = {}
    pending = [type_name]
    while pending:
        name = pending.pop()
        if name in found:
            continue
        found[name] = individual_description(name, lookup(name))
        pending += [f["type"]["nested_type_name"] for f in found[name]["fields"] if f["type"]["nested_type_name"]]
    return {
        "type_description": found[type_name],
        "referenced_type_descriptions": [found[name] for name in sorted(found) if name != type_name],
    }


def rihs01(description: dict[str, Any]) -> str:
    """The RIHS01 hash of a TypeDescription."""
    return f"RIHS01_{sha256(json.dumps(description).encode()).hexdigest()}"


def service_fields(request: str, response: str, event: str) -> list[Field]:
    """The fields rosidl describes a service with."""
    return [
        ("request_message", nested(request)),
        ("response_message", nested(response)),
        ("event_message", nested(event)),
    ]


def action_fields(
    goal: str, result: str, feedback: str, send_goal: str, get_result: str, feedback_message: str
) -> list[Field]:
    """The fields rosidl describes an action with."""
    return [
        ("goal", nested(goal)),
        ("result", nested(result)),
        ("feedback", nested(feedback)),
        ("send_goal_service", nested(send_goal)),
        ("get_result_service", nested(get_result)),
        ("feedback_message", nested(feedback_message)),
    ]
