"""A Dynamixel AX-12A (protocol 1.0) on a pseudo-terminal: the face tracker's pan servo, shaft included.

The emulator is a ``PtyBoard`` (``pty_board.py``): the driver opens its stable path with
``dynamixel-sdk``'s ``PortHandler`` (pyserial) as it would open a USB2Dynamixel's
``/dev/ttyUSB0``. It answers instruction packets from a full control table and moves a shaft
toward the goal in real time, on its own thread.

**The control table** (50 bytes; addresses, access and initial values from the e-manual's AX-12A
page, ROBOTIS-GIT/emanual ``docs/en/dxl/ax/ax-12a.md``): EEPROM model number 12, firmware
``firmware`` (decision: 24; the e-manual gives none), ID 1, baud 1 (1 Mbps: 2 Mbps / (value + 1),
``control_table_baudrate.md``), return delay 250 (500 µs), CW/CCW angle limits 0/1023,
temperature limit 70 °C, voltage limits 60/140 (6.0/14.0 V), max torque 1023, status return level
2, alarm LED and shutdown 36 (overheating and overload); RAM torque enable 0, LED 0, compliance
margins 1, slopes 32, goal position = present position, moving speed 0 (the 2006 AX-12 manual's
initial value; the e-manual gives none), torque limit = max torque, registered 0, moving 0, lock
0, punch 32. The addresses 10, 19-23 and 45 are reserved and read as 0; present position, speed,
load, voltage (volts x 10: 120 at ``voltage=12.0``), temperature (``temperature``, 32 °C: the
e-manual's read example answers 0x20), registered and moving are read-only.

**Instructions** (``docs/en/dxl/protocol1.md``; DynamixelSDK ``robotis_def.py``): ping (1), read
(2), write (3), reg write (4), action (5), reset (6: the factory table, the reply first), sync write
(0x83). A status packet is ``FF FF id len error params checksum``; the error byte carries the
packet's own bits (angle limit, range, checksum, instruction) and the servo's conditions while
they last (input voltage outside the voltage limits, temperature above its limit, overload).

- **No reply** to the broadcast ID 254 (the e-manual says so of write, reg write, action and sync
  write and, through Status Return Level, of read; decision: nor to a broadcast ping, which the SDK
  does not offer for 1.0 either), to another ID, or when Status Return Level says so (0: ping only;
  1: ping and read; 2: all), judged after the instruction ran (decision: the write that sets 0 is
  not answered).
- **Checksum error**: a packet for this ID whose checksum is wrong is not executed and is answered
  with bit 4 (0x10) and no parameters.
- **Instruction error** (bit 6, 0x40): an unknown instruction, an action with nothing registered,
  and (decision; the manual names no bit for it) a wrong parameter count.
- **Angle limit error** (bit 1, 0x02; the SDK's ``ERRBIT_ANGLE``; the e-manual's goal position
  page says "0x01" but its own error table and the SDK say bit 1): a goal outside CW..CCW angle
  limit. Decision: the goal is not taken and the servo keeps its old one (as a user reports on
  ROBOTIS' forum of an XL430 given a goal beyond its limits: it does "nothing at all"; the e-manual
  says only that the bit is set).
- **Range error** (bit 3, 0x08): a write to a read-only or reserved address, beyond the table, to
  half of a 2-byte item, a value outside the item's range (the 2006 AX-12 manual's "data range for
  writing" table: "write instructions made outside of these valid ranges will return an error";
  Lock accepts only 1), an EEPROM write while Lock is 1; a read beyond the table answers with it
  and no data. A refused packet writes nothing (decision: no half-applied writes).
- **Side effects**: a write to goal position or moving speed turns the torque on (the AX firmware's
  habit, confirmed by Pyluos' maintainers for moving speed, Luos-io/Pyluos#59; decision: the same
  for the goal); while the torque is off, the goal follows the present position (ROBOTIS support,
  of an RX-28: after moving the horn by hand and turning the torque on "the motor did not jump"); a
  new baud or ID takes effect after the reply, which carries the ID the packet addressed.
- A condition in Alarm Shutdown sets Torque Limit to 0: the motor gives no torque (and can be
  back-driven) until the host writes a torque limit above 0 (e-manual ``control_table_torque_limit``).

**The shaft** moves toward the goal at the moving speed, 0.111 rpm a unit; 0, or any speed above it,
means the motor's maximum: the AX-12A's no-load speed, 59 rpm at 12 V (e-manual specifications;
``dynamixel_const``'s 59 rpm @ 12 V), in proportion to the voltage (as ``dynamixel_const``'s
``velocity_per_volt``). (The register's full scale, 1023 x 0.111 = 114 rpm, is beyond what an AX-12A
turns: the e-manual's note, "the motor cannot exceed the maximum rpm".) One position unit is 300° /
1024 (``dynamixel_const``'s encoder resolution and range, which the book's controller converts with);
the shaft has no inertia and no compliance (it stops on the goal). Torque off (or a torque limit of
0): it stays where it is, and ``push(position)`` back-drives it. Present speed (bit 10 set when
turning clockwise, toward lower positions), moving and present position follow the motion every
``1/loop_hz`` (decision: 100 Hz) of ``monotonic`` (injectable: a test steps it). ``angle`` is the
shaft in radians from 512, counter-clockwise positive, as ``dynamixel_controllers`` maps it
(``raw = init + angle * ticks_per_radian`` for ``min < max``; see the driver).

**The line**: a packet must be complete within ``packet_timeout_s`` of its first byte (decision:
20 ms, some 2,000 bytes at 1 Mbps) or it is dropped (a cut packet does not swallow the next one);
bytes before a header are skipped and counted. The host's port speed is read from the pty
(termios) and must be within 3 % of the baud register (the e-manual's margin): otherwise the bytes
are misframed and lost (``check_baud``). The return delay is not emulated (a pty has no bus to turn
around).

**Faults** (bounded arguments, ``ValueError`` beyond): from ``PtyBoard``, ``inject_garbage`` (random
bytes before the next reply), ``drop_lines``/``drop_replies`` (the next replies are lost),
``unplug``/``replug``/``disconnect(for_s)`` (the USB adapter goes away; the servo, on its own supply,
keeps its state and motion); here ``corrupt_replies`` (wrong checksums), ``cut_replies`` (the first
half only), ``overload(on)``, ``set_temperature``, ``set_voltage`` and ``power_cycle`` (the RAM
area starts over: torque off, goal = present); ``model`` (another servo on the bus: 18 is an AX-18A)
and ``baud_register`` for a mis-set servo. ``counters`` count all of it; ``first_instructions``
keeps the first instruction heard on each link (a driver says ``ping`` first).
"""

from __future__ import annotations

import contextlib
import math
import termios
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from botstage.robots.ax12 import CENTRE, DIRECTION_BIT, POSITION_MAX, RAD_PER_UNIT, RPM_PER_SPEED_UNIT, SPEED_MAX
from botstage.robots.drivers.dynamixel_servo import (
    ACTION,
    ADDR_ALARM_LED,
    ADDR_BAUD,
    ADDR_CCW_LIMIT,
    ADDR_CW_LIMIT,
    ADDR_FIRMWARE,
    ADDR_GOAL,
    ADDR_ID,
    ADDR_LOCK,
    ADDR_MAX_TORQUE,
    ADDR_MAX_VOLTAGE,
    ADDR_MIN_VOLTAGE,
    ADDR_MODEL_NUMBER,
    ADDR_MOVING,
    ADDR_PRESENT_LOAD,
    ADDR_PRESENT_POSITION,
    ADDR_PRESENT_SPEED,
    ADDR_PRESENT_TEMPERATURE,
    ADDR_PRESENT_VOLTAGE,
    ADDR_REGISTERED,
    ADDR_RETURN_DELAY,
    ADDR_SHUTDOWN,
    ADDR_SPEED,
    ADDR_STATUS_RETURN,
    ADDR_TEMPERATURE_LIMIT,
    ADDR_TORQUE_ENABLE,
    ADDR_TORQUE_LIMIT,
    AX12_MODEL,
    BROADCAST_ID,
    ERROR_BITS,
    INSTRUCTIONS,
    MAX_ID,
    PING,
    RAM_START,
    READ,
    REG_WRITE,
    RESET,
    SYNC_WRITE,
    TABLE_SIZE,
    WRITE,
    checksum,
)
from botstage.robots.emulators.pty_board import MAX_DROP, MAX_GARBAGE, MAX_UNPLUG_S, PtyBoard

__all__ = [
    "DEFAULT_TABLE",
    "MAX_DROP",
    "MAX_GARBAGE",
    "MAX_UNPLUG_S",
    "NO_LOAD_RPM",
    "Ax12Emulator",
    "status_packet",
]

NO_LOAD_RPM = 59.0  # at 12 V (e-manual specifications)
RATED_VOLTS = 12.0
DEGREES_PER_UNIT = 300.0 / 1024
BAUD_MARGIN = 0.03  # the e-manual: under 3 % of error does not affect UART communication
MAX_LOOP_HZ = 1000.0
MAX_VOLTS = 25.0
MAX_CELSIUS = 150

# item: (size, lowest, highest) for what a write may set; absent addresses are read-only or reserved
WRITABLE: dict[int, tuple[int, int, int]] = {
    ADDR_ID: (1, 0, MAX_ID),
    ADDR_BAUD: (1, 0, 254),
    ADDR_RETURN_DELAY: (1, 0, 254),
    ADDR_CW_LIMIT: (2, 0, POSITION_MAX),
    ADDR_CCW_LIMIT: (2, 0, POSITION_MAX),
    ADDR_TEMPERATURE_LIMIT: (1, 0, 150),
    ADDR_MIN_VOLTAGE: (1, 50, 250),
    ADDR_MAX_VOLTAGE: (1, 50, 250),
    ADDR_MAX_TORQUE: (2, 0, 1023),
    ADDR_STATUS_RETURN: (1, 0, 2),
    ADDR_ALARM_LED: (1, 0, 127),
    ADDR_SHUTDOWN: (1, 0, 127),
    ADDR_TORQUE_ENABLE: (1, 0, 1),
    25: (1, 0, 1),  # LED
    26: (1, 0, 254),  # CW compliance margin
    27: (1, 0, 254),  # CCW compliance margin
    28: (1, 1, 254),  # CW compliance slope
    29: (1, 1, 254),  # CCW compliance slope
    ADDR_GOAL: (2, 0, POSITION_MAX),
    ADDR_SPEED: (2, 0, SPEED_MAX),
    ADDR_TORQUE_LIMIT: (2, 0, 1023),
    ADDR_LOCK: (1, 1, 1),  # once locked, only a power cycle unlocks
    48: (2, 0, 1023),  # punch
}
TWO_BYTE = {address for address, (size, _, _) in WRITABLE.items() if size == 2} | {
    ADDR_MODEL_NUMBER,
    ADDR_PRESENT_POSITION,
    ADDR_PRESENT_SPEED,
    ADDR_PRESENT_LOAD,
}


def _default_table(firmware: int, position: int) -> bytearray:
    table = bytearray(TABLE_SIZE)

    def put(address: int, value: int, size: int = 1) -> None:
        table[address : address + size] = value.to_bytes(size, "little")

    put(ADDR_MODEL_NUMBER, AX12_MODEL, 2)
    put(ADDR_FIRMWARE, firmware)
    put(ADDR_ID, 1)
    put(ADDR_BAUD, 1)
    put(ADDR_RETURN_DELAY, 250)
    put(ADDR_CW_LIMIT, 0, 2)
    put(ADDR_CCW_LIMIT, 1023, 2)
    put(ADDR_TEMPERATURE_LIMIT, 70)
    put(ADDR_MIN_VOLTAGE, 60)
    put(ADDR_MAX_VOLTAGE, 140)
    put(ADDR_MAX_TORQUE, 1023, 2)
    put(ADDR_STATUS_RETURN, 2)
    put(ADDR_ALARM_LED, 36)
    put(ADDR_SHUTDOWN, 36)
    _power_on_ram(table, position)
    return table


def _power_on_ram(table: bytearray, position: int) -> None:
    """The RAM area as the servo powers up with its shaft at ``position``."""
    table[RAM_START:TABLE_SIZE] = bytes(TABLE_SIZE - RAM_START)
    table[26] = table[27] = 1  # compliance margins
    table[28] = table[29] = 32  # compliance slopes
    table[ADDR_GOAL : ADDR_GOAL + 2] = position.to_bytes(2, "little")
    table[ADDR_TORQUE_LIMIT : ADDR_TORQUE_LIMIT + 2] = table[ADDR_MAX_TORQUE : ADDR_MAX_TORQUE + 2]
    table[ADDR_PRESENT_POSITION : ADDR_PRESENT_POSITION + 2] = position.to_bytes(2, "little")
    table[48] = 32  # punch


DEFAULT_TABLE = bytes(_default_table(24, CENTRE))  # the factory table, shaft at the centre

SPEEDS = {getattr(termios, f"B{rate}"): rate for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800)} | {
    getattr(termios, f"B{rate}"): rate
    for rate in (500000, 576000, 921600, 1000000, 1152000, 2000000, 2500000, 3000000, 3500000, 4000000)
    if hasattr(termios, f"B{rate}")
}


def status_packet(dxl_id: int, error: int, params: bytes = b"") -> bytes:
    """``FF FF id len error params checksum``."""
    body = bytes([dxl_id, len(params) + 2, error]) + params
    return b"\xff\xff" + body + bytes([checksum(body)])


def _bounded(name: str, value: float, low: float, high: float, *, open_low: bool = False) -> float:
    if not (math.isfinite(value) and (low < value if open_low else low <= value) and value <= high):
        above = f"more than {low:g}" if open_low else f"at least {low:g}"
        raise ValueError(f"{name} = {value}: {above} and at most {high:g}")
    return value


@dataclass
class _Packet:
    dxl_id: int
    instruction: int
    params: bytes
    intact: bool


class Ax12Emulator(PtyBoard):
    """The servo; see the module. ``start()`` (or a ``with`` block) plugs it in and runs it."""

    def __init__(
        self,
        *,
        dxl_id: int = 1,
        baud_register: int = 1,
        model: int = AX12_MODEL,
        firmware: int = 24,
        position: float = CENTRE,
        voltage: float = RATED_VOLTS,
        temperature: int = 32,
        no_load_rpm: float = NO_LOAD_RPM,
        loop_hz: float = 100.0,
        packet_timeout_s: float = 0.02,
        check_baud: bool = True,
        link_dir: Path | None = None,
        seed: int = 0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        _bounded("dxl_id", dxl_id, 0, MAX_ID)
        _bounded("baud_register", baud_register, 0, 254)
        _bounded("model", model, 0, 0xFFFF)
        _bounded("firmware", firmware, 0, 255)
        _bounded("position", position, 0, POSITION_MAX)
        _bounded("voltage", voltage, 0, MAX_VOLTS)
        _bounded("temperature", temperature, 0, MAX_CELSIUS)
        _bounded("no_load_rpm", no_load_rpm, 0, 1000, open_low=True)
        _bounded("loop_hz", loop_hz, 0, MAX_LOOP_HZ, open_low=True)
        self.packet_timeout_s = _bounded("packet_timeout_s", packet_timeout_s, 0, 10, open_low=True)
        super().__init__(
            name="ax12", link_name="ttyDynamixel", loop_hz=loop_hz, link_dir=link_dir, seed=seed, monotonic=monotonic
        )
        self.lock = threading.Lock()
        self.no_load_rpm = no_load_rpm
        self.check_baud = check_baud
        self.firmware = firmware
        self.model = model
        self.first_instructions: list[str] = []  # the first instruction heard on each link
        self._shaft = float(position)
        self._volts = float(voltage)
        self._celsius = int(temperature)
        self._overload = False
        self._rx = bytearray()
        self._rx_started = 0.0
        self._registered: tuple[int, bytes] | None = None
        self._corrupt = 0
        self._cut = 0
        self._velocity = 0.0  # units/s over the last pass
        self.table = _default_table(firmware, round(position))
        self.table[ADDR_MODEL_NUMBER : ADDR_MODEL_NUMBER + 2] = model.to_bytes(2, "little")
        self.table[ADDR_ID] = dxl_id
        self.table[ADDR_BAUD] = baud_register
        self._update_present()

    # -- state ----------------------------------------------------------------------------------

    def word(self, address: int) -> int:
        """A 2-byte item of the control table."""
        with self.lock:
            return self._word(address)

    @property
    def dxl_id(self) -> int:
        return self.table[ADDR_ID]

    @property
    def position(self) -> int:
        """Present position (0..1023)."""
        return self.word(ADDR_PRESENT_POSITION)

    @property
    def goal(self) -> int:
        return self.word(ADDR_GOAL)

    @property
    def angle(self) -> float:
        """The shaft in radians from 512, counter-clockwise positive (dynamixel_controllers' sign)."""
        with self.lock:
            return (self._shaft - CENTRE) * RAD_PER_UNIT

    @property
    def torque_enabled(self) -> bool:
        return bool(self.table[ADDR_TORQUE_ENABLE])

    @property
    def moving(self) -> bool:
        return bool(self.table[ADDR_MOVING])

    @property
    def alarm(self) -> bool:
        """The alarm LED blinks: a condition listed in Alarm LED holds."""
        with self.lock:
            return bool(self._conditions() & self.table[ADDR_ALARM_LED])

    @property
    def baud(self) -> float:
        """The line's speed the baud register sets (bps)."""
        return 2_000_000 / (self.table[ADDR_BAUD] + 1)

    # -- faults and the world -------------------------------------------------------------------

    def push(self, position: float) -> None:
        """A hand turns the horn to ``position`` (0..1023): it stays there while the torque is off;
        with torque the servo goes back to its goal."""
        _bounded("position", position, 0, POSITION_MAX)
        with self.lock:
            self._shaft = float(position)
            self._velocity = 0.0
            self._update_present()
        self.counters["pushes"] += 1

    def overload(self, on: bool = True) -> None:
        """The load cannot be held (bit 5) while ``on``; in the default Shutdown, the torque goes."""
        with self.lock:
            self._overload = on
            self._update_present()

    def set_temperature(self, celsius: int) -> None:
        """The internal temperature (above the Temperature Limit: bit 2, overheating)."""
        _bounded("temperature", celsius, 0, MAX_CELSIUS)
        with self.lock:
            self._celsius = int(celsius)
            self._update_present()

    def set_voltage(self, volts: float) -> None:
        """The supply (outside the voltage limits: bit 0, input voltage)."""
        _bounded("voltage", volts, 0, MAX_VOLTS)
        with self.lock:
            self._volts = float(volts)
            self._update_present()

    def drop_replies(self, count: int) -> None:
        """The next ``count`` status packets are lost (at most ``MAX_DROP`` waiting)."""
        self.drop_lines(count)

    def corrupt_replies(self, count: int) -> None:
        """The next ``count`` status packets go out with a wrong checksum."""
        with self.lock:
            if not 0 <= count <= MAX_DROP - self._corrupt:
                raise ValueError(f"corrupting {count} replies: 0 to {MAX_DROP - self._corrupt:,} more may wait")
            self._corrupt += count

    def cut_replies(self, count: int) -> None:
        """The next ``count`` status packets go out cut in half."""
        with self.lock:
            if not 0 <= count <= MAX_DROP - self._cut:
                raise ValueError(f"cutting {count} replies: 0 to {MAX_DROP - self._cut:,} more may wait")
            self._cut += count

    def power_cycle(self) -> None:
        """The servo's supply goes and comes back: the RAM area starts over (torque off)."""
        with self.lock:
            _power_on_ram(self.table, self._present())
            self._overload = False
            self._registered = None
            self._rx.clear()
            self._velocity = 0.0
            self._update_present()
        self.counters["power_cycles"] += 1

    # -- the firmware ---------------------------------------------------------------------------

    def _word(self, address: int) -> int:
        return self.table[address] | self.table[address + 1] << 8

    def _present(self) -> int:
        return min(POSITION_MAX, max(0, round(self._shaft)))

    def _conditions(self) -> int:
        bits = 0
        volts10 = round(self._volts * 10)
        if not self.table[ADDR_MIN_VOLTAGE] <= volts10 <= self.table[ADDR_MAX_VOLTAGE]:
            bits |= ERROR_BITS["input_voltage"]
        if self._celsius > self.table[ADDR_TEMPERATURE_LIMIT]:
            bits |= ERROR_BITS["overheating"]
        if self._overload:
            bits |= ERROR_BITS["overload"]
        return bits

    def _update_present(self) -> None:
        """The read-only items from the shaft and the conditions; Alarm Shutdown drops the torque limit."""
        table = self.table
        if self._conditions() & table[ADDR_SHUTDOWN] and self._word(ADDR_TORQUE_LIMIT):
            table[ADDR_TORQUE_LIMIT : ADDR_TORQUE_LIMIT + 2] = b"\x00\x00"
            self.counters["shutdowns"] += 1
        present = self._present()
        table[ADDR_PRESENT_POSITION : ADDR_PRESENT_POSITION + 2] = present.to_bytes(2, "little")
        if not table[ADDR_TORQUE_ENABLE]:
            table[ADDR_GOAL : ADDR_GOAL + 2] = present.to_bytes(2, "little")  # the goal follows the hand
        rpm = abs(self._velocity) * DEGREES_PER_UNIT / 6
        speed = min(SPEED_MAX, round(rpm / RPM_PER_SPEED_UNIT))
        if speed and self._velocity < 0:
            speed |= DIRECTION_BIT
        table[ADDR_PRESENT_SPEED : ADDR_PRESENT_SPEED + 2] = speed.to_bytes(2, "little")
        load = (SPEED_MAX | (DIRECTION_BIT if self._velocity < 0 else 0)) if self._overload else 0
        table[ADDR_PRESENT_LOAD : ADDR_PRESENT_LOAD + 2] = load.to_bytes(2, "little")
        table[ADDR_PRESENT_VOLTAGE] = min(255, round(self._volts * 10))
        table[ADDR_PRESENT_TEMPERATURE] = self._celsius
        table[ADDR_REGISTERED] = int(self._registered is not None)
        table[ADDR_MOVING] = int(self._driven() and self._shaft != self._word(ADDR_GOAL))

    def _driven(self) -> bool:
        return bool(self.table[ADDR_TORQUE_ENABLE]) and self._word(ADDR_TORQUE_LIMIT) > 0

    def _units_per_s(self) -> float:
        top = self.no_load_rpm * self._volts / RATED_VOLTS
        speed = self._word(ADDR_SPEED)
        rpm = top if speed == 0 else min(top, speed * RPM_PER_SPEED_UNIT)
        return rpm * 6 / DEGREES_PER_UNIT

    def _loop(self, now: float, dt: float) -> None:
        """One pass: the shaft toward the goal, then the present values."""
        with self.lock:
            before = self._shaft
            if self._driven() and dt > 0:
                goal = self._word(ADDR_GOAL)
                step = self._units_per_s() * dt
                gap = goal - self._shaft
                self._shaft = float(goal) if abs(gap) <= step else self._shaft + math.copysign(step, gap)
            arrived = self._shaft == self._word(ADDR_GOAL)  # and stopped there: no speed to report
            self._velocity = 0.0 if arrived or dt <= 0 else (self._shaft - before) / dt
            self._update_present()

    def _received(self, data: bytes) -> None:
        self.counters["bytes_received"] += len(data)
        now = self.monotonic()
        replies: list[bytes] = []
        with self.lock:
            if self.check_baud and not self._baud_matches():
                self.counters["bytes_misframed"] += len(data)
                return
            if self._rx and now - self._rx_started > self.packet_timeout_s:
                self.counters["packets_timed_out"] += 1
                self._rx.clear()
            if not self._rx:
                self._rx_started = now
            self._rx += data
            waiting = len(self._rx)
            for packet in self._packets():
                reply = self._handle(packet)
                if reply is not None:
                    replies.append(self._damaged(reply))
            if self._rx and len(self._rx) < waiting:  # what is left began in this chunk
                self._rx_started = now
        for reply in replies:
            self._send_lines([reply])
            self.counters["replies"] += 1

    def _baud_matches(self) -> bool:
        slave = self._slave
        if slave is None:
            return True
        with contextlib.suppress(OSError, termios.error):
            host = SPEEDS.get(termios.tcgetattr(slave)[5])
            return host is None or abs(host - self.baud) <= BAUD_MARGIN * self.baud
        return True

    def _packets(self) -> list[_Packet]:
        """Whole packets from the receive buffer; skipped bytes are counted, a partial packet waits."""
        rx = self._rx
        packets = []
        while True:
            start = rx.find(b"\xff\xff")
            if start < 0:
                keep = 1 if rx.endswith(b"\xff") else 0
                self.counters["bytes_skipped"] += len(rx) - keep
                del rx[: len(rx) - keep]
                return packets
            while len(rx) > start + 2 and rx[start + 2] == 0xFF:  # a third 0xFF: IDs stop at 254
                start += 1
            if start:
                self.counters["bytes_skipped"] += start
                del rx[:start]
            if len(rx) < 4:
                return packets
            length = rx[3]
            if length < 2:
                self.counters["bad_packets"] += 1
                del rx[:2]
                continue
            if len(rx) < length + 4:
                return packets
            raw = bytes(rx[: length + 4])
            del rx[: length + 4]
            packets.append(_Packet(raw[2], raw[4], raw[5:-1], checksum(raw[2:-1]) == raw[-1]))

    def _damaged(self, reply: bytes) -> bytes:
        if self._corrupt:
            self._corrupt -= 1
            self.counters["replies_corrupted"] += 1
            reply = reply[:-1] + bytes([reply[-1] ^ 0xFF])
        if self._cut:
            self._cut -= 1
            self.counters["replies_cut"] += 1
            reply = reply[: len(reply) // 2]
        return reply

    def _handle(self, packet: _Packet) -> bytes | None:
        """Run one instruction packet; the status packet to send, if any."""
        me = self.table[ADDR_ID]
        if packet.dxl_id not in (me, BROADCAST_ID):
            self.counters["other_ids"] += 1
            return None
        broadcast = packet.dxl_id == BROADCAST_ID
        name = INSTRUCTIONS.get(packet.instruction, "unknown")
        self.counters[f"instruction_{name}"] += 1
        if self._fresh_link:
            self._fresh_link = False
            self.first_instructions.append(name)
        if not packet.intact:
            self.counters["checksum_errors"] += 1
            return None if broadcast else self._status(packet, ERROR_BITS["checksum"])
        params, error, data = packet.params, 0, b""
        after: Callable[[], None] | None = None
        if packet.instruction == PING:
            error = 0 if not params else ERROR_BITS["instruction"]
        elif packet.instruction == READ:
            if len(params) != 2:
                error = ERROR_BITS["instruction"]
            elif params[1] == 0 or params[0] + params[1] > TABLE_SIZE:
                error = ERROR_BITS["range"]
            else:
                self._update_present()
                data = bytes(self.table[params[0] : params[0] + params[1]])
        elif packet.instruction == WRITE:
            error, after = self._write_table(params)
        elif packet.instruction == REG_WRITE:
            error = self._check(params) if len(params) >= 2 else ERROR_BITS["instruction"]
            if not error:
                self._registered = (params[0], params[1:])
        elif packet.instruction == ACTION:
            if self._registered is None or params:
                error = ERROR_BITS["instruction"]
            else:
                address, values = self._registered
                self._registered = None
                error, after = self._write_table(bytes([address]) + values)
        elif packet.instruction == RESET:
            error = ERROR_BITS["instruction"] if params else 0
            after = None if params else self._factory_reset
        elif packet.instruction == SYNC_WRITE:
            self._sync_write(params)
            broadcast = True  # never answered
        else:
            error = ERROR_BITS["instruction"]
        for bit in ("angle_limit", "range", "instruction"):
            if error & ERROR_BITS[bit]:
                self.counters[f"{bit}_errors"] += 1
        self._update_present()
        reply = None if broadcast else self._status(packet, error, data)
        if after is not None:
            after()
            self._update_present()
        return reply

    def _status(self, packet: _Packet, error: int, data: bytes = b"") -> bytes | None:
        level = self.table[ADDR_STATUS_RETURN]
        if not (packet.instruction == PING or level >= 2 or (level == 1 and packet.instruction == READ)):
            self.counters["replies_withheld"] += 1
            return None
        return status_packet(packet.dxl_id, error | self._conditions(), data)

    def _check(self, params: bytes) -> int:
        """The error bits a write of ``params`` (address, bytes…) would get; 0 when it may be done."""
        address, values = params[0], params[1:]
        end = address + len(values)
        if end > TABLE_SIZE:
            return ERROR_BITS["range"]
        offset = address
        while offset < end:
            item = offset if offset in WRITABLE else offset - 1
            if item not in WRITABLE or (item != offset and item not in TWO_BYTE):
                return ERROR_BITS["range"]  # read-only, reserved, or the high byte alone
            size, low, high = WRITABLE[item]
            if item + size > end or item < address:
                return ERROR_BITS["range"]  # half of a 2-byte item
            value = int.from_bytes(values[item - address : item - address + size], "little")
            if not low <= value <= high:
                return ERROR_BITS["range"]
            if self.table[ADDR_LOCK] and item < RAM_START:
                return ERROR_BITS["range"]  # the EEPROM is locked
            offset = item + size
        if address <= ADDR_GOAL < end:
            goal = int.from_bytes(values[ADDR_GOAL - address : ADDR_GOAL - address + 2], "little")
            cw, ccw = self._word(ADDR_CW_LIMIT), self._word(ADDR_CCW_LIMIT)
            wheel = cw == 0 and ccw == 0
            if not wheel and not cw <= goal <= ccw:
                return ERROR_BITS["angle_limit"]
        return 0

    def _write_table(self, params: bytes) -> tuple[int, Callable[[], None] | None]:
        if len(params) < 2:
            return ERROR_BITS["instruction"], None
        error = self._check(params)
        if error:
            return error, None
        address, values = params[0], params[1:]
        end = address + len(values)
        link = bytes(self.table[ADDR_ID : ADDR_BAUD + 1])  # ID and baud change after the reply
        self.table[address:end] = values
        if address <= ADDR_GOAL < end or address <= ADDR_SPEED < end:
            self.table[ADDR_TORQUE_ENABLE] = 1  # the AX's habit: a goal or a speed turns the torque on
        settled = bytes(self.table[ADDR_ID : ADDR_BAUD + 1])
        if settled == link:
            return 0, None
        self.table[ADDR_ID : ADDR_BAUD + 1] = link

        def settle() -> None:
            self.table[ADDR_ID : ADDR_BAUD + 1] = settled

        return 0, settle

    def _sync_write(self, params: bytes) -> None:
        if len(params) < 2 or params[1] == 0 or (len(params) - 2) % (params[1] + 1):
            self.counters["bad_packets"] += 1
            return
        address, size = params[0], params[1]
        for offset in range(2, len(params), size + 1):
            if params[offset] == self.table[ADDR_ID]:
                error, after = self._write_table(bytes([address]) + params[offset + 1 : offset + 1 + size])
                if error:
                    self.counters["sync_write_refused"] += 1
                if after is not None:
                    after()

    def _factory_reset(self) -> None:
        self.table[:] = _default_table(self.firmware, self._present())
        self.table[ADDR_MODEL_NUMBER : ADDR_MODEL_NUMBER + 2] = self.model.to_bytes(2, "little")
        self._registered = None
        self.counters["factory_resets"] += 1
