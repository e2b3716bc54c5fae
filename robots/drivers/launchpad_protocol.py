"""The Chefbot Launchpad's serial protocol (book ch. 9): framing, parsing, commands. No I/O.

The Tiva C firmware prints one line per reading at 115200 baud 8N1, a letter naming the device
and its values separated by tabs (the chapter: "by spaces and tabs"), ending in ``\\n``
(``Serial.println`` ends in ``\\r\\n``, which is accepted too):

- ``e <left> <right>``: encoder counters, C ``long``: 32-bit two's complement on the Tiva C
  (ARM Cortex-M4), so they wrap from 2**31 - 1 to -2**31. Only the difference of two readings
  is used, taken modulo 2**32 (``wrap_delta``), so a wrap is an ordinary step of one tick.
- ``b <volts>``, ``u <cm>`` (HC-SR04; 0 when no echo came back), ``i <qx> <qy> <qz> <qw>``
  (MPU-6050 DMP quaternion), ``t <micros> <seconds since the last update>`` (``micros()``,
  ``unsigned long``: wraps every 71.6 min), ``s <left> <right>`` (the motor speeds applied).

The PC sends ``s <left> <right>\\r`` (motor outputs, -255..255 PWM as the book's pid_velocity
node produces them) and ``r\\r`` (reset the board), read by the firmware's Messenger library.

A line that is not exactly one of these (wrong letter, wrong number of fields, a field that is
not a finite number or out of its C type's range, too long, or cut by a reconnection) is
dropped and counted by reason, never raised to the caller: a serial line carries noise, and the
next line is good again.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

BAUD = 115_200
LINE_RATE_BYTES = BAUD / 10  # 8N1: ten bits a byte, 11,520 bytes/s at most
MAX_LINE = 96  # bytes; the longest valid line (an IMU line of four floats) is under 60
ENCODER_BITS = 32  # C long on the Tiva C
MICROS_BITS = 32  # unsigned long micros()
PWM_LIMIT = 255  # the motor outputs the firmware takes (analogWrite duty)

_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


@dataclass(frozen=True, slots=True)
class Encoders:
    left: int
    right: int


@dataclass(frozen=True, slots=True)
class BatteryVolts:
    volts: float


@dataclass(frozen=True, slots=True)
class Ultrasonic:
    cm: float  # 0: no echo within the sensor's range


@dataclass(frozen=True, slots=True)
class Quaternion:
    x: float
    y: float
    z: float
    w: float

    @property
    def yaw(self) -> float:
        """Rotation about z (rad), from the quaternion as ROS's tf does."""
        return math.atan2(2.0 * (self.w * self.z + self.x * self.y), 1.0 - 2.0 * (self.y * self.y + self.z * self.z))


@dataclass(frozen=True, slots=True)
class BoardTime:
    micros: int
    since_last: float  # s since the firmware's previous loop


@dataclass(frozen=True, slots=True)
class MotorSpeeds:
    left: float
    right: float


Message = Encoders | BatteryVolts | Ultrasonic | Quaternion | BoardTime | MotorSpeeds


class BadLine(ValueError):
    """A line that is not a valid board message; ``reason`` is its counter's name."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _int(field: bytes, low: int, high: int) -> int:
    try:
        value = int(field)
    except ValueError:
        raise BadLine("not_a_number") from None
    if not low <= value <= high:
        raise BadLine("out_of_range")
    return value


def _float(field: bytes) -> float:
    try:
        value = float(field)
    except ValueError:
        raise BadLine("not_a_number") from None
    if not math.isfinite(value):
        raise BadLine("not_a_number")
    return value


def _encoders(fields: list[bytes]) -> Encoders:
    return Encoders(_int(fields[1], _INT32_MIN, _INT32_MAX), _int(fields[2], _INT32_MIN, _INT32_MAX))


def _battery(fields: list[bytes]) -> BatteryVolts:
    volts = _float(fields[1])
    if not 0.0 <= volts < 100.0:
        raise BadLine("out_of_range")
    return BatteryVolts(volts)


def _ultrasonic(fields: list[bytes]) -> Ultrasonic:
    cm = _float(fields[1])
    if not 0.0 <= cm < 100_000.0:
        raise BadLine("out_of_range")
    return Ultrasonic(cm)


def _imu(fields: list[bytes]) -> Quaternion:
    q = Quaternion(_float(fields[1]), _float(fields[2]), _float(fields[3]), _float(fields[4]))
    norm = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w
    if not 0.8 <= norm <= 1.2:  # printed with few decimals, a unit quaternion is still near 1
        raise BadLine("out_of_range")
    return q


def _time(fields: list[bytes]) -> BoardTime:
    since = _float(fields[2])
    if since < 0.0:
        raise BadLine("out_of_range")
    return BoardTime(_int(fields[1], 0, 2**MICROS_BITS - 1), since)


def _speeds(fields: list[bytes]) -> MotorSpeeds:
    left, right = _float(fields[1]), _float(fields[2])
    if abs(left) > 100_000 or abs(right) > 100_000:
        raise BadLine("out_of_range")
    return MotorSpeeds(left, right)


_PARSERS = {
    b"e": (3, _encoders),
    b"b": (2, _battery),
    b"u": (2, _ultrasonic),
    b"i": (5, _imu),
    b"t": (3, _time),
    b"s": (3, _speeds),
}


def parse_line(line: bytes) -> Message:
    """One line (without its ``\\n``) as a message; ``BadLine`` with the reason otherwise."""
    fields = line.split()  # tabs or spaces, a trailing \r or tab included
    if not fields:
        raise BadLine("empty")
    entry = _PARSERS.get(fields[0])
    if entry is None:
        raise BadLine("unknown_tag")
    count, parse = entry
    if len(fields) != count:
        raise BadLine("field_count")
    if b"_" in line:  # Python's int() and float() take 1_000; the firmware never prints it
        raise BadLine("not_a_number")
    return parse(fields)


def wrap_delta(new: int, old: int, bits: int = ENCODER_BITS) -> int:
    """The signed step from ``old`` to ``new`` of a two's complement counter of ``bits`` bits:
    exact across a wrap, as long as a step is under half the counter's range."""
    span = 1 << bits
    half = span >> 1
    return (new - old + half) % span - half


def micros_delta(new: int, old: int) -> int:
    """Microseconds from ``old`` to ``new`` of the board's unsigned 32-bit ``micros()``."""
    return (new - old) % (1 << MICROS_BITS)


def speed_command(left: int, right: int) -> bytes:
    """The motor command; outputs beyond the PWM range are clamped here, whatever asked for them."""
    left = max(-PWM_LIMIT, min(PWM_LIMIT, int(left)))
    right = max(-PWM_LIMIT, min(PWM_LIMIT, int(right)))
    return b"s %d %d\r" % (left, right)


RESET_COMMAND = b"r\r"


class LineDecoder:
    """Bytes from the port to messages: survives partial lines, garbage and cut-off lines.

    ``feed`` takes whatever a read returned and gives the messages of the lines it completed;
    a partial line waits for the rest. A run of more than ``max_line`` bytes without a newline
    is garbage: it is dropped up to the next newline. ``resync()`` (after a reconnection)
    drops the partial line held; the first line that follows may start mid-way, and if it
    does not parse it is counted as ``cut`` rather than as garbage.
    Counters: ``ok`` by message kind, ``bad`` by reason.
    """

    def __init__(self, max_line: int = MAX_LINE) -> None:
        self.max_line = max_line
        self._partial = b""
        self._discarding = False  # inside an over-long line: drop until its newline
        self._first_cut = False  # the first line after a resync may start mid-way
        self.ok: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()
        self.bytes = 0

    def resync(self) -> None:
        self._partial = b""
        self._discarding = False
        self._first_cut = True

    def feed(self, data: bytes) -> list[Message]:
        self.bytes += len(data)
        lines = (self._partial + data).split(b"\n")
        self._partial = lines.pop()
        messages: list[Message] = []
        bad = self.bad
        for line in lines:
            if self._discarding:
                self._discarding = False
                continue
            if len(line) > self.max_line:
                bad["too_long"] += 1
                continue
            try:
                messages.append(parse_line(line))
            except BadLine as exc:
                bad["cut" if self._first_cut else exc.reason] += 1
            self._first_cut = False
        if len(self._partial) > self.max_line:
            bad["too_long"] += 1
            self._partial = b""
            self._discarding = True
        if messages:
            ok = self.ok
            for message in messages:
                ok[type(message).__name__] += 1
        return messages

    @property
    def lines_ok(self) -> int:
        return sum(self.ok.values())

    @property
    def lines_bad(self) -> int:
        return sum(self.bad.values())


@dataclass(frozen=True, slots=True)
class Command:
    """A command the board received: ``s`` with the two motor outputs, or ``r``."""

    kind: str
    left: int = 0
    right: int = 0


class CommandDecoder:
    """The firmware's side (Messenger): commands end in ``\\r`` (or ``\\n``), fields split by spaces.

    Anything else is counted and ignored, as the firmware ignores what Messenger cannot match."""

    def __init__(self, max_line: int = 64) -> None:
        self.max_line = max_line
        self._partial = b""
        self.bad = 0

    def feed(self, data: bytes) -> list[Command]:
        text = (self._partial + data).replace(b"\n", b"\r")
        parts = text.split(b"\r")
        self._partial = parts.pop()
        if len(self._partial) > self.max_line:
            self._partial = b""
            self.bad += 1
        commands = []
        for part in parts:
            fields = part.split()
            if not fields:
                continue
            if fields == [b"r"]:
                commands.append(Command("r"))
            elif len(fields) == 3 and fields[0] == b"s":
                try:
                    left, right = int(fields[1]), int(fields[2])
                except ValueError:
                    self.bad += 1
                    continue
                commands.append(Command("s", left, right))
            else:
                self.bad += 1
        return commands
