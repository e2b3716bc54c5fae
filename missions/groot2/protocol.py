"""Groot2's wire format, as BehaviorTree.CPP defines it (``loggers/groot2_protocol.h`` and
``groot2_publisher.cpp``): request and reply headers, node statuses, hooks, and the MessagePack
that carries blackboards.

Every exchange is a multipart ZMQ request/reply. A request's first part is 6 bytes: protocol id
(``2``), request type (one ASCII letter), a random ``uint32`` id (little-endian, as BT.CPP
memcpy's it on the machines it runs on). A reply's first part repeats them and adds the tree's
16-byte UUID. A refused request is answered ``["error", why]``.
"""

from __future__ import annotations

import json
import math
import random
import struct
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

PROTOCOL_ID = 2
REQUEST_SIZE = 6
REPLY_SIZE = REQUEST_SIZE + 16

# request types (RequestType in groot2_protocol.h)
FULLTREE = ord("T")
STATUS = ord("S")
BLACKBOARD = ord("B")
HOOK_INSERT = ord("I")
HOOK_REMOVE = ord("R")
BREAKPOINT_REACHED = ord("N")
BREAKPOINT_UNLOCK = ord("U")
HOOKS_DUMP = ord("D")
REMOVE_ALL_HOOKS = ord("A")
DISABLE_ALL_HOOKS = ord("X")
TOGGLE_RECORDING = ord("r")
GET_TRANSITIONS = ord("t")

# NodeStatus in BT.CPP's basic_types.h; the status buffer says "idle, after X" as 10 + X
IDLE, RUNNING, SUCCESS, FAILURE, SKIPPED = 0, 1, 2, 3, 4
IDLE_FROM = 10
STATUS_NAMES = {IDLE: "IDLE", RUNNING: "RUNNING", SUCCESS: "SUCCESS", FAILURE: "FAILURE", SKIPPED: "SKIPPED"}
STATUS_CODES = {name: code for code, name in STATUS_NAMES.items()}
PY_TREES = {"INVALID": IDLE, "RUNNING": RUNNING, "SUCCESS": SUCCESS, "FAILURE": FAILURE}

# Hook::Position and Hook::Mode
PRE, POST = 0, 1
BREAKPOINT, REPLACE = 0, 1


class ProtocolError(ValueError):
    """A request that does not follow the protocol; the text is what the client is told."""


@dataclass(frozen=True)
class RequestHeader:
    type: int
    unique_id: int
    protocol: int = PROTOCOL_ID

    def pack(self) -> bytes:
        return struct.pack("<BBI", self.protocol, self.type, self.unique_id)

    @classmethod
    def unpack(cls, data: bytes) -> RequestHeader:
        if len(data) != REQUEST_SIZE:
            raise ProtocolError("wrong request header")  # BT.CPP's words for it
        protocol, kind, unique_id = struct.unpack("<BBI", data)
        return cls(kind, unique_id, protocol)

    @classmethod
    def new(cls, kind: int) -> RequestHeader:
        """A header of our own (the PUB socket's notifications): a random id will do, as in BT.CPP."""
        return cls(kind, random.getrandbits(32))


def reply_header(request: RequestHeader, tree_id: bytes) -> bytes:
    """The reply's first part: the request's header (protocol set to ours) and the tree's UUID."""
    return RequestHeader(request.type, request.unique_id).pack() + tree_id


def new_tree_id() -> bytes:
    """The 16 bytes that name this tree for as long as the publisher lives (a version-4 UUID)."""
    return uuid.uuid4().bytes


@dataclass
class Hook:
    """A Groot2 hook on one node: a breakpoint that holds the run, or a replacement that returns
    ``desired_status`` instead of running the node."""

    uid: int
    enabled: bool = True
    mode: int = BREAKPOINT
    once: bool = False
    desired_status: int = SKIPPED
    position: int = PRE
    ready: bool = False  # unlocked: a run held on it may go (never sent)

    def plain(self) -> dict[str, Any]:
        """As BT.CPP's ``to_json(Hook)`` writes it."""
        return {
            "enabled": self.enabled,
            "uid": self.uid,
            "mode": self.mode,
            "once": self.once,
            "desired_status": STATUS_NAMES[self.desired_status],
            "position": self.position,
        }


def parse_json(data: bytes) -> Any:
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ProtocolError(f"the request's second part is not JSON: {exc}") from None


def _field(js: Mapping[str, Any], name: str, kind: type | tuple[type, ...]) -> Any:
    if name not in js:
        raise ProtocolError(f"hook: missing field {name!r}")
    value = js[name]
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise ProtocolError(f"hook: field {name!r} must be {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


def hook_from_json(js: Any) -> Hook:
    """BT.CPP's ``from_json(Hook)``: every field is required."""
    if not isinstance(js, Mapping):
        raise ProtocolError(f"a hook is a JSON object, got {js!r}")
    status = _field(js, "desired_status", str)
    if status not in STATUS_CODES:
        raise ProtocolError(f"hook: desired_status {status!r} is not one of {', '.join(STATUS_CODES)}")
    mode, position = _field(js, "mode", int), _field(js, "position", int)
    if mode not in (BREAKPOINT, REPLACE):
        raise ProtocolError(f"hook: mode {mode} is neither 0 (breakpoint) nor 1 (replace)")
    if position not in (PRE, POST):
        raise ProtocolError(f"hook: position {position} is neither 0 (pre) nor 1 (post)")
    return Hook(
        uid=_uid(_field(js, "uid", int)),
        enabled=_field(js, "enabled", bool),
        mode=mode,
        once=_field(js, "once", bool),
        desired_status=STATUS_CODES[status],
        position=position,
    )


def _uid(value: int) -> int:
    if not 0 <= value <= 0xFFFF:
        raise ProtocolError(f"uid {value} is not a uint16")
    return value


def uid_and_position(js: Any) -> tuple[int, int]:
    """HOOK_REMOVE's body: the hook's node and position (BT.CPP reads only these two fields)."""
    if not isinstance(js, Mapping):
        raise ProtocolError(f"a hook to remove is a JSON object, got {js!r}")
    return _uid(_field(js, "uid", int)), _field(js, "position", int)


def unlock_from_json(js: Any) -> tuple[int, int, int, bool]:
    """BREAKPOINT_UNLOCK's body: (uid, position, desired status, remove when done). As in BT.CPP,
    a desired status other than SUCCESS or FAILURE means "run the node as usual" (SKIPPED)."""
    if not isinstance(js, Mapping):
        raise ProtocolError(f"an unlock is a JSON object, got {js!r}")
    uid = _uid(_field(js, "uid", int))
    status = _field(js, "desired_status", str)
    position = _field(js, "position", int)
    remove = _field(js, "remove_when_done", bool)
    return uid, position, {"SUCCESS": SUCCESS, "FAILURE": FAILURE}.get(status, SKIPPED), remove


def pack_transition(timestamp_us: int, uid: int, status: int) -> bytes:
    """One transition as GET_TRANSITIONS and .btlog files carry it: 6 bytes of the timestamp
    (microseconds, little-endian), the node's uint16 uid, its uint8 status."""
    return struct.pack("<Q", timestamp_us)[:6] + struct.pack("<HB", uid, status)


# -- MessagePack (the subset JSON values need; nlohmann::json::to_msgpack's choices) ---------


def msgpack(value: Any) -> bytes:
    out = bytearray()
    _pack(value, out)
    return bytes(out)


def _pack(value: Any, out: bytearray) -> None:
    if value is None:
        out.append(0xC0)
    elif value is True or value is False:
        out.append(0xC3 if value else 0xC2)
    elif isinstance(value, int):
        _pack_int(value, out)
    elif isinstance(value, float):
        if math.isfinite(value):
            out += b"\xcb" + struct.pack(">d", value)
        else:
            _pack(repr(value), out)  # JSON has no inf/nan: say it as the trace does
    elif isinstance(value, str):
        data = value.encode("utf-8")
        _length(len(data), out, 0xA0, 31, (0xD9, 0xDA, 0xDB))
        out += data
    elif isinstance(value, Mapping):
        _length(len(value), out, 0x80, 15, (None, 0xDE, 0xDF))
        for key, item in value.items():
            _pack(str(key), out)
            _pack(item, out)
    elif isinstance(value, list | tuple):
        _length(len(value), out, 0x90, 15, (None, 0xDC, 0xDD))
        for item in value:
            _pack(item, out)
    else:
        raise TypeError(f"no MessagePack form for {type(value).__name__}")


def _length(n: int, out: bytearray, fix: int, fix_max: int, wide: tuple[int | None, int, int]) -> None:
    if n <= fix_max:
        out.append(fix | n)
    elif n <= 0xFF and wide[0] is not None:
        out += bytes((wide[0], n))
    elif n <= 0xFFFF:
        out += bytes((wide[1],)) + struct.pack(">H", n)
    else:
        out += bytes((wide[2],)) + struct.pack(">I", n)


def _pack_int(n: int, out: bytearray) -> None:
    if 0 <= n <= 0x7F:
        out.append(n)
    elif -32 <= n < 0:
        out += struct.pack(">b", n)
    elif n >= 0:
        for code, fmt, top in ((0xCC, ">B", 0xFF), (0xCD, ">H", 0xFFFF), (0xCE, ">I", 0xFFFFFFFF)):
            if n <= top:
                out += bytes((code,)) + struct.pack(fmt, n)
                return
        if n > 0xFFFFFFFFFFFFFFFF:
            raise OverflowError(f"{n} does not fit MessagePack's integers")
        out += b"\xcf" + struct.pack(">Q", n)
    else:
        for code, fmt, low in ((0xD0, ">b", -0x80), (0xD1, ">h", -0x8000), (0xD2, ">i", -0x80000000)):
            if n >= low:
                out += bytes((code,)) + struct.pack(fmt, n)
                return
        if n < -0x8000000000000000:
            raise OverflowError(f"{n} does not fit MessagePack's integers")
        out += b"\xd3" + struct.pack(">q", n)
