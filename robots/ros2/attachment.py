"""The attachment rmw_zenoh puts on every message, and the entity GIDs it carries.

33 bytes, as rmw_zenoh's ``AttachmentData`` writes them with ``zenoh::ext::Serializer``::

    int64 LE sequence number | int64 LE source timestamp (ns since the epoch) | 0x10 | 16-byte GID

0x10 is the GID's length as LEB128. A subscriber of rmw_zenoh drops a sample without one, so
every botstage publication has it. Decoding also takes the 32 bytes without the length byte,
which later ROS 2 releases may send.

The GID is rmw_zenoh's: XXH3-128 of the entity's exact liveliness token, low 64 bits then high
64 bits, each little endian (rmw_zenoh memcpys them on little-endian machines, the only ones it
ships for). It needs the ``xxhash`` package, a dependency for this reason: a GID of any other
derivation would work on the wire, but ROS 2 tools could not match a message's GID to its
publisher in the graph (``ros2 topic info -v``, message_info.publisher_gid).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import xxhash

GID_SIZE = 16
_HEADER = struct.Struct("<qq")  # sequence number, source timestamp
_WHOLE = struct.Struct(f"<qqB{GID_SIZE}s")  # and the GID with its length byte
ENCODED_SIZE = _HEADER.size + 1 + GID_SIZE
_INT64 = (-(2**63), 2**63 - 1)


class AttachmentError(ValueError):
    """Bytes that are not an rmw_zenoh attachment."""


@dataclass(frozen=True, slots=True)
class Attachment:
    """A message's sequence number (from 1 per publisher), source time in ns and publisher GID."""

    sequence: int
    timestamp_ns: int
    gid: bytes

    def __post_init__(self) -> None:
        for name in ("sequence", "timestamp_ns"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not _INT64[0] <= value <= _INT64[1]:
                raise ValueError(f"attachment {name} {value!r}: must be a 64-bit signed integer")
        if not isinstance(self.gid, bytes) or len(self.gid) != GID_SIZE:
            raise ValueError(f"attachment gid: must be {GID_SIZE} bytes, got {self.gid!r}")


def encode(attachment: Attachment) -> bytes:
    """The attachment's 33 bytes."""
    return pack(attachment.sequence, attachment.timestamp_ns, attachment.gid)


def pack(sequence: int, timestamp_ns: int, gid: bytes) -> bytes:
    """``encode`` of a sender's own values, without building (and checking) an Attachment per message.

    ``gid`` must be an entity's 16-byte GID; struct.error for a number out of range.
    """
    return _WHOLE.pack(sequence, timestamp_ns, GID_SIZE, gid)


def unpack(data: bytes | bytearray | memoryview) -> tuple[int, int, bytes]:
    """The sequence number, timestamp and GID in ``data`` (as ``decode`` reads them); AttachmentError otherwise."""
    raw = bytes(data)
    if len(raw) == ENCODED_SIZE:
        sequence, timestamp_ns, length, gid = _WHOLE.unpack(raw)
        if length != GID_SIZE:
            raise AttachmentError(f"attachment GID length byte is {length}, expected {GID_SIZE}")
        return sequence, timestamp_ns, gid
    if len(raw) == ENCODED_SIZE - 1:
        sequence, timestamp_ns = _HEADER.unpack_from(raw)
        return sequence, timestamp_ns, raw[_HEADER.size :]
    raise AttachmentError(f"an attachment has {ENCODED_SIZE} bytes (or {ENCODED_SIZE - 1}), got {len(raw)}")


def decode(data: bytes | bytearray | memoryview) -> Attachment:
    """The attachment in ``data`` (33 bytes, or 32 without the length byte); AttachmentError otherwise."""
    sequence, timestamp_ns, gid = unpack(data)
    # struct read the fields, so they are in range: skip the checks __post_init__ makes of callers' values
    attachment = object.__new__(Attachment)
    _set(attachment, "sequence", sequence)
    _set(attachment, "timestamp_ns", timestamp_ns)
    _set(attachment, "gid", gid)
    return attachment


_set = object.__setattr__  # how a frozen dataclass sets its own fields


def entity_gid(token: str) -> bytes:
    """rmw_zenoh's GID of the entity whose liveliness token is ``token``."""
    digest = xxhash.xxh3_128_intdigest(token.encode("utf-8"))
    low, high = digest & (2**64 - 1), digest >> 64
    return low.to_bytes(8, "little") + high.to_bytes(8, "little")
