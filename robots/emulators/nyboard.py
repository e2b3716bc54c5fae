"""Petoi's NyBoard V1 running OpenCat 2.x (Bittle's board) on a pseudo-terminal, walking the simulated Bittle.

The emulator is a ``PtyBoard`` (``pty_board.py``): the driver opens its stable path with
pyserial at 115200 baud and speaks OpenCat's ASCII tokens (``robots/drivers/opencat_protocol.py``,
whose ``CommandDecoder`` reads the host's bytes here). Its thread plays the firmware's ``loop()``
at ``loop_hz`` (decision: 50 Hz), **steps the World by the wall-clock time since its last loop**
under ``world_lock`` (the only thread that moves the world), with ``extra_steps`` (people) after
it, and commands the body every loop with ``motion_of(gaits, skill)``: the profile's gait table
says how fast each gait goes; a posture, a behaviour, a gait the table does not list, a pause, a
transition, the boot and a low-power stall stand still.

What the firmware does, from Petoi's OpenCat 2.x sources (see the protocol module and the
research notes it cites):

- **Boot** (on every plug, as a USB adapter's DTR pulse resets the ATmega; and on
  ``board_reset``): a lone ``k``, an empty line and ``* Start *``, ``Bittle``, the version
  (``N_250224``), ``Init IMU``; then, ``boot_s`` later, ``Skill`` and ``Ready!``, and the implicit
  rest (``g``, ``d``). Lines end in ``\\r\\n`` (Arduino's ``println``). Until ``Ready!`` the board
  hears nothing: bytes are dropped (``bytes_ignored``). Opening the port does *not* reset the
  board (a pty has no DTR line, and the article's Raspberry Pi UART none either), so a driver
  that opens it after the boot sees none of the boot text: it must ask (``?``).
- **Commands** end at their newline (OpenCat 2 also ends one after 5 ms of silence: not
  emulated, a driver writes each command whole, newline included) and are taken from a 64-byte
  receive buffer (the Arduino's), one after another; a command the firmware is busy with blocks
  those behind it, and what overflows the buffer meanwhile is lost (``commands_lost``). Every
  command's token comes back as its acknowledgement when it is done (2.x), preceded by ``G`` for
  the first command after a rest or calibration (except ``c``) and by ``p`` for any but ``p``
  while paused (which resumes).
- ``k<name>``: 2.x's name matching, in the firmware's skill order: an exact name, or any name
  sharing an ``…L`` skill's stem (``kwk`` and ``kwkR`` both match ``wkL``); a name ending in ``R``
  runs that skill mirrored (``crR`` turns clockwise). A posture or gait is acknowledged
  ``ack_delay_s`` later (the transition to its first frame; the body stands meanwhile); the gait
  it is already in is acknowledged at once and not restarted. A behaviour (``hi``, ``pu``…) keeps
  the board busy for ``behaviour_s``, is acknowledged at its end, and the board goes back to the
  posture or gait it was in (decision: as the firmware reloads the last gait after a fall
  recovery; from rest it stands, in ``balance``, since a behaviour ends on its feet). An unknown
  name prints ``?`` and keeps the skill, then ``k`` (2.x checks the period of the skill it kept).
- ``d`` rests (servos off): ``g`` at once, ``d`` after the transition. ``p`` pauses (``P``,
  servos off) and resumes (``p``). ``g`` toggles the gyro (``G`` on, ``g`` off). ``b …`` beeps
  (``b``). ``m``/``i`` with index-angle pairs (joints 0-15, -125..125°) move joints (their token;
  bad pairs move nothing and count as ``bad_arguments``). ``j`` prints ``=``, the joint indices
  and angles (tab-separated rows), then ``j``; ``j N`` one angle. ``c`` enters calibration
  (``calib``), applies index-offset pairs, prints the offset table, then ``c``; ``s`` (``saved``)
  keeps the offsets, ``a`` (``aborted``) restores the saved ones. ``u`` answers ``u``. ``v``
  prints ``yaw\\tpitch\\troll`` in degrees (yaw from the world's IMU since boot: the DMP knows no
  heading; pitch and roll 0 on a flat floor), then ``v``. ``?`` prints ``Bittle``, the version,
  then ``?``. The joints' angles are only those ``m``/``i`` set (skills' frames are not modelled).
- **Low battery**: every ``battery_check_s`` (10 s in the firmware) the board reads its voltage;
  under 650/99 V (ADC 650 on A7) it prints ``Low power:<volts>V`` (whole volts) and blocks its
  loop for 2 s: the body stops, commands wait. (The firmware also wants two equal readings in a
  row; the simulated voltage is smooth, so one reading decides.)
- **Faults**: from ``PtyBoard``, ``inject_garbage``, ``drop_lines``, ``unplug``/``replug``/
  ``disconnect`` (the board, on Bittle's battery, goes on with its skill while unplugged, and
  boots again when plugged back in); here, ``board_reset``. ``first_commands`` keeps the first
  command heard on each link (a driver should say something safe first, such as ``kbalance`` or
  ``d``).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from botstage.robots.drivers.opencat_protocol import Command, CommandDecoder
from botstage.robots.emulators.pty_board import MAX_DROP, MAX_GARBAGE, MAX_UNPLUG_S, PtyBoard
from botstage.robots.gaits import Gaits, motion_of
from botstage.robots.sim.world import World

__all__ = [
    "BEHAVIOURS",
    "GAITS",
    "LOW_VOLTAGE_V",
    "MAX_DROP",
    "MAX_GARBAGE",
    "MAX_UNPLUG_S",
    "MODEL",
    "POSTURES",
    "SKILLS",
    "VERSION",
    "NyBoardEmulator",
    "resolve_skill",
]

MODEL = "Bittle"
VERSION = "N_250224"  # recent 2.x's SOFTWARE_VERSION
LOW_VOLTAGE_V = 650 / 99  # LOW_VOLTAGE (ADC counts on A7) over the firmware's 99 counts a volt: about 6.57 V
LOW_POWER_STALL_S = 2.0  # the firmware's delay(2000) after the warning
RX_BUFFER = 64  # bytes: the Arduino's serial receive buffer
JOINTS = 16
JOINT_LIMIT = 125  # degrees: what OpenCat's protocol carries (126 is the binary terminator)
MAX_DELAY_S = 60.0  # the longest boot, transition or behaviour the emulator accepts
MAX_LOOP_HZ = 1000.0
MAX_BATTERY_CHECK_S = 3600.0

# Bittle's skills in OpenCat 2.x (src/InstinctBittle.h), in the firmware's order: its name
# matching takes the first that fits. Right-hand gaits are the left ones mirrored.
GAITS = ("bdF", "bk", "bkL", "crF", "crL", "hlw", "mhF", "mhL", "pcF", "phF", "phL", "trF", "trL", "vtF", "vtL")
GAITS += ("wkF", "wkL")
POSTURES = ("balance", "buttUp", "calib", "dropped", "lifted", "rest", "sit", "str", "zero")
BEHAVIOURS = ("bf", "ck", "climbCeil", "cmh", "fd", "ff", "hi", "jmp", "jy", "kcL", "nd", "pd", "pee", "pu", "pu1")
BEHAVIOURS += ("rc", "rlL", "rt", "sh", "stand", "stp", "ts")
SKILLS = GAITS + POSTURES + BEHAVIOURS
STAND = "balance"  # where a behaviour started from rest ends

_BOOT_START = [b"k\r\n", b"\n* Start *\r\n", b"%s\r\n" % MODEL.encode()]  # then the version, "Init IMU"


def resolve_skill(key: str) -> tuple[str, str] | None:
    """The skill OpenCat 2.x runs for ``k<key>`` and its kind (``gait``, ``posture``, ``behaviour``),
    or None (``?``).

    The firmware's test (``src/skill.h``), in its skill order: the name equals the key, or the
    name ends in ``L`` and the key starts with the name's stem (``strncmp`` over the name's length
    less one). A key ending in ``R`` runs the skill mirrored: its name then ends in ``R``.
    """
    for name in SKILLS:
        stem = name[:-1]
        if name == key or (name.endswith("L") and key[: len(stem)] == stem):
            kind = "gait" if name in GAITS else "posture" if name in POSTURES else "behaviour"
            mirrored = name.endswith("L") and key.endswith("R")
            return (stem + "R" if mirrored else name), kind
    return None


@dataclass
class _Busy:
    """What the firmware is doing (a transition, a behaviour): until when, what it prints at the
    end, and the skill it then goes back to (a behaviour's return)."""

    until: float
    ack: str
    then: str | None = None


def _bounded(name: str, value: float, low: float, high: float, *, open_low: bool = False) -> float:
    if not (math.isfinite(value) and (low < value if open_low else low <= value) and value <= high):
        above = f"more than {low:g}" if open_low else f"at least {low:g}"
        raise ValueError(f"{name} = {value}: {above} and at most {high:g}")
    return value


def _table(values: list[int]) -> list[bytes]:
    """The firmware's two-row table: indices, then values, tab-separated."""
    return [
        "\t".join(str(i) for i in range(len(values))).encode() + b"\r\n",
        "\t".join(str(v) for v in values).encode() + b"\r\n",
    ]


class NyBoardEmulator(PtyBoard):
    """The board; see the module. ``start()`` (or a ``with`` block) plugs it in, boots it and runs it."""

    REBOOTS_ON_PLUG = True

    def __init__(
        self,
        world: World,
        *,
        world_lock: threading.Lock | None = None,
        loop_hz: float = 50.0,
        boot_s: float = 0.5,
        ack_delay_s: float = 0.05,
        behaviour_s: float = 1.0,
        battery_check_s: float = 10.0,
        version: str = VERSION,
        link_dir: Path | None = None,
        extra_steps: list[Callable[[float], None]] | None = None,
        seed: int = 0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        gaits = world.profile.gaits
        if gaits is None:
            raise ValueError(f"the NyBoard walks a legged robot: profile {world.profile.name!r} has no gaits")
        _bounded("loop_hz", loop_hz, 0, MAX_LOOP_HZ, open_low=True)
        self.boot_s = _bounded("boot_s", boot_s, 0, MAX_DELAY_S)
        self.ack_delay_s = _bounded("ack_delay_s", ack_delay_s, 0, MAX_DELAY_S)
        self.behaviour_s = _bounded("behaviour_s", behaviour_s, 0, MAX_DELAY_S)
        self.battery_check_s = _bounded("battery_check_s", battery_check_s, 0, MAX_BATTERY_CHECK_S, open_low=True)
        if not version.isprintable() or not 0 < len(version) <= 32:
            raise ValueError(f"version {version!r}: 1 to 32 printable characters")
        super().__init__(
            name="nyboard",
            link_name="ttyNyBoard",
            loop_hz=loop_hz,
            link_dir=link_dir,
            seed=seed,
            monotonic=monotonic,
        )
        self.world = world
        self.lock = world_lock or threading.Lock()
        self.gaits: Gaits = gaits
        self.version = version
        self.extra_steps = list(extra_steps or [])
        self.first_commands: list[str] = []  # the first command heard on each link, as sent ("kbalance", "d")
        self._queue: deque[tuple[Command, int]] = deque()  # commands waiting, with their size in bytes
        self._queued_bytes = 0
        self._reset(monotonic())  # the state it boots into (the first plug boots it)

    # -- state --------------------------------------------------------------------------------

    @property
    def ready(self) -> bool:
        """The boot is over and ``Ready!`` printed."""
        return self._boot_stage == 2

    @property
    def motion(self) -> tuple[float, float]:
        """What the board has the body do now: (v m/s, w rad/s)."""
        return self._motion(self.monotonic())

    def board_reset(self) -> None:
        """The reset button (or a DTR pulse): the board boots again, deaf until ``Ready!``."""
        self._boot(self.monotonic())
        self.counters["resets"] += 1

    # -- the firmware -------------------------------------------------------------------------

    def _reset(self, at: float) -> None:
        self.decoder = CommandDecoder()
        self._queue.clear()
        self._queued_bytes = 0
        self.skill = "rest"  # the implicit rest at the end of the boot
        self.paused = False
        self.gyro = True
        self.joints = [0] * JOINTS
        self.offsets = [0] * JOINTS  # calibration
        self._saved_offsets = [0] * JOINTS
        self._last_token = "d"
        self._busy: _Busy | None = None
        self._stalled_until = -math.inf
        self._booted_at = at
        self._booting_until = at + self.boot_s
        self._boot_stage = 0  # 0: nothing printed yet, 1: the first lines printed, 2: ready
        self._next_battery = at + self.battery_check_s
        self._imu_zero = self.world.imu_yaw

    def _boot(self, at: float) -> None:
        with self.lock:
            self._reset(at)
        self.counters["boots"] += 1

    def _received(self, data: bytes) -> None:
        self.counters["bytes_received"] += len(data)
        with self.lock:
            if self.monotonic() < self._booting_until:
                self.counters["bytes_ignored"] += len(data)  # a booting board hears nothing
                return
            bad = sum(self.decoder.bad.values())
            commands = self.decoder.feed(data)
            self.counters["bad_commands"] += sum(self.decoder.bad.values()) - bad
            for command in commands:
                text = command.token + (command.argument if command.token == "k" else f" {command.argument}".rstrip())
                if self._fresh_link:
                    self._fresh_link = False
                    self.first_commands.append(text)
                self.counters[f"command_{command.token}"] += 1
                size = len(text) + 1
                if self._queued_bytes + size > RX_BUFFER:  # the receive buffer is full: the bytes are lost
                    self.counters["commands_lost"] += 1
                    continue
                self._queue.append((command, size))
                self._queued_bytes += size

    def _motion(self, now: float) -> tuple[float, float]:
        if (
            self._boot_stage < 2
            or now < self._booting_until
            or now < self._stalled_until
            or self.paused
            or self._busy is not None
        ):
            return 0.0, 0.0
        return motion_of(self.gaits, self.skill)

    def _loop(self, now: float, dt: float) -> None:
        """One pass of the firmware's loop(): read and do commands, then move the world."""
        lines: list[bytes] = []
        with self.lock:
            self._firmware(now, lines)
            world = self.world
            world.cmd_vel(*self._motion(now))
            if dt > 0:
                world.step(dt)
                for step in self.extra_steps:
                    step(dt)
        self._send_lines(lines)

    def _firmware(self, now: float, lines: list[bytes]) -> None:
        if self._boot_stage == 0:
            lines += [*_BOOT_START, self.version.encode() + b"\r\n", b"Init IMU\r\n"]
            self._boot_stage = 1
        if now < self._booting_until:
            return
        if self._boot_stage == 1:
            lines += [b"Skill\r\n", b"Ready!\r\n", b"g\r\n", b"d\r\n"]  # and the implicit rest
            self._boot_stage = 2
        if now < self._stalled_until:
            return  # delay(2000): the loop is blocked
        if now >= self._next_battery:
            self._next_battery = max(self._next_battery + self.battery_check_s, now)
            volts = self.world.battery_voltage
            if volts < LOW_VOLTAGE_V:
                lines.append(b"Low power:%dV\r\n" % int(volts))
                self.counters["low_power"] += 1
                self._stalled_until = now + LOW_POWER_STALL_S
                if self._busy is not None:
                    self._busy.until += LOW_POWER_STALL_S
                return
        while True:
            busy = self._busy
            if busy is not None:
                if now < busy.until:
                    return
                self._busy = None
                self._ack(lines, busy.ack)
                if busy.then is not None:
                    self.skill = busy.then
            if not self._queue:
                return
            command, size = self._queue.popleft()
            self._queued_bytes -= size
            self._handle(command, now, lines)

    def _ack(self, lines: list[bytes], token: str) -> None:
        lines.append(token.encode() + b"\r\n")
        self.counters["acks"] += 1

    def _handle(self, command: Command, now: float, lines: list[bytes]) -> None:
        token, argument = command.token, command.argument
        if self._last_token in ("c", "d") and token != "c":
            self.gyro = True
            lines.append(b"G\r\n")
        if token != "p" and self.paused:
            self.paused = False
            lines.append(b"p\r\n")
        self._last_token = token
        if token == "k":
            self._skill(argument, now, lines)
        elif token == "d":
            self.gyro = False
            lines.append(b"g\r\n")
            self.skill = "rest"
            self._busy = _Busy(now + self.ack_delay_s, "d")
        elif token == "p":
            self.paused = not self.paused
            self._ack(lines, "P" if self.paused else "p")
        elif token == "g":
            self.gyro = not self.gyro
            self._ack(lines, "G" if self.gyro else "g")
        elif token in ("m", "i"):
            moves = self._pairs(argument, range(JOINTS))
            for index, angle in moves or []:
                self.joints[index] = angle
            self._ack(lines, token)
        elif token == "j":
            self._joints(argument, lines)
        elif token == "c":
            self.skill = "calib"
            for index, offset in self._pairs(argument, range(JOINTS)) or []:
                self.offsets[index] = offset
            lines += _table(self.offsets)
            self._ack(lines, "c")
        elif token == "s":
            self._saved_offsets = list(self.offsets)
            lines.append(b"saved\r\n")
            self._ack(lines, "s")
        elif token == "a":
            self.offsets = list(self._saved_offsets)
            lines.append(b"aborted\r\n")
            self._ack(lines, "a")
        elif token == "v":
            yaw = math.degrees(math.remainder(self.world.imu_yaw - self._imu_zero, 2 * math.pi))
            lines.append(b"%.2f\t%.2f\t%.2f\r\n" % (yaw, 0.0, 0.0))
            self._ack(lines, "v")
        elif token == "?":
            lines += [MODEL.encode() + b"\r\n", self.version.encode() + b"\r\n"]
            self._ack(lines, "?")
        else:  # b (a beep), u (a meow): nothing the simulation shows
            self._ack(lines, token)

    def _skill(self, key: str, now: float, lines: list[bytes]) -> None:
        resolved = resolve_skill(key)
        if resolved is None:
            self.counters["unknown_skills"] += 1
            lines.append(b"?\r\n")
            self._ack(lines, "k")  # 2.x confirms anyway: the skill it kept has a period above 0
            return
        name, kind = resolved
        if kind == "gait" and name == self.skill:
            self._ack(lines, "k")  # the same gait is not reloaded
            return
        if kind == "behaviour":
            back = STAND if self.skill == "rest" else self.skill
            self.skill = name
            self._busy = _Busy(now + self.behaviour_s, "k", then=back)
        else:
            self.skill = name
            self._busy = _Busy(now + self.ack_delay_s, "k")

    def _pairs(self, argument: str, indices: range) -> list[tuple[int, int]] | None:
        """``index value`` pairs (spaces, commas or tabs between), or None (counted) when they are not."""
        words = argument.replace(",", " ").split()
        try:
            numbers = [int(word) for word in words]
        except ValueError:
            numbers = None
        if (
            numbers is None
            or len(numbers) % 2
            or any(
                index not in indices or not -JOINT_LIMIT <= value <= JOINT_LIMIT
                for index, value in zip(numbers[::2], numbers[1::2], strict=True)
            )
        ):
            self.counters["bad_arguments"] += 1
            return None
        return list(zip(numbers[::2], numbers[1::2], strict=True))

    def _joints(self, argument: str, lines: list[bytes]) -> None:
        if not argument:
            lines += [b"=\r\n", *_table(self.joints)]
        elif argument.isdigit() and int(argument) < JOINTS:
            lines += [b"=\r\n", b"%d\r\n" % self.joints[int(argument)]]
        else:
            self.counters["bad_arguments"] += 1
        self._ack(lines, "j")
