"""ROS 2 message types: Jazzy's standard messages and botstage's own, their CDR bytes and hashes.

One rosbags type store holds ROS 2 Jazzy's messages plus every ``.msg`` shipped under
``robots/ros2/msg/<package>/msg/``, registered when the store is first used. Everything that
goes on the wire about a type comes from here: its DDS name and RIHS01 hash (both in every key
expression and liveliness token) and its CDR bytes with the 4-byte encapsulation header, as
rmw_zenoh sends them. CDR is rosbags' work, never written by hand.
"""

from __future__ import annotations

import difflib
import re
from functools import cache
from pathlib import Path
from typing import Any

from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

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


def shipped_definitions(root: Path = MSG_ROOT) -> dict[str, str]:
    """The ``.msg`` files under ``root`` by full type name (``pkg/msg/Name``)."""
    return {
        f"{path.parent.parent.name}/msg/{path.stem}": path.read_text(encoding="utf-8")
        for path in sorted(root.glob("*/msg/*.msg"))
    }


@cache
def type_store() -> Any:
    """ROS 2 Jazzy's type store with botstage's messages registered (built once per process)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    parsed: dict[str, Any] = {}
    for name, text in shipped_definitions().items():
        parsed.update(get_types_from_msg(text, name))
    store.register(parsed)
    return store


def check_type_name(type_name: str) -> str:
    """``type_name`` if it is a full interface name (``pkg/msg/Type``), else a ValueError saying why."""
    if not isinstance(type_name, str) or not _TYPE_NAME.match(type_name):
        raise ValueError(
            f"{type_name!r} is not a ROS 2 interface type name: expected 'package/msg/Type' "
            "(a lower-case package, msg, srv or action, then a CamelCase name), e.g. 'geometry_msgs/msg/Twist'"
        )
    return type_name


def _known(type_name: str) -> str:
    check_type_name(type_name)
    store = type_store()
    if type_name not in store.types:
        near = difflib.get_close_matches(type_name, list(store.types), n=3)
        hint = f"; did you mean {', '.join(repr(n) for n in near)}?" if near else ""
        raise UnknownTypeError(
            f"unknown message type {type_name!r}: not one of ROS 2 Jazzy's standard messages nor of "
            f"botstage's ({MSG_ROOT.name}/<package>/msg/*.msg){hint}"
        )
    return type_name


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
    """Whether ``type_name`` is in the store (a standard message or botstage's)."""
    return isinstance(type_name, str) and type_name in type_store().types


def message_class(type_name: str) -> Any:
    """The class whose instances are messages of ``type_name`` (what ``serialize`` takes)."""
    return type_store().types[_known(type_name)]


def type_hash(type_name: str) -> str:
    """The type's RIHS01 hash (REP 2016): ``RIHS01_`` and 64 lower-case hex digits."""
    return type_store().hash_rihs01(_known(type_name))


def serialize(message: Any, type_name: str | None = None) -> bytes:
    """The message's CDR bytes, little endian, with the encapsulation header ``00 01 00 00``.

    ``type_name`` defaults to the message's own type; naming another one is an error rather than
    a silent reinterpretation.
    """
    own = getattr(message, "__msgtype__", None)
    name = _known(type_name or own or "")
    if own != name:
        raise TypeError(f"a {own or type(message).__name__} message cannot be serialised as {name}")
    try:
        return bytes(type_store().serialize_cdr(message, name))
    except (SerdeError, TypeError, ValueError, AttributeError, OverflowError) as error:
        raise CdrError(f"cannot serialise this {name} message: {error}") from error


def deserialize(data: bytes | bytearray | memoryview, type_name: str) -> Any:
    """The message of ``type_name`` in ``data`` (CDR with its encapsulation header), or a CdrError."""
    name = _known(type_name)
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
