"""The face tracker's pan servo: one Dynamixel AX-12A over ROBOTIS' own ``dynamixel-sdk`` (protocol 1.0).

The book's chapter 2 drives the servo through ``dynamixel_controllers`` with this ``pan.yaml``::

    pan_controller: {controller: {package: dynamixel_controllers, module: joint_position_controller,
      type: JointPositionController}, joint_name: pan_joint, joint_speed: 1.17,
      motor: {id: 1, init: 512, min: 316, max: 708}}

on ``/dev/ttyUSB0`` at 1 Mbps (``baud_rate: 1000000``), with the servo set to ID 1, baud register 1 in
RoboPlus. ``DynamixelServo`` does what that controller does, without ROS, and what it does not do
for a robot that must be safe:

- **Open**: ``PortHandler(port)`` at ``baud`` (1 Mbps; any rate the SDK's ``getCFlagBaud`` lists),
  ``PacketHandler(1.0)``, a ping whose model number must be 12 (the AX-12A; another model is a
  wiring or configuration error: ``WrongModelError``), the angle limits written to CW/CCW Angle
  Limit (6, 8) when the servo holds others (EEPROM: not rewritten needlessly), then **hold** (goal
  = present position clamped into the limits, torque on) and the joint speed into Moving Speed
  (32). The same happens on every reconnection: the servo kept whatever it was told while the host
  was away, and the first thing it hears is "stay where you are".
- **Angles** as ``dynamixel_controllers`` takes them (``joint_controller.rad_to_raw``):
  ``raw = round(init + angle * ticks_per_radian)``, with ``ticks_per_radian = 1024 / radians(300)``
  (``dynamixel_serial_proxy``: ``encoder_resolution / range_radians`` with the AX-12's 1024 and
  300°), so positive angles turn **counter-clockwise** seen from the horn (raw counts grow CCW in
  the e-manual's Goal Position figure: 0 is the CW end, 1023 the CCW end); when ``min > max`` the
  controller is "flipped" and the sign is reversed, as here. ``move_to`` clamps to the limits
  (±1.002 rad for 316..708 about 512) before converting, as ``pos_rad_to_raw`` does: the servo
  never sees a goal it would refuse.
- **Speed**: ``joint_speed`` (rad/s) to Moving Speed units of 0.111 rpm (the e-manual; the
  ``rpm_per_tick`` of ``dynamixel_const``), at least 1 (0 means "as fast as it can", which
  ``spd_rad_to_raw`` avoids too): 1.17 rad/s is 101 units (11.2 rpm), the 100 the chapter sets in
  RoboPlus within a unit.
- **Transactions** hold one lock (the port is shared by every caller). A transaction that gets no
  valid status (timeout, corrupt packet, a short read, or the servo's own checksum error: our packet
  was damaged and not executed) is retried up to ``retries`` times, each counted; the servo's
  error byte is decoded into named bits (``ERROR_BITS``), counted in ``errors`` and kept as
  ``last_error``. Before each instruction the input buffer is flushed (``clearPort``: the C++ SDK's
  ``tcflush(TCIFLUSH)``; the Python SDK's ``ser.flush()`` only drains output, so a late reply
  would be read as the next one's).
- **Unplugging**: a port error (the device is gone) or a transaction that exhausts its retries
  closes the port; later calls reopen it with exponential backoff (``backoff``, on ``monotonic``)
  and return False/None meanwhile: nothing raises into the caller's loop. Everything is counted
  (``counters``, ``stats()``).
- **Exit**: ``close()`` (also at interpreter exit) holds the servo at its present position with
  torque on, then closes the port: the pan joint stays where it is and resists, it neither falls
  nor goes on to a stale goal. (A torque limit the servo's own Alarm Shutdown set to 0 is left to
  the operator: the driver reports the overload or overheating, it does not re-arm the motor.)

``GroupSyncWrite`` is not used: sync write is a broadcast, which the servo never answers, so a goal
sent that way could not be confirmed (nor its errors read); with one servo it saves nothing.

Sources: ROBOTIS-GIT/DynamixelSDK ``python/src/dynamixel_sdk`` (``protocol1_packet_handler.py``: the
packet layout, ``ERRBIT_*``, ping = ping + read of address 0; ``port_handler.py``: packet timeout =
``tx_time_per_byte * length + 2 * LATENCY_TIMER (16 ms) + 2 ms``, ``time.time`` based;
``robotis_def.py``: instructions 1-6 and 0x83, broadcast 254), ``c++/src/dynamixel_sdk/
port_handler_linux.cpp`` (``clearPort`` flushes input); the ROBOTIS e-manual (``emanual``
repository: ``docs/en/dxl/ax/ax-12a.md`` for the control table addresses and defaults, model
number 12, 0.111 rpm per Moving Speed unit, 0.29° per position unit; ``docs/en/dxl/protocol1.md``
for the status packet's error bits); arebgun/dynamixel_motor (``joint_controller.py``,
``joint_position_controller.py``, ``dynamixel_const.py``, ``dynamixel_serial_proxy.py``) for the
angle and speed conversions the book's controller applies.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import serial
from dynamixel_sdk import COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler, PortHandler

from botstage.robots.ax12 import (  # the servo's units and conversions, shared with the simulator
    BAUD,
    CENTRE,
    DIRECTION_BIT,
    JOINT_SPEED,
    LIMITS,
    POSITION_MAX,
    RAD_S_PER_SPEED_UNIT,
    SPEED_MAX,
    angle_to_raw,
    raw_to_angle,
    speed_to_raw,
)
from botstage.robots.drivers.serial_link import RateLimitedLog

try:
    from termios import error as TermiosError
except ImportError:  # not a POSIX system: pyserial raises its own errors there
    TermiosError = OSError  # type: ignore[misc,assignment]

log = logging.getLogger(__name__)

# -- protocol 1.0 and the AX-12A's control table (e-manual: docs/en/dxl/ax/ax-12a.md, protocol1.md) --

PROTOCOL = 1.0
BROADCAST_ID = 254
MAX_ID = 253
AX12_MODEL = 12

PING, READ, WRITE, REG_WRITE, ACTION, RESET, SYNC_WRITE = 1, 2, 3, 4, 5, 6, 0x83
INSTRUCTIONS = {
    PING: "ping",
    READ: "read",
    WRITE: "write",
    REG_WRITE: "reg_write",
    ACTION: "action",
    RESET: "reset",
    SYNC_WRITE: "sync_write",
}

# EEPROM area
ADDR_MODEL_NUMBER = 0  # 2 bytes, read-only
ADDR_FIRMWARE = 2
ADDR_ID = 3
ADDR_BAUD = 4  # baud = 2 Mbps / (value + 1): 1 is 1 Mbps
ADDR_RETURN_DELAY = 5  # 2 µs a unit
ADDR_CW_LIMIT = 6  # 2 bytes: the lowest goal
ADDR_CCW_LIMIT = 8  # 2 bytes: the highest goal
ADDR_TEMPERATURE_LIMIT = 11
ADDR_MIN_VOLTAGE = 12  # 0.1 V a unit
ADDR_MAX_VOLTAGE = 13
ADDR_MAX_TORQUE = 14  # 2 bytes
ADDR_STATUS_RETURN = 16  # 0: ping only, 1: ping and read, 2: all
ADDR_ALARM_LED = 17
ADDR_SHUTDOWN = 18
# RAM area
ADDR_TORQUE_ENABLE = 24
ADDR_LED = 25
ADDR_CW_MARGIN = 26
ADDR_CCW_MARGIN = 27
ADDR_CW_SLOPE = 28
ADDR_CCW_SLOPE = 29
ADDR_GOAL = 30  # 2 bytes
ADDR_SPEED = 32  # 2 bytes, Moving Speed
ADDR_TORQUE_LIMIT = 34  # 2 bytes
ADDR_PRESENT_POSITION = 36  # 2 bytes, read-only from here to 46
ADDR_PRESENT_SPEED = 38
ADDR_PRESENT_LOAD = 40
ADDR_PRESENT_VOLTAGE = 42
ADDR_PRESENT_TEMPERATURE = 43
ADDR_REGISTERED = 44
ADDR_MOVING = 46
ADDR_LOCK = 47
ADDR_PUNCH = 48  # 2 bytes
TABLE_SIZE = 50
RAM_START = ADDR_TORQUE_ENABLE

# the status packet's error byte (protocol1.md; the SDK's ERRBIT_*)
ERROR_BITS = {
    "input_voltage": 0x01,
    "angle_limit": 0x02,
    "overheating": 0x04,
    "range": 0x08,
    "checksum": 0x10,
    "overload": 0x20,
    "instruction": 0x40,
}

MAX_RETRIES = 10
MAX_LATENCY_MS = 1000.0
READ_WAIT_S = 0.001  # pyserial's read timeout inside the SDK's polling loop (the SDK's own 0 spins)


def decode_error(error: int) -> frozenset[str]:
    """The named bits of a status packet's error byte."""
    return frozenset(name for name, bit in ERROR_BITS.items() if error & bit)


def checksum(body: bytes | bytearray) -> int:
    """Protocol 1.0's checksum: the ones' complement of the byte sum of ID, length, instruction or
    error and parameters (the lower byte)."""
    return ~sum(body) & 0xFF


def signed_magnitude(value: int) -> int:
    """Present Speed / Load: bits 0-9 the magnitude, bit 10 set for clockwise (negative)."""
    magnitude = value & 0x3FF
    return -magnitude if value & DIRECTION_BIT else magnitude


class DynamixelError(Exception):
    """A servo that cannot be driven as configured (not a passing communication failure)."""


class WrongModelError(DynamixelError):
    """The ID answers with another model number than the one expected."""


@dataclass(frozen=True)
class ServoState:
    """One reading of the servo (Present Position to Moving, in one read)."""

    position: float  # rad from the centre, counter-clockwise positive
    speed: float  # rad/s, counter-clockwise positive
    load: float  # share of the maximum torque, -1..1, counter-clockwise positive
    voltage: float  # V
    temperature: int  # °C
    moving: bool
    error: frozenset[str]


class _Port(PortHandler):
    """The SDK's PortHandler with the C++ SDK's ``clearPort`` (input flushed before each packet), a
    configurable USB latency in the packet timeout, and a short blocking read instead of a spin."""

    def __init__(self, port_name: str, latency_ms: float) -> None:
        super().__init__(port_name)
        self.latency_ms = latency_ms

    def clearPort(self) -> None:
        self.ser.reset_input_buffer()

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.latency_ms * 2.0 + 2.0

    def setupPort(self, cflag_baud: int) -> bool:
        ok = super().setupPort(cflag_baud)
        self.ser.timeout = READ_WAIT_S
        self.ser.write_timeout = 0.5  # a port nobody drains must not hang the caller
        return ok


# a vanished device: pyserial's errors, the OS's, termios' (tcflush on a hung-up tty), a port closed under us
_PORT_ERRORS = (serial.SerialException, OSError, TermiosError, ValueError, TypeError, AttributeError)
_Call = Callable[[Any, PortHandler], tuple[Any, int, int]]
_RESULTS = {COMM_RX_TIMEOUT: "timeouts", COMM_RX_CORRUPT: "corrupt_replies"}


class DynamixelServo:
    """One AX-12A on one port (see the module). Thread-safe; ``open()`` first, ``close()`` last."""

    def __init__(
        self,
        port: str,
        *,
        dxl_id: int = 1,
        baud: int = BAUD,
        limits: tuple[int, int] = LIMITS,
        centre: int = CENTRE,
        joint_speed: float = JOINT_SPEED,
        model: int = AX12_MODEL,
        retries: int = 3,
        latency_ms: float = 16.0,
        backoff: tuple[float, float] = (0.05, 2.0),
        name: str = "pan_joint",
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        if not 0 <= dxl_id <= MAX_ID:
            raise ValueError(f"ID {dxl_id}: 0 to {MAX_ID} (254 is the broadcast ID)")
        if PortHandler(port).getCFlagBaud(baud) <= 0:
            raise ValueError(f"baud {baud}: not a rate the SDK's PortHandler opens")
        low, high = sorted(limits)
        if not (0 <= low < high <= POSITION_MAX and low <= centre <= high):
            raise ValueError(f"limits {limits} about centre {centre}: two different positions in 0..1023 around it")
        if not 0 <= retries <= MAX_RETRIES:
            raise ValueError(f"retries {retries}: 0 to {MAX_RETRIES}")
        if not (math.isfinite(latency_ms) and 0 < latency_ms <= MAX_LATENCY_MS):
            raise ValueError(f"latency {latency_ms} ms: more than 0 and at most {MAX_LATENCY_MS:g}")
        if not (0 < backoff[0] <= backoff[1] and math.isfinite(backoff[1])):
            raise ValueError(f"backoff {backoff}: 0 < first <= longest, seconds")
        self.port = port
        self.dxl_id = dxl_id
        self.baud = baud
        self.limits = (limits[0], limits[1])
        self.low, self.high = low, high
        self.centre = centre
        self.flipped = limits[0] > limits[1]  # dynamixel_controllers' "flipped" (min > max)
        self.speed_raw = speed_to_raw(joint_speed)
        self.model = model
        self.retries = retries
        self.latency_ms = latency_ms
        self.backoff = backoff
        self.name = name
        self.monotonic = monotonic
        self.counters: Counter[str] = Counter()
        self.errors: Counter[str] = Counter()  # status packets carrying each error bit
        self.last_error: frozenset[str] = frozenset()
        self.held_on_close: bool | None = None  # whether close() could hold the servo
        self.warn = RateLimitedLog(log, monotonic=monotonic)
        self._packet = PacketHandler(PROTOCOL)
        self._port: _Port | None = None
        self._lock = threading.RLock()
        self._closed = False
        self._opened = False
        self._linked = False  # a connection was set up and not lost since
        self._delay = backoff[0]
        self._next_attempt = -math.inf

    # -- limits in radians ----------------------------------------------------------------------

    @property
    def min_angle(self) -> float:
        return min(raw_to_angle(limit, self.centre, self.flipped) for limit in self.limits)

    @property
    def max_angle(self) -> float:
        return max(raw_to_angle(limit, self.centre, self.flipped) for limit in self.limits)

    def goal_raw(self, angle: float) -> int:
        """The goal ``move_to(angle)`` sends: ``angle`` clamped to the limits, in position units."""
        if not math.isfinite(angle):
            raise ValueError(f"angle {angle}: a finite number of radians")
        clamped = min(max(angle, self.min_angle), self.max_angle)
        return min(max(angle_to_raw(clamped, self.centre, self.flipped), self.low), self.high)

    # -- lifecycle ------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        return self._port is not None

    @property
    def closed(self) -> bool:
        return self._closed

    def open(self) -> bool:
        """Connect now (ping, model, limits, hold, speed); False when the servo is not reachable yet
        (later calls keep trying, with backoff). Raises ``WrongModelError`` for another model."""
        with self._lock:
            if self._closed:
                raise DynamixelError(f"{self.name} on {self.port} was closed")
            self._register_exit()
            if self._port is not None:
                return True
            self._next_attempt = -math.inf
            return self._ensure_link(first=True)

    def close(self) -> None:
        """Hold the servo at its present position with torque on, then close the port. Safe to call
        twice, from any thread."""
        with self._lock:
            if self._closed:
                return
            if not self._opened:  # never opened nor used: nothing to hold
                self._closed = True
                return
            if self._port is None:
                self._next_attempt = -math.inf  # one last try to reach it: the hold comes with the connection
                held = self._ensure_link()
            else:
                held = self._hold()
            self.held_on_close = held
            self._closed = True
            self._close_port()
        if self._opened:
            atexit.unregister(self.close)

    def _register_exit(self) -> None:
        if not self._opened:
            self._opened = True
            atexit.register(self.close)

    def __enter__(self) -> DynamixelServo:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- commands and readings ------------------------------------------------------------------

    def move_to(self, angle: float) -> bool:
        """Send the goal for ``angle`` (radians from the centre, clamped to the limits); True once the
        servo acknowledged it without refusing it (its conditions, such as overheating, are counted)."""
        raw = self.goal_raw(angle)
        with self._lock:
            if raw != angle_to_raw(angle, self.centre, self.flipped):
                self.counters["clamped"] += 1
            if not self._ensure_link():
                return False
            return self._write2(ADDR_GOAL, raw, "goal")

    def position(self) -> float | None:
        """The present position in radians from the centre, or None when the servo is unreachable."""
        with self._lock:
            if not self._ensure_link():
                return None
            raw = self._read_word(ADDR_PRESENT_POSITION, "present position")
        return None if raw is None else raw_to_angle(raw, self.centre, self.flipped)

    def read_state(self) -> ServoState | None:
        """Present position, speed, load, voltage, temperature and moving in one read, or None."""
        with self._lock:
            if not self._ensure_link():
                return None
            length = ADDR_MOVING - ADDR_PRESENT_POSITION + 1
            result = self._transact("state", self._reader(ADDR_PRESENT_POSITION, length))
        if result is None:
            return None
        data, error = result
        if len(data) != length:
            return None
        sign = -1 if self.flipped else 1
        return ServoState(
            position=raw_to_angle(data[0] | data[1] << 8, self.centre, self.flipped),
            speed=sign * signed_magnitude(data[2] | data[3] << 8) * RAD_S_PER_SPEED_UNIT,
            load=sign * signed_magnitude(data[4] | data[5] << 8) / SPEED_MAX,
            voltage=data[6] / 10,
            temperature=data[7],
            moving=bool(data[10]),
            error=decode_error(error),
        )

    def hold(self) -> bool:
        """Goal = present position (clamped into the limits), torque on: the joint stops and resists."""
        with self._lock:
            if not self._ensure_link():
                return False
            return self._hold()

    def stats(self) -> dict[str, Any]:
        """Counters for reports: link events, transactions, retries, status errors by bit."""
        return {
            "port": self.port,
            "id": self.dxl_id,
            "connected": self.connected,
            "errors": dict(sorted(self.errors.items())),
            "last_error": sorted(self.last_error),
            **dict(sorted(self.counters.items())),
        }

    # -- the link -------------------------------------------------------------------------------

    def _ensure_link(self, *, first: bool = False) -> bool:
        if self._closed:
            self.counters["calls_after_close"] += 1
            return False
        if self._port is not None:
            return True
        now = self.monotonic()
        if now < self._next_attempt:
            self.counters["calls_while_down"] += 1
            return False
        if self._connect(first=first):
            self._delay = self.backoff[0]
            return True
        self._next_attempt = self.monotonic() + self._delay
        self._delay = min(self._delay * 2, self.backoff[1])
        return False

    def _connect(self, *, first: bool) -> bool:
        port = _Port(self.port, self.latency_ms)
        try:
            opened = port.setBaudRate(self.baud)
        except _PORT_ERRORS as exc:
            self.counters["open_failures"] += 1
            self.warn.warning("open", f"{self.name} {self.port}: cannot open: {exc}; retrying")
            return False
        if not opened:
            self.counters["open_failures"] += 1
            return False
        self._port = port
        pinged = self._transact("ping", self._ping)
        model = None if pinged is None else pinged[0]
        if model is None:
            self.counters["ping_failures"] += 1
            self.warn.warning("ping", f"{self.name} {self.port}: ID {self.dxl_id} does not answer at {self.baud} bps")
            self._close_port()
            return False
        if model != self.model:
            self.counters["wrong_model"] += 1
            self._close_port()
            message = f"{self.name} {self.port}: ID {self.dxl_id} is model {model}, not {self.model} (AX-12A: 12)"
            if first:
                raise WrongModelError(message)
            self.warn.warning("model", message)
            return False
        if not (self._set_limits() and self._hold() and self._write2(ADDR_SPEED, self.speed_raw, "moving speed")):
            self.counters["setup_failures"] += 1
            self._close_port()
            return False
        self._linked = True
        self._register_exit()  # used without open(): still held at exit
        self.counters["connects"] += 1
        if self.counters["connects"] > 1:
            self.counters["reconnects"] += 1
            self.warn.warning("reconnect", f"{self.name} {self.port}: reconnected; holding")
        return True

    def _lost(self, why: str) -> None:
        self._close_port()
        if self._linked:
            self._linked = False
            self.counters["disconnects"] += 1
        self._next_attempt = self.monotonic() + self._delay
        self.warn.warning("lost", f"{self.name} {self.port}: link lost ({why}); reconnecting")

    def _close_port(self) -> None:
        port, self._port = self._port, None
        if port is not None and port.ser is not None:
            with contextlib.suppress(*_PORT_ERRORS):
                port.closePort()

    # -- transactions ---------------------------------------------------------------------------

    def _transact(self, what: str, call: _Call) -> Any:
        """``call`` on the open port, retried; its value, or None once every attempt failed (the link
        is then dropped: a port that stopped answering is reopened before the next try)."""
        for attempt in range(self.retries + 1):
            port = self._port
            if port is None:
                return None
            if attempt:
                self.counters["retries"] += 1
            self.counters["transactions"] += 1
            try:
                value, result, error = call(self._packet, port)
            except _PORT_ERRORS as exc:
                self.counters["port_errors"] += 1
                self._lost(f"{what}: {exc}")
                return None
            except IndexError:  # the SDK's ping read a short reply as a model number
                value, result, error = None, COMM_RX_CORRUPT, 0
            if result != COMM_SUCCESS:
                self.counters[_RESULTS.get(result, "tx_failures")] += 1
                continue
            self._note(error)
            if error & ERROR_BITS["checksum"]:  # our packet arrived damaged: not executed
                continue
            return value, error
        self.counters["failures"] += 1
        self._lost(f"{what}: no valid status in {self.retries + 1} tries")
        return None

    def _note(self, error: int) -> None:
        bits = decode_error(error)
        self.last_error = bits
        for name in bits:
            self.errors[name] += 1
        if bits:
            self.counters["status_errors"] += 1
            self.warn.warning("status", f"{self.name} {self.port}: servo reports {', '.join(sorted(bits))}")

    def _ping(self, packet: Any, port: PortHandler) -> tuple[Any, int, int]:
        return packet.ping(port, self.dxl_id)

    def _reader(self, address: int, length: int) -> _Call:
        def read(packet: Any, port: PortHandler) -> tuple[Any, int, int]:
            data, result, error = packet.readTxRx(port, self.dxl_id, address, length)
            if result == COMM_SUCCESS and len(data) != length and not error:
                self.counters["short_replies"] += 1
                return None, COMM_RX_CORRUPT, 0
            return data, result, error

        return read

    def _writer(self, address: int, data: list[int]) -> _Call:
        def write(packet: Any, port: PortHandler) -> tuple[Any, int, int]:
            result, error = packet.writeTxRx(port, self.dxl_id, address, len(data), data)
            return None, result, error

        return write

    def _write(self, address: int, data: list[int], what: str) -> bool:
        """Write and check: True when acknowledged with no refusal bit (range, angle limit, instruction)."""
        result = self._transact(what, self._writer(address, data))
        if result is None:
            return False
        _, error = result
        refused = error & (ERROR_BITS["range"] | ERROR_BITS["angle_limit"] | ERROR_BITS["instruction"])
        if refused:
            self.counters["refused_writes"] += 1
        return not refused

    def _write2(self, address: int, value: int, what: str) -> bool:
        return self._write(address, [value & 0xFF, value >> 8 & 0xFF], what)

    def _read_word(self, address: int, what: str) -> int | None:
        result = self._transact(what, self._reader(address, 2))
        if result is None:
            return None
        data, error = result
        if error & (ERROR_BITS["range"] | ERROR_BITS["instruction"]) or len(data) != 2:
            return None
        return data[0] | data[1] << 8

    def _set_limits(self) -> bool:
        result = self._transact("angle limits", self._reader(ADDR_CW_LIMIT, 4))
        if result is None:
            return False
        data, _ = result
        wanted = [self.low & 0xFF, self.low >> 8, self.high & 0xFF, self.high >> 8]
        if list(data) == wanted:
            return True
        self.counters["limits_written"] += 1
        return self._write(ADDR_CW_LIMIT, wanted, "angle limits")

    def _hold(self) -> bool:
        present = self._read_word(ADDR_PRESENT_POSITION, "present position")
        if present is None:
            return False
        goal = min(max(present, self.low), self.high)
        if not (self._write2(ADDR_GOAL, goal, "hold goal") and self._write(ADDR_TORQUE_ENABLE, [1], "torque on")):
            return False
        self.counters["holds"] += 1
        return True
