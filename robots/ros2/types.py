"""ROS 2 interface types: Jazzy's standard messages, services and actions and botstage's own.

One rosbags type store holds ROS 2 Jazzy's messages plus every definition shipped under
``robots/ros2/msg/<package>/``: ``msg/*.msg``, ``srv/*.srv`` and ``action/*.action``, registered
when the store is first used. Defining a new service or action is dropping its file there.

A service ``pkg/srv/S`` becomes the messages rosidl generates for it: ``S_Request``,
``S_Response`` and ``S_Event`` (service_msgs/ServiceEventInfo plus at most one request and one
response). An action ``pkg/action/A`` becomes ``A_Goal``, ``A_Result``, ``A_Feedback``, the
services ``A_SendGoal`` (goal id and goal -> accepted and stamp) and ``A_GetResult`` (goal id ->
status and result) and ``A_FeedbackMessage`` (goal id and feedback), as rcl_action uses them.
rosbags has none of Jazzy's services or actions: the standard ones botstage speaks (std_srvs,
action_msgs/CancelGoal, example_interfaces) are shipped as files too.

Everything that goes on the wire about a type comes from here: its DDS name and RIHS01 hash
(both in every key expression and liveliness token; hashes by robots.ros2.type_description) and
its CDR bytes with the 4-byte encapsulation header, as rmw_zenoh sends them. CDR is rosbags'
work, never written by hand.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy
from rosbags.interfaces import Nodetype
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from botstage.robots.ros2 import type_description
from botstage.robots.ros2.type_description import Field, nested

MSG_ROOT = Path(__file__).parent / "msg"

# pkg/msg/Type (also srv and action: the naming rules are the same for every interface kind)
_TYPE_NAME = re.compile(r"^(?P<pkg>[a-z][a-z0-9_]*)/(?P<kind>msg|srv|action)/(?P<name>[A-Z][A-Za-z0-9_]*)$")
_DDS_NAME = re.compile(r"^(?P<pkg>[a-z][a-z0-9_]*)::(?P<kind>msg|srv|action)::dds_::(?P<name>[A-Z][A-Za-z0-9_]*)_$")
# The encapsulation kinds rosbags reads: plain CDR, big endian (00 00) or little endian (00 01).
_PLAIN_CDR = (b"\x00\x00", b"\x00\x01")


class UnknownTypeError(LookupError):
    """A message type that is neither one of Jazzy's standard messages nor one of botstage's."""

    def __str__(self) -> str:  # LookupError's str() would quote the message
        return str(self.args[0])


class CdrError(ValueError):
    """Bytes that are not a CDR message of the expected type."""


class DefinitionError(ValueError):
    """A ``.srv`` or ``.action`` file that is not one."""


SERVICE_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"
UUID = "unique_identifier_msgs/msg/UUID"
TIME = "builtin_interfaces/msg/Time"


@dataclass(frozen=True, slots=True)
class ServiceType:
    """A service type and the message types rosidl generates for it."""

    name: str  # pkg/srv/S (or pkg/action/A_SendGoal for an action's own services)

    @property
    def request(self) -> str:
        return f"{self.name}_Request"

    @property
    def response(self) -> str:
        return f"{self.name}_Response"

    @property
    def event(self) -> str:
        return f"{self.name}_Event"


@dataclass(frozen=True, slots=True)
class ActionType:
    """An action type and the message and service types rosidl generates for it."""

    name: str  # pkg/action/A

    @property
    def goal(self) -> str:
        return f"{self.name}_Goal"

    @property
    def result(self) -> str:
        return f"{self.name}_Result"

    @property
    def feedback(self) -> str:
        return f"{self.name}_Feedback"

    @property
    def send_goal(self) -> ServiceType:
        return ServiceType(f"{self.name}_SendGoal")

    @property
    def get_result(self) -> ServiceType:
        return ServiceType(f"{self.name}_GetResult")

    @property
    def feedback_message(self) -> str:
        return f"{self.name}_FeedbackMessage"


def shipped_definitions(root: Path = MSG_ROOT) -> dict[str, str]:
    """The ``.msg`` files under ``root`` by full type name (``pkg/msg/Name``)."""
    return _files(root, "msg")


def shipped_interfaces(root: Path = MSG_ROOT) -> dict[str, str]:
    """The ``.srv`` and ``.action`` files under ``root`` by full type name (``pkg/srv/Name``, ``pkg/action/Name``)."""
    return {**_files(root, "srv"), **_files(root, "action")}


def _files(root: Path, kind: str) -> dict[str, str]:
    return {
        f"{path.parent.parent.name}/{kind}/{path.stem}": path.read_text(encoding="utf-8")
        for path in sorted(root.glob(f"*/{kind}/*.{kind}"))
    }


def _sections(text: str, count: int, type_name: str) -> list[str]:
    """The ``---``-separated parts of a definition (rosidl: a line that is exactly ``---``)."""
    parts: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.rstrip() == "---":
            parts.append([])
        else:
            parts[-1].append(line)
    if len(parts) != count:
        what = "request --- response" if count == 2 else "goal --- result --- feedback"
        raise DefinitionError(f"{type_name}: {len(parts) - 1} '---' separators, a definition is {what}")
    return ["\n".join(part) for part in parts]


def _part(text: str, type_name: str) -> dict[str, Any]:
    """One part of a definition as the message ``type_name`` (``Foo`` refers to ``<pkg>/msg/Foo``, as in rosidl)."""
    pkg, _, base = type_name.split("/")
    as_message = f"{pkg}/msg/{base}"
    try:
        parsed = get_types_from_msg(text, as_message)
    except Exception as error:  # rosbags' parser raises its own errors
        raise DefinitionError(f"{type_name}: {error}") from error
    return {type_name: parsed[as_message]}


def _service_messages(service: ServiceType, request: dict[str, Any], response: dict[str, Any]) -> dict[str, Any]:
    event_fields: list[Field] = [  # an event carries at most one request and one response
        ("info", nested(SERVICE_EVENT_INFO)),
        ("request", (Nodetype.SEQUENCE, (nested(service.request), 1))),
        ("response", (Nodetype.SEQUENCE, (nested(service.response), 1))),
    ]
    return {**request, **response, service.event: ([], event_fields)}


def service_definition(text: str, type_name: str) -> tuple[dict[str, Any], dict[str, list[Field]]]:
    """The messages a ``.srv`` defines (rosbags typesdict) and the service's description fields."""
    service = ServiceType(type_name)
    request, response = _sections(text, 2, type_name)
    messages = _service_messages(service, _part(request, service.request), _part(response, service.response))
    return messages, {type_name: _service_fields(service)}


def action_definition(text: str, type_name: str) -> tuple[dict[str, Any], dict[str, list[Field]]]:
    """The messages an ``.action`` defines (rosbags typesdict) and the description fields of it and its services."""
    action = ActionType(type_name)
    goal, result, feedback = _sections(text, 3, type_name)
    send_goal, get_result = action.send_goal, action.get_result
    messages = {**_part(goal, action.goal), **_part(result, action.result), **_part(feedback, action.feedback)}
    goal_id: Field = ("goal_id", nested(UUID))
    messages |= _service_messages(
        send_goal,
        {send_goal.request: ([], [goal_id, ("goal", nested(action.goal))])},
        {send_goal.response: ([], [("accepted", (Nodetype.BASE, ("bool", 0))), ("stamp", nested(TIME))])},
    )
    messages |= _service_messages(
        get_result,
        {get_result.request: ([], [goal_id])},
        {get_result.response: ([], [("status", (Nodetype.BASE, ("int8", 0))), ("result", nested(action.result))])},
    )
    messages[action.feedback_message] = ([], [goal_id, ("feedback", nested(action.feedback))])
    fields = type_description.action_fields(
        action.goal, action.result, action.feedback, send_goal.name, get_result.name, action.feedback_message
    )
    composites = {
        type_name: fields,
        send_goal.name: _service_fields(send_goal),
        get_result.name: _service_fields(get_result),
    }
    return messages, composites


def _service_fields(service: ServiceType) -> list[Field]:
    return type_description.service_fields(service.request, service.response, service.event)


@dataclass(frozen=True)
class Interfaces:
    """A type store and the services and actions it knows (their description fields, by name)."""

    store: Any
    composites: dict[str, list[Field]]
    actions: frozenset[str] = frozenset()

    @property
    def services(self) -> frozenset[str]:
        """Every service: those of .srv files and the SendGoal and GetResult services of each action."""
        return frozenset(self.composites) - self.actions

    def fields(self, type_name: str) -> Sequence[Field]:
        """A type's fields as its type description lists them."""
        if type_name in self.composites:
            return self.composites[type_name]
        return self.store.fielddefs[type_name][1]

    def knows(self, type_name: str) -> bool:
        return type_name in self.composites or type_name in self.store.types

    def type_hash(self, type_name: str) -> str:
        return type_description.rihs01(type_description.describe(type_name, self.fields))


def load_interfaces(root: Path = MSG_ROOT) -> Interfaces:
    """ROS 2 Jazzy's type store with every definition under ``root`` registered."""
    store = get_typestore(Stores.ROS2_JAZZY)
    parsed: dict[str, Any] = {}
    composites: dict[str, list[Field]] = {}
    actions: set[str] = set()
    for name, text in shipped_definitions(root).items():
        parsed.update(get_types_from_msg(text, name))
    for name, text in shipped_interfaces(root).items():
        is_service = "/srv/" in name
        messages, described = (service_definition if is_service else action_definition)(text, name)
        clash = (set(messages) | set(described)) & (set(parsed) | set(composites))
        if clash:
            raise DefinitionError(f"{name}: defines {sorted(clash)} again")
        parsed.update(messages)
        composites.update(described)
        actions |= set() if is_service else {name}
    _check_references(parsed, set(store.types) | set(parsed))
    store.register(parsed)
    return Interfaces(store, composites, frozenset(actions))


def _check_references(parsed: dict[str, Any], known: set[str]) -> None:
    """Every type a new definition refers to exists (rosbags parses ``int3 a`` as a message type ``int3``)."""
    for name, (_, fields) in parsed.items():
        for field, desc in fields:
            element = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
            if element[0] == Nodetype.NAME and element[1] not in known:
                raise DefinitionError(f"{name}: field {field!r} has the unknown type {element[1]!r}")


@cache
def _interfaces() -> Interfaces:
    return load_interfaces()


def type_store() -> Any:
    """ROS 2 Jazzy's type store with botstage's definitions registered (built once per process)."""
    return _interfaces().store


def check_type_name(type_name: str) -> str:
    """``type_name`` if it is a full interface name (``pkg/msg/Type``), else a ValueError saying why."""
    if not isinstance(type_name, str) or not _TYPE_NAME.match(type_name):
        raise ValueError(
            f"{type_name!r} is not a ROS 2 interface type name: expected 'package/msg/Type' "
            "(a lower-case package, msg, srv or action, then a CamelCase name), e.g. 'geometry_msgs/msg/Twist'"
        )
    return type_name


def _known(type_name: str, messages_only: bool = True) -> str:
    check_type_name(type_name)
    interfaces = _interfaces()
    known = type_name in interfaces.store.types if messages_only else interfaces.knows(type_name)
    if not known:
        names = list(interfaces.store.types) + ([] if messages_only else list(interfaces.composites))
        near = difflib.get_close_matches(type_name, names, n=3)
        hint = f"; did you mean {', '.join(repr(n) for n in near)}?" if near else ""
        kind = type_name.split("/")[1]
        what = "message" if messages_only else {"msg": "message", "srv": "service", "action": "action"}[kind]
        raise UnknownTypeError(
            f"unknown {what} type {type_name!r}: not one of ROS 2 Jazzy's standard {what}s nor of "
            f"botstage's ({MSG_ROOT.name}/<package>/{kind}/*.{kind}){hint}"
        )
    return type_name


def service_type(type_name: str) -> ServiceType:
    """The service ``type_name`` (``pkg/srv/S``, or an action's ``pkg/action/A_SendGoal``) with its message types."""
    if _known(type_name, messages_only=False) not in _interfaces().services:
        raise UnknownTypeError(f"{type_name!r} is a message or an action, not a service type")
    return ServiceType(type_name)


def action_type(type_name: str) -> ActionType:
    """The action ``type_name`` (``pkg/action/A``) with its message and service types."""
    if _known(type_name, messages_only=False) not in _interfaces().actions:
        raise UnknownTypeError(f"{type_name!r} is a message or a service, not an action type")
    return ActionType(type_name)


def dds_type_name(type_name: str) -> str:
    """The DDS name rmw_zenoh puts in keys and tokens: ``pkg/msg/T`` -> ``pkg::msg::dds_::T_``."""
    match = _TYPE_NAME.match(check_type_name(type_name))
    assert match is not None
    return f"{match['pkg']}::{match['kind']}::dds_::{match['name']}_"


def ros_type_name(dds_name: str) -> str:
    """The ROS name of a DDS type name (``pkg::msg::dds_::T_`` -> ``pkg/msg/T``), as ROS 2 tools show it."""
    match = _DDS_NAME.match(dds_name)
    if match is None:
        raise ValueError(f"{dds_name!r} is not a DDS type name of the form 'package::msg::dds_::Type_'")
    return f"{match['pkg']}/{match['kind']}/{match['name']}"


def is_known(type_name: str) -> bool:
    """Whether ``type_name`` is a known message, service or action (a standard one or botstage's)."""
    return isinstance(type_name, str) and _interfaces().knows(type_name)


def message_class(type_name: str) -> Any:
    """The class whose instances are messages of ``type_name`` (what ``serialize`` takes)."""
    return type_store().types[_known(type_name)]


def type_hash(type_name: str) -> str:
    """The RIHS01 hash (REP 2016) of a message, service or action: ``RIHS01_`` and 64 lower-case hex digits."""
    return _hash(_known(type_name, messages_only=False))


@cache
def _hash(type_name: str) -> str:
    return _interfaces().type_hash(type_name)


_CHECKED: set[str] = set()  # message type names ``_known`` accepted: a type once known stays known


def _known_message(type_name: str) -> str:
    """``_known(type_name)``, checked once per name: serialising is on every call's hot path."""
    if type_name in _CHECKED:
        return type_name
    name = _known(type_name)
    _CHECKED.add(name)
    return name


def serialize(message: Any, type_name: str | None = None) -> bytes:
    """The message's CDR bytes, little endian, with the encapsulation header ``00 01 00 00``.

    ``type_name`` defaults to the message's own type; naming another one is an error rather than
    a silent reinterpretation.
    """
    own = getattr(message, "__msgtype__", None)
    name = _known_message(type_name or own or "")
    if own != name:
        raise TypeError(f"a {own or type(message).__name__} message cannot be serialised as {name}")
    try:
        return bytes(type_store().serialize_cdr(message, name))
    except (SerdeError, TypeError, ValueError, AttributeError, OverflowError) as error:
        raise CdrError(f"cannot serialise this {name} message: {error}") from error


def deserialize(data: bytes | bytearray | memoryview, type_name: str) -> Any:
    """The message of ``type_name`` in ``data`` (CDR with its encapsulation header), or a CdrError."""
    name = _known_message(type_name)
    raw = bytes(data)
    if len(raw) < 4:
        raise CdrError(f"{len(raw)} bytes cannot hold a {name} message: CDR starts with a 4-byte header")
    if raw[:2] not in _PLAIN_CDR:
        raise CdrError(
            f"unsupported CDR encapsulation {raw[:2].hex(' ')} for {name}: expected plain CDR "
            "(00 00 big endian or 00 01 little endian)"
        )
    try:
        return type_store().deserialize_cdr(raw, name)
    except (SerdeError, ValueError, IndexError, UnicodeDecodeError, OverflowError) as error:
        raise CdrError(f"these {len(raw)} bytes are not a {name} message: {error}") from error


_NUMPY_DTYPES = {"bool": "bool", "byte": "uint8", "char": "uint8", "float32": "float32", "float64": "float64"}
_NUMPY_DTYPES |= {f"{sign}int{bits}": f"{sign}int{bits}" for sign in ("", "u") for bits in (8, 16, 32, 64)}


def default_message(type_name: str) -> Any:
    """A message of ``type_name`` with every field at its zero value (0, false, "", empty sequences)."""
    name = _known(type_name)
    return message_class(name)(**{field: _default(desc) for field, desc in type_store().fielddefs[name][1]})


def _default(desc: Any) -> Any:
    kind, detail = desc
    if kind == Nodetype.BASE:
        return {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}.get(detail[0], 0)
    if kind == Nodetype.NAME:
        return default_message(detail)
    element, count = detail
    count = count if kind == Nodetype.ARRAY else 0
    if element[0] == Nodetype.BASE and element[1][0] in _NUMPY_DTYPES:
        return numpy.zeros(count, dtype=_NUMPY_DTYPES[element[1][0]])
    return [_default(element) for _ in range(count)]
