"""OpenCat's serial protocol (Petoi's NyBoard, Bittle's board): tokens out, acknowledgements back.

From Petoi's OpenCat firmware (``src/OpenCat.h``, ``src/io.h``, ``src/reaction.h`` of 2.x;
``OpenCat.ino`` of 1.x) and its host tool ``serialMaster/ardSerial.py``:

- A command is one case-sensitive token character, ASCII arguments separated by spaces, and a
  newline: ``kwkF\\n`` (skill ``wkF``: walk forward), ``d\\n`` (rest, servos off), ``p\\n``
  (pause toggle), ``g\\n`` (gyro toggle), ``b 12 8\\n`` (beep: tone, duration), ``m 0 30\\n``
  (move joints one after another), ``i 0 30 8 -20\\n`` (move joints together, 2.x), ``j\\n``
  (joint angles), ``?\\n`` (model and version, recent 2.x). Upper-case tokens are binary in 2.x
  (``I``, ``L``, ``M``, ``B``, ``K``, ending in ``~``); they are not used here. OpenCat 2 also
  ends a command after 5 ms of silence, so each command goes out in one write.
- The board answers a command with its token on a line of its own (``k\\r\\n``): in 1.x as soon
  as it read it, in 2.x when it has done it (a posture reached, a gait's first frame, a
  behaviour's end). Around that it prints other lines a driver must take in its stride: boot
  text (``* Start *``, ``Bittle``, the version, ``Init IMU``, ``Ready!``), state echoes (``G``,
  ``g``, ``P``, ``p``), ``?`` or ``wrong key!`` for an unknown skill, ``OVF`` for an overflowed
  buffer, ``Low power:6V`` (2.x) or ``check battery`` (1.x) with beeps when the battery is low,
  IMU lines ``yaw\\tpitch\\troll``, and ``k`` lines nobody asked for (fall recovery, the IR remote).
- Speed: 115200 baud on NyBoard V1 (Bittle's board, both firmware versions; the article says
  115200); 57600 on NyBoard V0 and in the article's repository (``bittle_driver.py``).

``ReplyDecoder`` turns the board's bytes into replies (latin-1 text, ``\\r\\n`` lines), dropping
and counting what cannot be a line of the firmware; ``CommandDecoder`` is the board's side, for
the emulator.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass

BAUD = 115200  # the article's, and NyBoard V1's in every OpenCat version
BAUD_V0 = 57600  # NyBoard V0's, and the article's repository's
MAX_LINE = 256  # the longest line the firmware prints is a joint or calibration table row
MAX_COMMAND = 64  # a skill name or a few joint moves; OpenCat 2's buffer is 467 bytes

TOKENS = frozenset("abcdgijkmpsuv?")  # lower-case ASCII tokens a host may send
ACK_TOKENS = frozenset("abcdgijkmpsuvGPV")  # lines a token's acknowledgement can be (`?` is also "unknown skill")
_SKILL = re.compile(rb"[A-Za-z][A-Za-z0-9]{0,15}")
_LOW_POWER = re.compile(r"Low power:\s*(-?\d+)\s*V", re.IGNORECASE)
_IMU = re.compile(r"-?\d+(\.\d+)?\t-?\d+(\.\d+)?\t-?\d+(\.\d+)?")


class CommandError(ValueError):
    """A command that the firmware would not read as meant."""


# -- the host's commands --------------------------------------------------------------------


def skill_command(skill: str) -> bytes:
    """``k<skill>\\n``: run a posture, gait or behaviour by name."""
    raw = skill.encode("ascii", "replace")
    if not _SKILL.fullmatch(raw):
        raise CommandError(f"{skill!r} is not an OpenCat skill name (a letter, then up to 15 letters or digits)")
    return b"k" + raw + b"\n"


def token_command(token: str, *arguments: int) -> bytes:
    """A lower-case token with integer arguments: ``b 12 8\\n``, ``m 0 30\\n``, ``d\\n``."""
    if token not in TOKENS or token == "k":
        raise CommandError(f"{token!r} is not a token this driver sends (skills go through skill_command)")
    if any(not isinstance(a, int) or isinstance(a, bool) or not -32768 <= a <= 32767 for a in arguments):
        raise CommandError(f"arguments of {token!r} are integers of the firmware's int16: {arguments!r}")
    data = (token + "".join(f" {a}" for a in arguments) + "\n").encode("ascii")
    if len(data) > MAX_COMMAND:
        raise CommandError(f"a {len(data)}-byte command: at most {MAX_COMMAND}")
    return data


REST = token_command("d")
PAUSE = token_command("p")
GYRO = token_command("g")
JOINTS = token_command("j")
QUERY = token_command("?")


def beep_command(tone: int, duration: int) -> bytes:
    """``b tone duration``: a tone (1-64, OpenCat's scale) for 1/duration s (2.x) or duration units (1.x)."""
    if not (0 <= tone <= 64 and 1 <= duration <= 64):
        raise CommandError(f"beep {tone} {duration}: tone 0-64, duration 1-64")
    return token_command("b", tone, duration)


def joint_command(moves: dict[int, int], together: bool = True) -> bytes:
    """Joint ``index: angle`` moves (degrees, -125..125), together (``i``, 2.x) or one by one (``m``)."""
    if not moves:
        raise CommandError("no joints to move")
    for index, angle in moves.items():
        if not (0 <= index <= 15 and -125 <= angle <= 125):
            raise CommandError(f"joint {index} to {angle}°: joints 0-15, angles -125..125")
    flat = [value for pair in sorted(moves.items()) for value in pair]
    return token_command("i" if together else "m", *flat)


# -- the board's replies --------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Ack:
    """A token's acknowledgement (or a state echo: G/g gyro, P/p pause)."""

    token: str


@dataclass(frozen=True, slots=True)
class LowBattery:
    """The firmware's low-voltage warning; ``volts`` in whole volts (2.x) or None (1.x)."""

    volts: int | None


@dataclass(frozen=True, slots=True)
class UnknownSkill:
    """``?`` (2.x) or ``wrong key!`` (1.x): the last skill name is not in the board."""


@dataclass(frozen=True, slots=True)
class Overflow:
    """``OVF``: a command overflowed the board's buffer (it then runs ``up``)."""


@dataclass(frozen=True, slots=True)
class Ready:
    """``Ready!``: the board finished booting (2.x)."""


@dataclass(frozen=True, slots=True)
class Attitude:
    """An IMU line: yaw, pitch, roll in degrees."""

    yaw: float
    pitch: float
    roll: float


@dataclass(frozen=True, slots=True)
class Text:
    """Any other printable line: boot text, the model, the version, a table row."""

    text: str


Reply = Ack | LowBattery | UnknownSkill | Overflow | Ready | Attitude | Text


class BadLine(ValueError):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def parse_reply(raw: bytes) -> Reply:
    """One line of the board's output (without its newline; a trailing ``\\r`` is dropped)."""
    line = raw.rstrip(b"\r")
    if any((byte < 0x20 and byte != 0x09) or byte == 0x7F for byte in line):
        raise BadLine("control_bytes")
    if any(byte >= 0x80 for byte in line):
        raise BadLine("not_ascii")
    text = line.decode("ascii").strip()
    if not text:
        return Text("")
    if len(text) == 1 and text in ACK_TOKENS:
        return Ack(text)
    if text == "Ready!":
        return Ready()
    if text in ("?", "wrong key!"):
        return UnknownSkill()
    if text == "OVF":
        return Overflow()
    if text == "check battery":
        return LowBattery(None)
    low = _LOW_POWER.fullmatch(text)
    if low:
        return LowBattery(int(low.group(1)))
    if _IMU.fullmatch(text):
        yaw, pitch, roll = (float(part) for part in text.split("\t"))
        return Attitude(yaw, pitch, roll)
    return Text(text)


def _kind(reply: Reply) -> str:
    return type(reply).__name__.lower()


class ReplyDecoder:
    """The board's bytes to replies: survives partial lines, garbage and lines cut by a reconnection.

    Counters: ``ok`` by reply kind, ``bad`` by reason (``control_bytes``, ``not_ascii``,
    ``too_long``, ``cut``: the first line after a resync that does not parse).
    """

    def __init__(self, max_line: int = MAX_LINE) -> None:
        self.max_line = max_line
        self._partial = b""
        self._discarding = False
        self._first_cut = False
        self.ok: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()

    def resync(self) -> None:
        self._partial = b""
        self._discarding = False
        self._first_cut = True

    def feed(self, data: bytes) -> list[Reply]:
        lines = (self._partial + data).split(b"\n")
        self._partial = lines.pop()
        if len(self._partial) > self.max_line:
            self._partial, self._discarding = b"", True
            self.bad["too_long"] += 1
        replies: list[Reply] = []
        for line in lines:
            if self._discarding:
                self._discarding = False
                continue
            if len(line) > self.max_line:
                self.bad["too_long"] += 1
                continue
            first, self._first_cut = self._first_cut, False
            try:
                reply = parse_reply(line)
            except BadLine as error:
                self.bad["cut" if first else error.reason] += 1
                continue
            self.ok[_kind(reply)] += 1
            replies.append(reply)
        return replies


# -- the board's side (the emulator) --------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Command:
    """One command as the firmware reads it: its token and its text after the token."""

    token: str
    argument: str


class CommandDecoder:
    """Bytes from the host to commands, as OpenCat reads them: a token, then up to a newline.

    A line that does not start with a known token, or is too long, is dropped and counted in
    ``bad`` (the firmware would misread it); ``ok`` counts commands by token.
    """

    def __init__(self) -> None:
        self._partial = b""
        self.ok: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()

    def feed(self, data: bytes) -> list[Command]:
        lines = (self._partial + data).split(b"\n")
        self._partial = lines.pop()
        if len(self._partial) > MAX_COMMAND:
            self._partial = b""
            self.bad["too_long"] += 1
        commands = []
        for raw in lines:
            line = raw.rstrip(b"\r")
            if not line:
                continue
            if len(line) > MAX_COMMAND:
                self.bad["too_long"] += 1
                continue
            token = chr(line[0])
            if token not in TOKENS:
                self.bad["unknown_token"] += 1
                continue
            try:
                argument = line[1:].decode("ascii").strip()
            except UnicodeDecodeError:
                self.bad["not_ascii"] += 1
                continue
            self.ok[token] += 1
            commands.append(Command(token, argument))
        return commands
