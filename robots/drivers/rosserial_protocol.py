"""The rosserial protocol (ROS 1's serial link to microcontrollers): packet framing and the
protocol's own messages. No I/O.

Sources (public repositories, read for the facts below):

- ros-drivers/rosserial ``rosserial_client/src/ros_lib/ros/node_handle.h`` (the device side) and
  ``rosserial_python/src/rosserial_python/SerialClient.py`` (the host side, noetic): a packet is
  ``0xFF``, the protocol version, the payload length (uint16, little end first), a length
  checksum ``255 - (len_lo + len_hi) % 256``, the topic id (uint16, little end first), the
  payload (a ROS 1 serialised message), and a checksum ``255 - (sum of topic id and payload
  bytes) % 256``. The host asks for the device's topics with an empty packet on topic 0
  (``ff fe 00 00 ff 00 00 ff``) and tells it to stop with one on topic 11
  (``ff fe 00 00 ff 0b 00 f4``).
- The protocol version is the second sync byte: ``0xFF`` through groovy (rosserial 0.4 and
  earlier), ``0xFE`` since hydro (0.5+), ``0xFD`` was kept for "some future version". A groovy
  packet has no length checksum: ``ff ff``, topic id, length, payload, one checksum over all of
  them. This host speaks hydro+ only, like SerialClient: a groovy frame is recognised whole,
  counted as ``protocol_version`` and dropped (its device must be rebuilt with a newer
  ros_lib); a hydro device that hears a wrong version while unconfigured answers with a time
  request in its own version, so the host sees who it talks to.
- ``rosserial_msgs/msg/TopicInfo.msg`` and ``Log.msg`` (noetic): the reserved topic ids
  (publisher 0, subscriber 1, service server 2, service client 4, parameter request 6, log 7,
  time 10, tx stop 11; ids from 100 are the device's publishers and subscribers), TopicInfo's
  fields (topic_id, topic_name, message_type, md5sum, buffer_size) and the log levels
  (ROSDEBUG 0, INFO 1, WARN 2, ERROR 3, FATAL 4). Their definitions are given below and
  registered in a rosbags typestore; the md5 sums rosbags computes from them are the published
  ones (0ad51f88… and 11abd731…, checked by the tests).
- ``rosserial_msgs/srv/RequestParam.srv``: a parameter request is ``string name``, its answer
  ``int32[] ints``, ``float32[] floats``, ``string[] strings``.
- ``rosserial_client/src/ros_lib/tf/transform_broadcaster.h``: ros_lib's TF broadcaster
  publishes ``tf/tfMessage`` (``geometry_msgs/TransformStamped[] transforms``) on ``/tf``;
  rosbags' noetic store lacks that type, so it is registered here too.

Messages are (de)serialised by rosbags (``serialize_ros1``/``deserialize_ros1``); only the
framing is done by hand. ``PacketDecoder`` is the streaming side: it keeps partial input, never
raises on bad bytes, and counts what it parsed (``ok``, by topic) and dropped (``bad``, by
reason). A packet that fails a check is dropped and the bytes after its sync byte are scanned
again, so a lying length field loses only its own packet: the good packets it swallowed are
found on the rescan (they are held back until enough bytes came to disprove it, at most
``max_payload``). Memory is bounded: the decoder holds at most one candidate packet
(``8 + max_payload`` bytes) between calls.
"""

from __future__ import annotations

import math
import struct
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

SYNC = 0xFF
PROTOCOL_VER1 = 0xFF  # through groovy (rosserial 0.4 and earlier)
PROTOCOL_VER2 = 0xFE  # hydro and later (rosserial 0.5+): the one spoken here
PROTOCOL_FUTURE = 0xFD  # SerialClient's "some future rosserial version"
HEADER = 7  # sync, version, length (2), length checksum, topic id (2)
OVERHEAD = HEADER + 1  # and the checksum after the payload
MAX_LENGTH = 0xFFFF  # the length field is 16 bits
# ros_lib's default NodeHandle buffers are 512 bytes (280 on an ATmega328P), framing included;
# twice that bounds what the decoder waits for on a length it cannot check yet.
DEFAULT_MAX_PAYLOAD = 1024

# Reserved topic ids (rosserial_msgs/TopicInfo, noetic); ids from FIRST_DYNAMIC_ID are endpoints.
ID_PUBLISHER = 0
ID_SUBSCRIBER = 1
ID_SERVICE_SERVER = 2
ID_SERVICE_CLIENT = 4
ID_PARAMETER_REQUEST = 6
ID_LOG = 7
ID_TIME = 10
ID_TX_STOP = 11
FIRST_DYNAMIC_ID = 100

RESERVED_KINDS = {
    ID_PUBLISHER: "publisher",
    ID_SUBSCRIBER: "subscriber",
    ID_SERVICE_SERVER + ID_PUBLISHER: "service_server",
    ID_SERVICE_SERVER + ID_SUBSCRIBER: "service_server_subscriber",
    ID_SERVICE_CLIENT + ID_PUBLISHER: "service_client",
    ID_SERVICE_CLIENT + ID_SUBSCRIBER: "service_client_subscriber",
    ID_PARAMETER_REQUEST: "parameter_request",
    ID_LOG: "log",
    ID_TIME: "time",
    ID_TX_STOP: "tx_stop",
}

# rosserial_msgs/Log levels
ROSDEBUG, INFO, WARN, ERROR, FATAL = range(5)

TOPIC_INFO = "rosserial_msgs/msg/TopicInfo"
LOG = "rosserial_msgs/msg/Log"
TIME = "std_msgs/msg/Time"
PARAM_REQUEST = "rosserial_msgs/msg/RequestParamRequest"
PARAM_RESPONSE = "rosserial_msgs/msg/RequestParamResponse"
TF_MESSAGE = "tf/msg/tfMessage"

# ROS 1 definitions, as in ros-drivers/rosserial (noetic) and ros/geometry (tf)
DEFINITIONS = {
    TOPIC_INFO: """# special topic_ids
uint16 ID_PUBLISHER=0
uint16 ID_SUBSCRIBER=1
uint16 ID_SERVICE_SERVER=2
uint16 ID_SERVICE_CLIENT=4
uint16 ID_PARAMETER_REQUEST=6
uint16 ID_LOG=7
uint16 ID_TIME=10
uint16 ID_TX_STOP=11

# The endpoint ID for this topic
uint16 topic_id

string topic_name
string message_type

# MD5 checksum for this message type
string md5sum

# size of the buffer message must fit in
int32 buffer_size
""",
    LOG: """
#ROS Logging Levels
uint8 ROSDEBUG=0
uint8 INFO=1
uint8 WARN=2
uint8 ERROR=3
uint8 FATAL=4

uint8 level
string msg
""",
    PARAM_REQUEST: "string name\n",
    PARAM_RESPONSE: "int32[] ints\nfloat32[] floats\nstring[] strings\n",
    TF_MESSAGE: "geometry_msgs/TransformStamped[] transforms\n",
}


def make_typestore(extra: dict[str, str] | None = None) -> Typestore:
    """ROS 1 noetic's types with rosserial's own (and ``extra``: rosbags name to definition): a
    store of one's own, since rosbags hands out a new one per call and registering is for keeps."""
    store = get_typestore(Stores.ROS1_NOETIC)
    register_types(store, {**DEFINITIONS, **(extra or {})})
    return store


def register_types(store: Typestore, definitions: dict[str, str]) -> None:
    """Add ROS 1 ``.msg`` definitions (rosbags name, e.g. ``pkg/msg/Name``, to text) to ``store``."""
    types: dict[str, Any] = {}
    for name, text in definitions.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)


TYPESTORE = make_typestore()


def store_name(wire_type: str) -> str | None:
    """rosserial's ``pkg/Name`` as rosbags' ``pkg/msg/Name``; None when it is not a type name."""
    parts = wire_type.split("/")
    if len(parts) == 2 and all(parts):
        return f"{parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] == "msg" and parts[0] and parts[2]:
        return wire_type
    return None


def wire_name(typename: str) -> str:
    """rosbags' ``pkg/msg/Name`` as ROS 1 and rosserial write it, ``pkg/Name``."""
    package, _, name = typename.rpartition("/msg/")
    return f"{package}/{name}" if package else typename


def md5sum(typename: str, store: Typestore = TYPESTORE) -> str:
    """The ROS 1 md5 of a type (rosbags name), as a TopicInfo carries it."""
    return store.generate_msgdef(typename, ros_version=1)[1]


def serialize(message: Any, store: Typestore = TYPESTORE) -> bytes:
    return bytes(store.serialize_ros1(message, message.__msgtype__))


def deserialize(payload: bytes, typename: str, store: Typestore = TYPESTORE) -> Any:
    return store.deserialize_ros1(payload, typename)


# -- framing -----------------------------------------------------------------------------------


def checksum(data: bytes) -> int:
    """rosserial's checksum: what makes the bytes' sum 255 modulo 256."""
    return 255 - sum(data) % 256


def encode_packet(topic_id: int, payload: bytes = b"", version: int = PROTOCOL_VER2) -> bytes:
    """One packet, framed as node_handle.h and SerialClient frame it."""
    if not 0 <= topic_id <= 0xFFFF:
        raise ValueError(f"topic id {topic_id}: 0 to 65535")
    if len(payload) > MAX_LENGTH:
        raise ValueError(f"payload of {len(payload)} bytes: at most {MAX_LENGTH}")
    length = struct.pack("<H", len(payload))
    body = struct.pack("<H", topic_id) + payload
    return bytes((SYNC, version)) + length + bytes((checksum(length),)) + body + bytes((checksum(body),))


TOPIC_REQUEST = encode_packet(ID_PUBLISHER)  # ff fe 00 00 ff 00 00 ff
TX_STOP = encode_packet(ID_TX_STOP)  # ff fe 00 00 ff 0b 00 f4


def kind_of(topic_id: int) -> str:
    """A counter's name for a topic id: the reserved ones by name, the rest by number."""
    if topic_id >= FIRST_DYNAMIC_ID:
        return f"topic_{topic_id}"
    return RESERVED_KINDS.get(topic_id, f"reserved_{topic_id}")


@dataclass(frozen=True, slots=True)
class Packet:
    topic_id: int
    payload: bytes

    @property
    def kind(self) -> str:
        return kind_of(self.topic_id)


class PacketDecoder:
    """Bytes in, packets out (see the module); the same packets and counts however the bytes
    are split between calls.

    ``ok`` counts packets by kind (``publisher``, ``time``, ``log``, … for the reserved ids,
    ``topic_<id>`` for the others). ``bad`` counts what was dropped, by reason: ``garbage`` (a
    stretch of bytes between packets that starts none), ``length_checksum``, ``checksum``,
    ``protocol_version`` (a whole groovy frame, or the future version byte 0xFD), ``oversize``
    (a checked length over ``max_payload``). The bytes a failed candidate claimed (its header,
    or all its length said) are part of that one fault, not garbage too."""

    def __init__(self, max_payload: int = DEFAULT_MAX_PAYLOAD) -> None:
        if not 0 <= max_payload <= MAX_LENGTH:
            raise ValueError(f"max_payload {max_payload}: 0 to {MAX_LENGTH}")
        self.max_payload = max_payload
        self.ok: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()
        self.skipped_bytes = 0  # bytes dropped outside packets, failed candidates' included
        self._buffer = bytearray()
        self._base = 0  # the stream offset of the buffer's first byte
        self._failed_until = 0  # stream offset: bytes before it belong to a failed candidate
        self._in_garbage = False  # inside a stretch of garbage already counted

    @property
    def buffered(self) -> int:
        """Bytes held for a packet not complete yet (at most ``8 + max_payload``)."""
        return len(self._buffer)

    def resync(self) -> None:
        """Forget a partial packet (a new link: the first bytes may be the middle of one)."""
        self._base += len(self._buffer)
        self._failed_until = self._base
        self._buffer.clear()
        self._in_garbage = False

    def feed(self, data: bytes) -> list[Packet]:
        buffer = self._buffer
        buffer += data
        packets: list[Packet] = []
        pos = 0
        end = len(buffer)
        while pos < end:
            start = buffer.find(SYNC, pos)
            if start < 0:
                self._skip(pos, end - pos)
                pos = end
                break
            if start > pos:
                self._skip(pos, start - pos)
                pos = start
            step = self._candidate(buffer, pos, packets)
            if step == 0:  # wait for more bytes
                break
            pos += step
        del buffer[:pos]
        self._base += pos
        return packets

    def _skip(self, at: int, count: int) -> None:
        """Drop ``count`` bytes from ``at``: a new stretch of garbage, unless they lie within
        the extent of a candidate that failed (a corrupt packet is one fault, not two)."""
        self.skipped_bytes += count
        if self._base + at + count > self._failed_until and not self._in_garbage:
            self.bad["garbage"] += 1
            self._in_garbage = True

    def _fail(self, reason: str, at: int, extent: int) -> int:
        """The candidate at ``at`` failed: count it, note the bytes it claimed (``extent``), and
        scan again from the byte after its sync byte."""
        self.bad[reason] += 1
        self.skipped_bytes += 1
        self._failed_until = max(self._failed_until, self._base + at + extent)
        return 1

    def _candidate(self, buffer: bytearray, pos: int, packets: list[Packet]) -> int:
        """Bytes to move past the sync byte at ``pos``: a packet's length, 1 after a failed or
        foreign candidate, 0 when more bytes are needed to decide."""
        available = len(buffer) - pos
        if available < 2:
            return 0
        version = buffer[pos + 1]
        if version in (PROTOCOL_VER2, PROTOCOL_FUTURE):
            if available < 5:
                return 0
            low, high, length_check = buffer[pos + 2], buffer[pos + 3], buffer[pos + 4]
            length_ok = (low + high + length_check) % 256 == 255
            length = low | high << 8
            if version == PROTOCOL_FUTURE:  # framed like ours, presumably: its bytes are one fault
                return self._fail("protocol_version", pos, OVERHEAD + length if length_ok else 2)
            if not length_ok:  # the length may be right and its checksum wrong: its bytes are this fault's
                return self._fail("length_checksum", pos, OVERHEAD + min(length, self.max_payload))
            if length > self.max_payload:
                return self._fail("oversize", pos, OVERHEAD + length)
            size = OVERHEAD + length
            if available < size:
                return 0
            if sum(buffer[pos + 5 : pos + size]) % 256 != 255:
                return self._fail("checksum", pos, size)
            packet = Packet(buffer[pos + 5] | buffer[pos + 6] << 8, bytes(buffer[pos + HEADER : pos + size - 1]))
            packets.append(packet)
            self.ok[packet.kind] += 1
            self._in_garbage = False
            return size
        if version == PROTOCOL_VER1:
            return self._groovy(buffer, pos, available)
        self._skip(pos, 1)  # a 0xFF of noise
        return 1

    def _groovy(self, buffer: bytearray, pos: int, available: int) -> int:
        """``ff ff``: a whole groovy frame (topic, length, payload, checksum over them) is a
        device of the old protocol; anything else is a noise byte before a sync byte."""
        if available >= 3 and buffer[pos + 2] == PROTOCOL_VER2:
            self._skip(pos, 1)  # ff ff fe: noise, then a packet
            return 1
        if available < 6:
            return 0
        length = buffer[pos + 4] | buffer[pos + 5] << 8
        if length <= self.max_payload:
            size = 7 + length
            if available < size:
                return 0
            if sum(buffer[pos + 2 : pos + size]) % 256 == 255:
                self._fail("protocol_version", pos, size)
                self.skipped_bytes += size - 1
                return size
        self._skip(pos, 1)
        return 1


# -- the protocol's messages ------------------------------------------------------------------


def topic_info(
    topic_id: int, topic_name: str, typename: str, buffer_size: int, store: Typestore = TYPESTORE, md5: str = ""
) -> Any:
    """A TopicInfo as a device announces an endpoint (``typename`` in rosbags' form); its md5 is
    the type's unless ``md5`` says otherwise (tests use that to lie)."""
    return store.types[TOPIC_INFO](
        topic_id=topic_id,
        topic_name=topic_name,
        message_type=wire_name(typename),
        md5sum=md5 or md5sum(typename, store),
        buffer_size=buffer_size,
    )


def time_message(seconds: float) -> Any:
    """std_msgs/Time for a time in seconds (sec, nsec; negative or non-finite times are 0)."""
    if not math.isfinite(seconds) or seconds < 0:
        seconds = 0.0
    sec = min(int(seconds), 2**32 - 1)
    nsec = min(round((seconds - sec) * 1e9), 999_999_999)
    types = TYPESTORE.types
    return types[TIME](data=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec))


def time_seconds(message: Any) -> float:
    return message.data.sec + message.data.nanosec * 1e-9


def log_message(level: int, text: str) -> Any:
    return TYPESTORE.types[LOG](level=level, msg=text)


def param_response(values: list[int] | list[float] | list[str]) -> Any:
    """A parameter's answer: ints (and bools), floats or strings, as SerialClient sorts them."""
    ints = [int(v) for v in values if isinstance(v, bool | int)]
    floats = [float(v) for v in values if isinstance(v, float)]
    strings = [v for v in values if isinstance(v, str)]
    return TYPESTORE.types[PARAM_RESPONSE](
        ints=np.array(ints, dtype=np.int32), floats=np.array(floats, dtype=np.float32), strings=strings
    )
