"""The rosserial framing and messages alone: round trips however the bytes are split, every bad
case dropped and counted by its reason, and bounded memory."""

from __future__ import annotations

import itertools
import random
import struct
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.drivers.rosserial_protocol import OVERHEAD, Packet, PacketDecoder, encode_packet


def feed_all(decoder: PacketDecoder, stream: bytes, cuts: list[int] | None = None) -> list[Packet]:
    """Feed ``stream`` in pieces split at ``cuts`` (offsets), collecting the packets."""
    bounds = [0, *sorted(set(cuts or [])), len(stream)]
    packets: list[Packet] = []
    for start, end in itertools.pairwise(bounds):
        packets += decoder.feed(stream[start:end])
    return packets


def groovy_frame(topic_id: int, payload: bytes) -> bytes:
    """A pre-hydro packet (rosserial 0.4, groovy): ff ff, topic id, length, payload, one checksum."""
    body = struct.pack("<HH", topic_id, len(payload)) + payload
    return b"\xff\xff" + body + bytes((rp.checksum(body),))


def test_the_host_packets_are_serialclients() -> None:
    assert rp.TOPIC_REQUEST == b"\xff\xfe\x00\x00\xff\x00\x00\xff"
    assert rp.TX_STOP == b"\xff\xfe\x00\x00\xff\x0b\x00\xf4"
    packet = encode_packet(126, b"\x01\x02\x03")
    assert packet[:5] == b"\xff\xfe\x03\x00\xfc"
    assert packet[5:7] == b"\x7e\x00" and packet[7:-1] == b"\x01\x02\x03"
    assert sum(packet[5:]) % 256 == 255
    with pytest.raises(ValueError):
        encode_packet(70_000, b"")
    with pytest.raises(ValueError):
        encode_packet(125, bytes(70_000))
    with pytest.raises(ValueError):
        PacketDecoder(max_payload=-1)


def test_md5_sums_are_the_published_ones() -> None:
    assert rp.md5sum(rp.TOPIC_INFO) == "0ad51f88fc44892f8c10684077646005"
    assert rp.md5sum(rp.LOG) == "11abd731c25933261cd6183bd12d6295"
    assert rp.md5sum(rp.TIME) == "cd7166c74c552c311fbcc2fe5a7bc289"
    assert rp.md5sum("geometry_msgs/msg/Vector3") == "4a842b65f413084dc2b10fb484ea7f17"
    assert rp.md5sum(rp.TF_MESSAGE) == "94810edda583a504dfda3829e70d7eec"


def test_type_names_between_rosserial_and_rosbags() -> None:
    assert rp.store_name("geometry_msgs/Vector3") == "geometry_msgs/msg/Vector3"
    assert rp.store_name("geometry_msgs/msg/Vector3") == "geometry_msgs/msg/Vector3"
    assert rp.store_name("Vector3") is None and rp.store_name("a//b") is None and rp.store_name("/x") is None
    assert rp.wire_name("geometry_msgs/msg/Vector3") == "geometry_msgs/Vector3"


def test_topic_info_is_laid_out_as_ros_lib_serialises_it() -> None:
    info = rp.topic_info(126, "imu_data", "geometry_msgs/msg/Vector3", 280)
    data = rp.serialize(info)

    def string(text: str) -> bytes:
        return struct.pack("<I", len(text)) + text.encode()

    expected = (
        struct.pack("<H", 126)
        + string("imu_data")
        + string("geometry_msgs/Vector3")
        + string("4a842b65f413084dc2b10fb484ea7f17")
        + struct.pack("<i", 280)
    )
    assert data == expected
    back = rp.deserialize(data, rp.TOPIC_INFO)
    assert (back.topic_id, back.topic_name, back.message_type, back.buffer_size) == (
        126,
        "imu_data",
        "geometry_msgs/Vector3",
        280,
    )


def test_time_log_and_parameter_messages() -> None:
    data = rp.serialize(rp.time_message(1_700_000_123.25))
    assert data == struct.pack("<II", 1_700_000_123, 250_000_000)
    assert rp.time_seconds(rp.deserialize(data, rp.TIME)) == pytest.approx(1_700_000_123.25)
    assert rp.serialize(rp.time_message(float("nan"))) == bytes(8)
    log = rp.deserialize(rp.serialize(rp.log_message(rp.WARN, "low battery")), rp.LOG)
    assert (log.level, log.msg) == (rp.WARN, "low battery")
    answer = rp.deserialize(rp.serialize(rp.param_response([0.5, 1.5])), rp.PARAM_RESPONSE)
    assert list(answer.floats) == [0.5, 1.5] and len(answer.ints) == 0 and answer.strings == []
    assert list(rp.param_response([True, 3]).ints) == [1, 3]
    assert isinstance(rp.param_response(["a"]).floats, np.ndarray)


packets_strategy = st.lists(
    st.tuples(st.integers(0, 0xFFFF), st.binary(max_size=300)),
    max_size=12,
)


@settings(max_examples=150, deadline=None)
@given(packets=packets_strategy, cuts=st.lists(st.integers(0, 4000), max_size=20))
def test_packets_round_trip_however_the_bytes_are_split(packets: list[tuple[int, bytes]], cuts: list[int]) -> None:
    stream = b"".join(encode_packet(topic, payload) for topic, payload in packets)
    decoder = PacketDecoder()
    got = feed_all(decoder, stream, [c for c in cuts if c < len(stream)])
    assert [(p.topic_id, p.payload) for p in got] == packets
    assert decoder.bad == Counter() and decoder.buffered == 0
    assert decoder.ok == Counter(rp.kind_of(topic) for topic, _ in packets)


GOOD_A = encode_packet(125, b"first packet")
GOOD_B = encode_packet(126, bytes(range(24)))
GOOD_C = encode_packet(rp.ID_TIME, bytes(8))


def lying(packet: bytes, extra: int) -> bytes:
    """``packet`` whose length field (with a valid checksum) claims ``extra`` more bytes."""
    claimed = len(packet) - OVERHEAD + extra
    low, high = claimed & 0xFF, claimed >> 8
    return packet[:2] + bytes((low, high, 255 - (low + high) % 256)) + packet[5:]


def corrupt(packet: bytes, index: int) -> bytes:
    return packet[:index] + bytes(((packet[index] + 1) % 256,)) + packet[index + 1 :]


BAD_CASES = {
    "garbage": (b"boot text\r\n\x00\x17" + GOOD_A, {"garbage": 1}),
    "a 0xff of noise": (b"\xff\x00\xff" + GOOD_A, {"garbage": 1}),
    "noise right before a sync": (b"\xff" + GOOD_A, {"garbage": 1}),
    "bad length checksum": (corrupt(GOOD_B, 4) + GOOD_A, {"length_checksum": 1}),
    "bad checksum": (corrupt(GOOD_B, len(GOOD_B) - 1) + GOOD_A, {"checksum": 1}),
    "a payload byte flipped": (corrupt(GOOD_B, 10) + GOOD_A, {"checksum": 1}),
    "a lying length swallows good packets": (lying(GOOD_B, 30) + GOOD_A + GOOD_C, {"checksum": 1}),
    "a cut packet": (GOOD_B[:15] + GOOD_A + GOOD_C, {"checksum": 1}),
    "a groovy device": (groovy_frame(125, b"old") + GOOD_A, {"protocol_version": 1}),
    "a future version": (encode_packet(125, b"new", version=rp.PROTOCOL_FUTURE) + GOOD_A, {"protocol_version": 1}),
    "oversize": (encode_packet(125, bytes(200)) + GOOD_A, {"oversize": 1}),
    "garbage then a bad checksum": (
        b"noise" + corrupt(GOOD_B, len(GOOD_B) - 1) + GOOD_A,
        {"garbage": 1, "checksum": 1},
    ),
}


@pytest.mark.parametrize("case", BAD_CASES)
def test_each_bad_case_is_dropped_and_counted_once(case: str) -> None:
    stream, expected = BAD_CASES[case]
    good = [p for p in (GOOD_A, GOOD_C) if p in stream and not stream.startswith(p)]
    tail = b"".join(good)
    for cuts in ([], list(range(len(stream))), [7, 19]):  # whole, byte by byte, a few pieces
        decoder = PacketDecoder(max_payload=128)
        packets = feed_all(decoder, stream, cuts)
        assert b"".join(encode_packet(p.topic_id, p.payload) for p in packets) == tail, cuts
        assert decoder.bad == Counter(expected), cuts
        assert decoder.buffered == 0


def test_a_lying_length_holds_back_only_until_it_is_disproved() -> None:
    decoder = PacketDecoder(max_payload=128)
    assert decoder.feed(lying(GOOD_B, 100) + GOOD_A) == []  # it may still be true
    assert decoder.buffered == len(GOOD_B) + len(GOOD_A)
    assert decoder.feed(GOOD_C * 4) == []  # 116 bytes of the 132 it claims
    packets = decoder.feed(GOOD_C * 2)  # enough to disprove it
    assert [p.topic_id for p in packets] == [125] + [rp.ID_TIME] * 6
    assert decoder.bad == Counter({"checksum": 1})


def test_resync_forgets_a_partial_packet() -> None:
    decoder = PacketDecoder()
    assert decoder.feed(GOOD_A[:9]) == []
    decoder.resync()
    assert decoder.buffered == 0
    assert decoder.feed(GOOD_A[9:] + GOOD_B) == [Packet(126, bytes(range(24)))]
    assert decoder.bad == Counter({"garbage": 1})


def test_memory_stays_bounded_whatever_comes() -> None:
    """Random bytes and headers that pass their length checksum and claim the most they may:
    the decoder never holds more than one candidate packet, and finds the packet at the end."""
    rng = random.Random(5)
    decoder = PacketDecoder(max_payload=512)
    limit = OVERHEAD + decoder.max_payload
    header = b"\xff\xfe\x00\x02\xfd"  # 512 bytes, a valid length checksum
    sent = 0
    while sent < 3_000_000:
        roll = rng.random()
        if roll < 0.4:
            chunk = rng.randbytes(rng.randint(1, 4096))
        elif roll < 0.7:
            chunk = header + rng.randbytes(rng.randint(0, 600))
        else:
            chunk = b"\xff\xfe" * rng.randint(1, 300)
        decoder.feed(chunk)
        sent += len(chunk)
        assert decoder.buffered <= limit
    assert decoder.bad["garbage"] > 0 and decoder.bad["checksum"] > 0
    found = decoder.feed(bytes(600) + GOOD_A)
    assert found[-1] == Packet(125, b"first packet")


def test_fuzz_every_packet_among_noise_is_found() -> None:
    """Packets between stretches of noise without a 0xff byte: every packet is found and every
    stretch counted once, whatever the split; with noise of any bytes, nearly every packet."""
    rng = random.Random(11)
    for noise_of_any_bytes in (False, True):
        chunks, packets, stretches = [], [], 0
        for _ in range(3000):
            if rng.random() < 0.4:
                noise = rng.randbytes(rng.randint(1, 80))
                if not noise_of_any_bytes:
                    noise = noise.replace(b"\xff", b"\x00")
                chunks.append(noise)
                stretches += not chunks[-2:-1] or chunks[-2] in packets
            else:
                packet = encode_packet(rng.randint(100, 200), rng.randbytes(rng.randint(0, 60)))
                chunks.append(packet)
                packets.append(packet)
        stream = b"".join(chunks)
        decoder = PacketDecoder(max_payload=64)
        found = feed_all(decoder, stream, sorted(rng.sample(range(len(stream)), 500)))
        framed = [encode_packet(p.topic_id, p.payload) for p in found]
        if noise_of_any_bytes:
            assert len(set(packets) - set(framed)) <= len(packets) // 100
        else:
            assert framed == packets
            assert decoder.bad == Counter({"garbage": stretches})
