"""The Launchpad's line protocol: parsing, framing, wrap-around, commands, and fuzzing."""

from __future__ import annotations

import math
import random

import pytest

from botstage.robots.drivers.launchpad_protocol import (
    BadLine,
    BatteryVolts,
    BoardTime,
    CommandDecoder,
    Encoders,
    LineDecoder,
    MotorSpeeds,
    Quaternion,
    Ultrasonic,
    micros_delta,
    parse_line,
    speed_command,
    wrap_delta,
)

VALID = [
    b"t\t1234567\t0.020000",
    b"e\t-1200\t2147483647",
    b"u\t87",
    b"s\t120\t-35",
    b"i\t0.0000\t0.0000\t0.3827\t0.9239",
    b"b\t12.47",
]


def test_each_line_of_the_firmware_parses() -> None:
    assert [parse_line(line) for line in VALID] == [
        BoardTime(1234567, 0.02),
        Encoders(-1200, 2147483647),
        Ultrasonic(87.0),
        MotorSpeeds(120.0, -35.0),
        Quaternion(0.0, 0.0, 0.3827, 0.9239),
        BatteryVolts(12.47),
    ]
    assert parse_line(b"i\t0.0000\t0.0000\t0.3827\t0.9239").yaw == pytest.approx(math.pi / 4, abs=1e-4)
    # println's \r, a trailing tab, spaces instead of tabs: all the firmware's habits
    assert parse_line(b"e\t5\t6\t\r") == Encoders(5, 6)
    assert parse_line(b"e 5  6") == Encoders(5, 6)


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        (b"", "empty"),
        (b"x\t1\t2", "unknown_tag"),
        (b"Encoder:\t1\t2", "unknown_tag"),
        (b"e\t1", "field_count"),
        (b"e\t1\t2\t3", "field_count"),
        (b"e\t1.5\t2", "not_a_number"),
        (b"e\t1_000\t2", "not_a_number"),
        (b"e\t2147483648\t0", "out_of_range"),  # beyond a 32-bit long
        (b"b\tnan", "not_a_number"),
        (b"b\tinf", "not_a_number"),
        (b"b\t-3", "out_of_range"),
        (b"i\t0\t0\t0\t0", "out_of_range"),  # not a unit quaternion
        (b"t\t-5\t0.02", "out_of_range"),  # micros() is unsigned
        (b"u\tfar", "not_a_number"),
    ],
)
def test_bad_lines_say_why(line: bytes, reason: str) -> None:
    with pytest.raises(BadLine) as info:
        parse_line(line)
    assert info.value.reason == reason


def test_partial_lines_wait_for_their_end_in_any_chunking() -> None:
    stream = b"".join(line + b"\n" for line in VALID) * 20
    for size in (1, 2, 3, 7, 64, len(stream)):
        decoder = LineDecoder()
        messages = []
        for i in range(0, len(stream), size):
            messages += decoder.feed(stream[i : i + size])
        assert len(messages) == 120 and decoder.lines_bad == 0, size
        assert messages[:6] == [parse_line(line) for line in VALID]


def test_garbage_overlong_runs_and_cut_lines_are_dropped_and_counted() -> None:
    decoder = LineDecoder(max_line=96)
    got = decoder.feed(b"\x00\xff\xfe junk\ne\t1\t2\n" + b"A" * 500)
    got += decoder.feed(b"AAAA still the same long line\nb\t12.1\n")
    assert got == [Encoders(1, 2), BatteryVolts(12.1)]
    assert decoder.bad == {"unknown_tag": 1, "too_long": 1}
    decoder.resync()  # a reconnection: the first line may start mid-way
    assert decoder.feed(b"\t2147483\t-7\ne\t3\t4\n") == [Encoders(3, 4)]
    assert decoder.bad["cut"] == 1
    decoder.resync()  # and when it starts at a line's beginning, it is kept
    assert decoder.feed(b"u\t12\n") == [Ultrasonic(12.0)]


def test_encoder_steps_are_exact_across_the_32_bit_wrap() -> None:
    top, bottom = 2**31 - 1, -(2**31)
    assert wrap_delta(bottom, top) == 1
    assert wrap_delta(top, bottom) == -1
    assert wrap_delta(bottom + 99, top - 100) == 200
    assert wrap_delta(-5, 7) == -12
    assert wrap_delta(-32768, 32767, bits=16) == 1  # boards with 16-bit counters (diff_tf's default)
    assert micros_delta(5, 2**32 - 10) == 15


def test_commands_are_the_firmwares_and_are_clamped() -> None:
    assert speed_command(120, -35) == b"s 120 -35\r"
    assert speed_command(900, -900) == b"s 255 -255\r"
    decoder = CommandDecoder()
    commands = decoder.feed(b"s 120 -35\rr\rs 1")
    commands += decoder.feed(b"0 20\rbogus\rs x y\r\n")
    assert [(c.kind, c.left, c.right) for c in commands] == [("s", 120, -35), ("r", 0, 0), ("s", 10, 20)]
    assert decoder.bad == 2


def mutate(line: bytes, rng: random.Random) -> bytes:
    data = bytearray(line)
    for _ in range(rng.randint(1, 3)):
        kind = rng.randrange(4)
        at = rng.randrange(len(data) + 1)
        if kind == 0 and data:
            del data[min(at, len(data) - 1)]
        elif kind == 1:
            data.insert(at, rng.randrange(256))
        elif kind == 2 and data:
            data[min(at, len(data) - 1)] = rng.randrange(256)
        else:
            data[at:at] = rng.choice([b"\t", b"-", b".", b"e", b"nan", b"9" * 12])
    return bytes(data).replace(b"\n", b"")


def test_fuzz_a_megabyte_of_random_bytes_never_raises() -> None:
    rng = random.Random(8)
    decoder = LineDecoder()
    blob = rng.randbytes(1_000_000)
    for i in range(0, len(blob), 4096):
        decoder.feed(blob[i : i + 4096])
    assert decoder.lines_bad > 0


def test_fuzz_valid_lines_survive_among_a_megabyte_of_mutated_ones() -> None:
    """Valid lines interleaved with mutated lines and random bytes: every valid line still
    parses (a mutated line may happen to be valid too, so at least as many as were sent)."""
    rng = random.Random(9)
    chunks, valid, size = [], 0, 0
    while size < 1_000_000:
        if rng.random() < 0.4:
            piece = rng.choice(VALID) + b"\n"
            valid += 1
        elif rng.random() < 0.8:
            piece = mutate(rng.choice(VALID), rng) + b"\n"
        else:
            piece = rng.randbytes(rng.randint(1, 200)).replace(b"\n", b"") + b"\n"
        chunks.append(piece)
        size += len(piece)
    stream = b"".join(chunks)
    decoder = LineDecoder()
    messages = []
    for i in range(0, len(stream), 1000):
        messages += decoder.feed(stream[i : i + 1000])
    assert valid > 10_000
    assert valid <= len(messages) <= valid * 1.2
    assert decoder.lines_ok + decoder.lines_bad == len(chunks)
