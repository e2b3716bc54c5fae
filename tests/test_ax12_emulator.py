"""The emulated AX-12A on a real pty, spoken to in raw protocol 1.0 packets through pyserial.

Replies are read packet by packet with a failsafe deadline; "no reply" is shown by the next
instruction's reply arriving first. Motion is judged on the emulator's own injectable clock,
stepped by the test: one step, one pass of its loop, never the wall clock.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from botstage.robots.ax12 import RAD_PER_UNIT
from botstage.robots.drivers.dynamixel_servo import (
    ACTION,
    ADDR_CCW_LIMIT,
    ADDR_CW_LIMIT,
    ADDR_GOAL,
    ADDR_ID,
    ADDR_MOVING,
    ADDR_PRESENT_POSITION,
    ADDR_PRESENT_SPEED,
    ADDR_PRESENT_TEMPERATURE,
    ADDR_REGISTERED,
    ADDR_SPEED,
    ADDR_STATUS_RETURN,
    ADDR_TORQUE_ENABLE,
    ADDR_TORQUE_LIMIT,
    BROADCAST_ID,
    PING,
    READ,
    REG_WRITE,
    RESET,
    SYNC_WRITE,
    WRITE,
    checksum,
)
from botstage.robots.emulators.ax12 import (
    DEFAULT_TABLE,
    MAX_DROP,
    MAX_GARBAGE,
    MAX_UNPLUG_S,
    Ax12Emulator,
    status_packet,
)
from tests.launchpad_helpers import FAILSAFE_S, wait_until

ANGLE, RANGE, CHECKSUM, INSTRUCTION = 0x02, 0x08, 0x10, 0x40
VOLTAGE, OVERHEATING, OVERLOAD = 0x01, 0x04, 0x20


def packet(dxl_id: int, instruction: int, *params: int) -> bytes:
    body = bytes([dxl_id, len(params) + 2, instruction, *params])
    return b"\xff\xff" + body + bytes([checksum(body)])


def write(address: int, value: int, size: int = 2, dxl_id: int = 1) -> bytes:
    return packet(dxl_id, WRITE, address, *value.to_bytes(size, "little"))


def read(address: int, length: int, dxl_id: int = 1) -> bytes:
    return packet(dxl_id, READ, address, length)


class Host:
    """The controller's end: pyserial at 1 Mbps, reading whole status packets."""

    def __init__(self, path: str, baud: int = 1_000_000) -> None:
        self.port = serial.Serial(path, baud, timeout=0.02)
        self.pending = b""

    def send(self, data: bytes) -> None:
        self.port.write(data)

    def raw_packet(self) -> bytes:
        """The next packet as received (header-synchronised, whole by its length byte)."""
        deadline = time.monotonic() + FAILSAFE_S
        while True:
            start = self.pending.find(b"\xff\xff")
            if start >= 0 and len(self.pending) >= start + 4:
                end = start + 4 + self.pending[start + 3]
                if len(self.pending) >= end:
                    found, self.pending = self.pending[start:end], self.pending[end:]
                    return found
            assert time.monotonic() < deadline, f"no whole packet; got {self.pending.hex(' ')}"
            self.pending += self.port.read(max(1, self.port.in_waiting))

    def status(self) -> tuple[int, int, bytes]:
        """The next status packet, checked: (id, error, parameters)."""
        raw = self.raw_packet()
        assert checksum(raw[2:-1]) == raw[-1], f"bad checksum in {raw.hex(' ')}"
        return raw[2], raw[4], raw[5:-1]

    def ask(self, instruction: bytes) -> tuple[int, bytes]:
        self.send(instruction)
        dxl_id, error, params = self.status()
        assert dxl_id == instruction[2]
        return error, params

    def word(self, address: int) -> int:
        error, data = self.ask(read(address, 2))
        assert error == 0
        return int.from_bytes(data, "little")

    def nothing_before_ping(self, dxl_id: int = 1) -> None:
        """What was sent before got no reply: the ping's reply is the next packet."""
        assert self.ask(packet(dxl_id, PING)) == (0, b"")
        assert self.pending == b""

    def exactly(self, count: int) -> bytes:
        """The next ``count`` bytes as received, whatever they are."""
        deadline = time.monotonic() + FAILSAFE_S
        while len(self.pending) < count:
            assert time.monotonic() < deadline, f"{len(self.pending)} of {count} bytes: {self.pending.hex(' ')}"
            self.pending += self.port.read(max(1, self.port.in_waiting))
        found, self.pending = self.pending[:count], self.pending[count:]
        return found

    def close(self) -> None:
        self.port.close()


class Clock:
    """The emulator's ``monotonic``: it stands still until the test moves it."""

    def __init__(self) -> None:
        self.now = 500.0

    def __call__(self) -> float:
        return self.now


def step(board: Ax12Emulator, clock: Clock, dt: float = 0.1) -> None:
    """Move the emulator's clock by ``dt`` and wait for the one loop pass that follows."""
    loops = board.loops
    clock.now += dt
    assert wait_until(lambda: board.loops > loops)


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Ax12Emulator]:
    with Ax12Emulator(link_dir=tmp_path) as made:
        yield made


@pytest.fixture
def host(board: Ax12Emulator) -> Iterator[Host]:
    made = Host(board.path)
    yield made
    made.close()


@pytest.fixture
def stepped(tmp_path: Path) -> Iterator[tuple[Ax12Emulator, Clock, Host]]:
    clock = Clock()
    with Ax12Emulator(link_dir=tmp_path, monotonic=clock) as made:
        link = Host(made.path)
        yield made, clock, link
        link.close()


# -- the control table --------------------------------------------------------------------


def test_the_e_manuals_ping_and_read_examples_byte_for_byte(host: Host) -> None:
    host.send(bytes.fromhex("FF FF 01 02 01 FB"))
    assert host.raw_packet() == bytes.fromhex("FF FF 01 02 00 FC")
    host.send(bytes.fromhex("FF FF 01 04 02 2B 01 CC"))  # present temperature
    assert host.raw_packet() == bytes.fromhex("FF FF 01 03 00 20 DB")  # 32 °C
    assert packet(1, READ, ADDR_PRESENT_TEMPERATURE, 1) == bytes.fromhex("FF FF 01 04 02 2B 01 CC")


def test_the_whole_table_holds_an_ax12a_s_defaults(host: Host) -> None:
    error, table = host.ask(read(0, 50))
    assert error == 0 and len(table) == 50

    def word(address: int) -> int:
        return table[address] | table[address + 1] << 8

    assert word(0) == 12 and table[3] == 1 and table[4] == 1 and table[5] == 250  # model, ID, 1 Mbps, 500 µs
    assert word(ADDR_CW_LIMIT) == 0 and word(ADDR_CCW_LIMIT) == 1023
    assert (table[11], table[12], table[13], word(14)) == (70, 60, 140, 1023)
    assert (table[16], table[17], table[18]) == (2, 36, 36)
    assert (table[ADDR_TORQUE_ENABLE], table[25], table[26], table[27], table[28], table[29]) == (0, 0, 1, 1, 32, 32)
    assert word(ADDR_GOAL) == word(ADDR_PRESENT_POSITION) == 512 and word(ADDR_SPEED) == 0
    assert word(ADDR_TORQUE_LIMIT) == 1023 and word(ADDR_PRESENT_SPEED) == 0
    assert table[42] == 120 and table[43] == 32 and table[ADDR_REGISTERED] == 0 and table[ADDR_MOVING] == 0
    assert table[47] == 0 and word(48) == 32
    assert bytes(table[:24]) == DEFAULT_TABLE[:24]  # the EEPROM area is the factory's
    assert host.ask(read(45, 6)) == (RANGE, b"")  # beyond the 50 bytes
    assert host.ask(read(10, 0)) == (RANGE, b"")


def test_writes_are_checked_as_the_firmware_checks_them(board: Ax12Emulator, host: Host) -> None:
    assert host.ask(write(ADDR_CW_LIMIT, 316)) == (0, b"")
    assert host.ask(write(ADDR_CCW_LIMIT, 708)) == (0, b"")
    assert host.ask(write(ADDR_GOAL, 800)) == (ANGLE, b"")  # beyond the CCW limit: refused
    assert host.ask(write(ADDR_GOAL, 200)) == (ANGLE, b"")
    assert host.word(ADDR_GOAL) == 512 and not board.torque_enabled
    assert host.ask(write(ADDR_PRESENT_POSITION, 600)) == (RANGE, b"")  # read-only
    assert host.ask(write(0, 18)) == (RANGE, b"")  # the model number
    assert host.ask(write(10, 1, size=1)) == (RANGE, b"")  # reserved
    assert host.ask(write(ADDR_GOAL, 0x02, size=1)) == (RANGE, b"")  # half of a 2-byte item
    assert host.ask(write(ADDR_SPEED, 2000)) == (RANGE, b"")  # beyond 1023
    assert host.ask(write(ADDR_STATUS_RETURN, 3, size=1)) == (RANGE, b"")
    assert host.ask(packet(1, WRITE, 49, 1, 1)) == (RANGE, b"")  # past the table's end
    assert host.ask(packet(1, WRITE, ADDR_GOAL)) == (INSTRUCTION, b"")  # no data
    assert host.word(ADDR_GOAL) == 512 and board.counters["angle_limit_errors"] == 2
    assert board.counters["range_errors"] == 7
    # a packet with one bad item writes nothing
    assert host.ask(packet(1, WRITE, ADDR_GOAL, 0x58, 0x02, 0xFF, 0x07)) == (RANGE, b"")  # goal 600, speed 2047
    assert host.word(ADDR_GOAL) == 512
    # goal and speed in one packet; either turns the torque on (the AX's habit)
    assert host.ask(packet(1, WRITE, ADDR_GOAL, 0x58, 0x02, 100, 0)) == (0, b"")
    assert host.word(ADDR_GOAL) == 600 and host.word(ADDR_SPEED) == 100 and board.torque_enabled
    # Lock: 1 only, and then the EEPROM refuses writes
    assert host.ask(write(47, 0, size=1)) == (RANGE, b"")
    assert host.ask(write(47, 1, size=1)) == (0, b"")
    assert host.ask(write(ADDR_CW_LIMIT, 300)) == (RANGE, b"")
    assert host.ask(write(ADDR_TORQUE_LIMIT, 512)) == (0, b"")  # the RAM still takes them


def test_a_wrong_checksum_is_answered_with_the_checksum_bit_and_not_executed(board: Ax12Emulator, host: Host) -> None:
    damaged = bytearray(write(ADDR_GOAL, 600))
    damaged[-1] ^= 0x5A
    host.send(bytes(damaged))
    assert host.status() == (1, CHECKSUM, b"")
    assert host.word(ADDR_GOAL) == 512 and board.counters["checksum_errors"] == 1


def test_unknown_instructions_and_a_lone_action_get_the_instruction_bit(board: Ax12Emulator, host: Host) -> None:
    assert host.ask(packet(1, 0x92, 0, 2, 1, 36)) == (INSTRUCTION, b"")  # bulk read: MX only
    assert host.ask(packet(1, 0x07)) == (INSTRUCTION, b"")
    assert host.ask(packet(1, ACTION)) == (INSTRUCTION, b"")  # nothing registered
    assert host.ask(packet(1, PING, 0)) == (INSTRUCTION, b"")  # a ping takes no parameter
    assert board.counters["instruction_errors"] == 4 and board.counters["instruction_unknown"] == 2


def test_reg_write_waits_for_action(board: Ax12Emulator, host: Host) -> None:
    assert packet(1, REG_WRITE, ADDR_GOAL, 0xF4, 0x01) == bytes.fromhex("FF FF 01 05 04 1E F4 01 E2")  # e-manual
    assert host.ask(packet(1, REG_WRITE, ADDR_GOAL, 0xF4, 0x01)) == (0, b"")
    assert host.ask(read(ADDR_REGISTERED, 1)) == (0, b"\x01")
    assert host.word(ADDR_GOAL) == 512
    assert host.ask(packet(1, ACTION)) == (0, b"")
    assert host.word(ADDR_GOAL) == 500 and host.ask(read(ADDR_REGISTERED, 1)) == (0, b"\x00")
    assert host.ask(packet(1, REG_WRITE, ADDR_PRESENT_POSITION, 0, 0)) == (RANGE, b"")  # checked when registered
    host.send(packet(BROADCAST_ID, REG_WRITE, ADDR_GOAL, 0x20, 0x02))
    host.send(packet(BROADCAST_ID, ACTION))  # the e-manual's broadcast action
    host.nothing_before_ping()
    assert board.goal == 544


def test_sync_write_the_e_manuals_example_and_no_reply(board: Ax12Emulator, host: Host) -> None:
    example = bytes.fromhex("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
    assert example == packet(BROADCAST_ID, SYNC_WRITE, 0x1E, 4, 0, 0x10, 0, 0x50, 1, 1, 0x20, 2, 0x60, 3)
    host.send(example)
    host.nothing_before_ping()
    assert host.word(ADDR_GOAL) == 0x220 and host.word(ADDR_SPEED) == 0x360  # ID 1's share
    host.send(packet(BROADCAST_ID, SYNC_WRITE, 0x1E, 2, 1, 0x10))  # a short share
    host.nothing_before_ping()
    assert board.counters["bad_packets"] == 1 and board.goal == 0x220


def test_broadcast_and_other_ids_get_no_reply(board: Ax12Emulator, host: Host) -> None:
    host.send(write(ADDR_GOAL, 520, dxl_id=BROADCAST_ID))
    host.send(packet(BROADCAST_ID, PING))
    host.send(read(ADDR_GOAL, 2, dxl_id=BROADCAST_ID))
    host.send(packet(7, PING))
    host.nothing_before_ping()
    assert board.goal == 520 and board.counters["other_ids"] == 1 and board.counters["instruction_ping"] == 2


def test_status_return_level(board: Ax12Emulator, host: Host) -> None:
    host.send(write(ADDR_STATUS_RETURN, 1, size=1))  # judged after it runs: not answered
    host.send(write(ADDR_GOAL, 530))
    assert host.ask(read(ADDR_GOAL, 2)) == (0, (530).to_bytes(2, "little"))
    host.send(write(ADDR_STATUS_RETURN, 0, size=1))
    host.send(read(ADDR_GOAL, 2))
    host.nothing_before_ping()  # ping is always answered
    assert board.counters["replies_withheld"] == 4


def test_id_baud_and_factory_reset(board: Ax12Emulator, host: Host) -> None:
    assert host.ask(write(ADDR_ID, 5, size=1)) == (0, b"")  # answered by the ID it was sent to
    host.nothing_before_ping(5)
    host.send(write(ADDR_CW_LIMIT, 316))  # to ID 1: nobody
    assert host.ask(write(ADDR_CW_LIMIT, 316, dxl_id=5)) == (0, b"")
    assert board.counters["other_ids"] == 1
    assert host.ask(packet(5, RESET)) == (0, b"")
    host.nothing_before_ping(1)
    assert host.word(ADDR_CW_LIMIT) == 0 and board.counters["factory_resets"] == 1
    assert host.ask(write(4, 34, size=1)) == (0, b"")  # 57600 bps, after the reply
    host.send(packet(1, PING))
    assert wait_until(lambda: board.counters["bytes_misframed"] >= 6)
    assert board.baud == pytest.approx(57142.86, rel=1e-4)
    slow = Host(board.path, 57600)  # within 3 %
    try:
        assert slow.ask(packet(1, PING)) == (0, b"")
    finally:
        slow.close()


def test_a_host_at_the_wrong_speed_is_not_heard(board: Ax12Emulator) -> None:
    slow = Host(board.path, 57600)
    try:
        slow.send(packet(1, PING))
        assert wait_until(lambda: board.counters["bytes_misframed"] == 6)
        assert board.counters["replies"] == 0
    finally:
        slow.close()


# -- the shaft, on the emulator's clock -----------------------------------------------------


def test_the_shaft_moves_at_the_moving_speed(stepped: tuple[Ax12Emulator, Clock, Host]) -> None:
    board, clock, host = stepped
    assert host.ask(write(ADDR_SPEED, 100)) == (0, b"")  # 11.1 rpm: 227.3 units/s
    assert host.ask(write(ADDR_GOAL, 612)) == (0, b"")
    assert board.torque_enabled
    step(board, clock)
    assert host.word(ADDR_PRESENT_POSITION) == 535  # 512 + 22.7
    assert host.word(ADDR_PRESENT_SPEED) == 100 and host.ask(read(ADDR_MOVING, 1)) == (0, b"\x01")
    assert board.angle == pytest.approx(22.7328 * RAD_PER_UNIT, rel=1e-4) and board.angle > 0  # CCW: positive
    steps = 1
    while board.moving:
        step(board, clock)
        steps += 1
    assert steps == 5 and board.position == 612  # 100 units at 22.7 a step
    step(board, clock)
    assert host.word(ADDR_PRESENT_SPEED) == 0 and host.ask(read(ADDR_MOVING, 1)) == (0, b"\x00")
    # 0 is the motor's maximum, 59 rpm at 12 V (1208 units/s); 1023 (114 rpm) asks for more than it has
    for speed in (0, 1023):
        start = board.position
        target = 412 if start > 512 else 612
        assert host.ask(write(ADDR_SPEED, speed)) == (0, b"")
        assert host.ask(write(ADDR_GOAL, target)) == (0, b"")
        step(board, clock)
        moved = board.position - start
        assert abs(moved) == 121  # 120.8 units in 0.1 s
        expected = 532 | (0x400 if moved < 0 else 0)  # 59 rpm / 0.111; bit 10: clockwise
        assert host.word(ADDR_PRESENT_SPEED) == expected
        step(board, clock)
        assert board.position == target and not board.moving


def test_torque_off_does_not_move_and_can_be_back_driven(stepped: tuple[Ax12Emulator, Clock, Host]) -> None:
    board, clock, host = stepped
    board.push(700)
    step(board, clock)
    assert host.word(ADDR_PRESENT_POSITION) == 700 and host.word(ADDR_GOAL) == 700  # the goal follows the hand
    assert host.ask(read(ADDR_MOVING, 1)) == (0, b"\x00")
    assert board.angle == pytest.approx(188 * RAD_PER_UNIT)
    assert host.ask(write(ADDR_TORQUE_ENABLE, 1, size=1)) == (0, b"")
    step(board, clock)
    assert board.position == 700 and not board.moving  # no jump to an old goal
    board.push(650)  # with torque, the servo goes back
    step(board, clock)
    assert board.position == 700
    assert host.ask(write(ADDR_TORQUE_ENABLE, 0, size=1)) == (0, b"")
    board.push(300)
    step(board, clock)
    step(board, clock)
    assert board.position == 300 and board.goal == 300 and not board.moving


def test_overload_and_overheating_on_demand(stepped: tuple[Ax12Emulator, Clock, Host]) -> None:
    board, clock, host = stepped
    assert host.ask(write(ADDR_SPEED, 100)) == (0, b"")
    board.overload(True)
    assert host.ask(packet(1, PING)) == (OVERLOAD, b"")  # in every status packet while it lasts
    assert host.ask(read(ADDR_TORQUE_LIMIT, 2)) == (OVERLOAD, b"\x00\x00")  # Alarm Shutdown (36) takes the torque
    assert host.ask(write(ADDR_GOAL, 600)) == (OVERLOAD, b"")
    step(board, clock)
    assert board.position == 512 and board.alarm and board.counters["shutdowns"] == 1
    board.overload(False)
    assert host.ask(packet(1, PING)) == (0, b"")
    step(board, clock)
    assert board.position == 512  # no torque until the host gives it back
    assert host.ask(write(ADDR_TORQUE_LIMIT, 1023)) == (0, b"")
    step(board, clock)
    assert board.position > 512
    board.set_temperature(75)  # above the 70 °C limit
    assert host.ask(read(ADDR_PRESENT_TEMPERATURE, 1)) == (OVERHEATING, b"\x4b")
    assert host.ask(read(ADDR_TORQUE_LIMIT, 2)) == (OVERHEATING, b"\x00\x00")  # in Shutdown too
    assert board.counters["shutdowns"] == 2
    board.set_temperature(40)
    assert host.ask(write(ADDR_TORQUE_LIMIT, 1023)) == (0, b"")
    board.set_voltage(15.0)  # above 14.0 V: not in Shutdown (36), the torque stays
    assert host.ask(read(ADDR_TORQUE_LIMIT, 2)) == (VOLTAGE, (1023).to_bytes(2, "little"))
    board.set_voltage(12.0)
    assert host.ask(packet(1, PING)) == (0, b"")


def test_power_cycle_starts_the_ram_over(stepped: tuple[Ax12Emulator, Clock, Host]) -> None:
    board, clock, host = stepped
    assert host.ask(write(ADDR_CW_LIMIT, 316)) == (0, b"")
    assert host.ask(write(ADDR_GOAL, 600)) == (0, b"")
    step(board, clock)
    held = board.position
    board.power_cycle()
    assert not board.torque_enabled and board.goal == held and board.word(ADDR_CW_LIMIT) == 316  # EEPROM kept
    step(board, clock)
    assert board.position == held


# -- faults -----------------------------------------------------------------------------------


def test_garbage_dropped_corrupted_and_cut_replies(board: Ax12Emulator, host: Host) -> None:
    board.inject_garbage(300)
    host.send(packet(1, PING))
    assert host.exactly(306)[-6:] == status_packet(1, 0)  # the garbage goes out before the reply
    host.nothing_before_ping()
    board.drop_replies(2)
    host.send(packet(1, PING))
    host.send(read(ADDR_GOAL, 2))
    assert wait_until(lambda: board.counters["lines_dropped"] == 2)
    host.nothing_before_ping()
    board.corrupt_replies(1)
    host.send(packet(1, PING))
    raw = host.raw_packet()
    assert raw[:5] == bytes.fromhex("FF FF 01 02 00") and raw[5] != checksum(raw[2:5])
    board.cut_replies(1)
    host.send(read(ADDR_GOAL, 2))
    host.send(packet(1, PING))
    assert host.exactly(10) == status_packet(1, 0, b"\x00\x02")[:4] + status_packet(1, 0)  # half, then the ping's
    assert board.counters["replies_cut"] == 1 and board.counters["replies_corrupted"] == 1


def test_host_garbage_and_cut_packets(stepped: tuple[Ax12Emulator, Clock, Host]) -> None:
    board, clock, host = stepped
    host.send(bytes([0x00, 0x13, 0xFF, 0x42, 0x99]) + packet(1, PING))
    assert host.status() == (1, 0, b"")
    assert board.counters["bytes_skipped"] == 5
    host.send(read(ADDR_GOAL, 2)[:5])  # cut: the rest never comes
    assert wait_until(lambda: board.counters["bytes_received"] == 16)
    host.send(packet(1, PING))  # at once: read as the cut packet's rest, a checksum error
    assert host.status() == (1, CHECKSUM, b"")
    host.send(read(ADDR_GOAL, 2)[:5])
    assert wait_until(lambda: board.counters["bytes_received"] == 27)
    clock.now += 1.0  # longer than a packet may take
    host.nothing_before_ping()
    assert board.counters["packets_timed_out"] == 1
    host.send(b"\xff\xff\xff" + packet(1, PING)[2:])  # a third 0xFF before the ID
    assert host.status() == (1, 0, b"")


def test_unplug_replug_keeps_the_servos_state(board: Ax12Emulator, host: Host) -> None:
    assert host.ask(write(ADDR_GOAL, 600)) == (0, b"")
    host.close()
    board.unplug()
    assert not os.path.exists(board.path)
    board.replug()
    assert os.path.exists(board.path) and board.counters["plugs"] == 2 and board.counters["unplugs"] == 1
    again = Host(board.path)
    try:
        assert again.word(ADDR_GOAL) == 600 and board.torque_enabled  # on its own supply: nothing forgotten
        again.close()
        board.disconnect(0.05)
        assert not os.path.exists(board.path)
        assert wait_until(lambda: board.counters["plugs"] == 3 and os.path.exists(board.path))
        again = Host(board.path)
        again.nothing_before_ping()
        assert board.first_instructions == ["write", "read", "ping"]
    finally:
        again.close()


def test_fault_arguments_are_bounded(board: Ax12Emulator) -> None:
    for fault, argument in [
        (board.inject_garbage, -1),
        (board.inject_garbage, MAX_GARBAGE + 1),
        (board.drop_replies, -1),
        (board.drop_replies, MAX_DROP + 1),
        (board.corrupt_replies, -1),
        (board.corrupt_replies, MAX_DROP + 1),
        (board.cut_replies, MAX_DROP + 1),
        (board.disconnect, 0.0),
        (board.disconnect, math.nan),
        (board.disconnect, MAX_UNPLUG_S + 1),
        (board.push, -1),
        (board.push, 1024),
        (board.push, math.inf),
        (board.set_temperature, 151),
        (board.set_voltage, -0.5),
        (board.set_voltage, math.nan),
    ]:
        with pytest.raises(ValueError):
            fault(argument)
    assert os.path.exists(board.path) and board.counters["unplugs"] == 0
    options: list[dict[str, float]] = [
        {"dxl_id": 254},
        {"baud_register": 255},
        {"position": 1024},
        {"voltage": 30.0},
        {"loop_hz": 0.0},
        {"packet_timeout_s": 0.0},
        {"no_load_rpm": math.nan},
    ]
    for option in options:
        with pytest.raises(ValueError):
            Ax12Emulator(**option)  # type: ignore[arg-type]
