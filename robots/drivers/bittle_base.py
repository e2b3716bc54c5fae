"""Bittle on its NyBoard: velocity commands as OpenCat gait tokens, the article's way, made safe.

``cmd_vel`` → ``gaits.choose`` (linear first; the forward gait by |v|; see robots/gaits.py) →
``k<skill>`` on the serial line (``opencat_protocol``), sent when the chosen skill changes, as the
article sends a token only when the direction changes. The board answers each token with its
echo (``k``); what is safe on a real robot, beyond the article, is decided here:

- **Acknowledgements.** A token the board has not acknowledged within ``ack_timeout_s`` is sent
  again (a token lost to line noise, or sent while the board rebooted when the port opened: the
  NyBoard resets on DTR and hears nothing while it boots), so the robot never stays in a gait
  it was told to leave. A skill the board does not know (``?``, ``wrong key!``) is not repeated:
  it is counted and warned about.
- **Watchdog.** With no velocity command for ``watchdog_s`` (profile ``control.watchdog_s``,
  0.5 s) the robot is told to stand (``kbalance``), and stands until the next command.
- **Exit paths.** ``kbalance`` first on every (re)connection and as a last try on every
  disconnection (``SerialLink``'s safe command); on ``close()`` the robot lies down and its
  servos go off (``d``, rest).
- **The board's news.** ``Ready!`` (a reboot: the board is resting) makes the wanted skill go out
  again; ``Low power:6V`` / ``check battery`` are counted and turned into the battery reading
  (the board reports no level otherwise); boot text, state echoes, IMU lines and ``k`` lines
  nobody asked for (fall recovery, the IR remote) are counted and otherwise ignored.

Odometry is dead reckoning from the gait in effect (from its acknowledgement, when the board is
in it) and the profile's speed table (``GaitOdometry``). Readings are stamped with the mission
clock; motion is integrated on the host's monotonic clock, as the robot walks in real time.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from typing import Any

from botstage.robots.clock import Clock
from botstage.robots.drivers import opencat_protocol as opencat
from botstage.robots.drivers.serial_link import RateLimitedLog, SerialLink
from botstage.robots.gaits import Direction, GaitChoice, GaitOdometry, Gaits, choose, motion_of
from botstage.robots.interfaces import BatteryState, OdometryReading, Pose2D
from botstage.robots.profile import Profile

log = logging.getLogger(__name__)

NYBOARD = "nyboard"  # the driver name profiles give (interfaces: {drive: {hardware: nyboard}})
ACK_TIMEOUT_S = 1.0  # an OpenCat 2 gait is acknowledged at its first frame, a posture when reached
SUPERVISE_S = 0.05


class BittleBase:
    """The gait chain and the devices; see the module. ``open_bittle`` builds one on a port."""

    def __init__(
        self,
        link: SerialLink,
        profile: Profile,
        clock: Clock,
        start: Pose2D | None = None,
        *,
        watchdog_s: float | None = None,
        ack_timeout_s: float = ACK_TIMEOUT_S,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        if profile.gaits is None:
            raise ValueError(f"robot {profile.name!r} has no gaits: the NyBoard driver walks in gaits")
        self.link = link
        self.profile = profile
        self.gaits: Gaits = profile.gaits
        self.clock = clock
        self.monotonic = monotonic
        self.watchdog_s = watchdog_s if watchdog_s is not None else profile.control.watchdog_s
        self.ack_timeout_s = ack_timeout_s
        self.base = profile.base
        self.warn = RateLimitedLog(log, monotonic=monotonic)
        self.counters: Counter[str] = Counter()
        self.odometry = GaitOdometry(start)
        self._lock = threading.Lock()
        self._wanted = self.gaits.stop  # the skill the robot should be in
        self._sent: str | None = None  # the last skill sent, and when
        self._sent_at = -math.inf
        self._acked: str | None = None  # the skill the board confirmed it is in
        self._awaiting: deque[str] = deque(maxlen=16)  # skills sent and not acknowledged yet, oldest first
        self._refused: set[str] = set()
        self._last_command = -math.inf
        self._moved_at = monotonic()
        self._low_volts: int | None = None
        self._closing = threading.Event()
        self._supervisor: threading.Thread | None = None
        self.supervised = 0  # the supervisor's passes (a test waits for one to have looked)
        self.devices: dict[str, Any] = {}
        interfaces = profile.interfaces
        for name, device in (("drive", BittleDrive), ("odometry", BittleOdometry), ("battery", BittleBattery)):
            spec = interfaces.get(name)
            if spec is not None and spec.hardware == NYBOARD:
                self.devices[name] = device(self)

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> None:
        self._supervisor = threading.Thread(target=self._supervise, name="bittle-supervisor", daemon=True)
        self._supervisor.start()

    def wait_ready(self, timeout: float) -> bool:
        """True once the link is up (the board may still be booting: tokens are repeated until acknowledged)."""
        return self.link.wait_connected(timeout)

    def close(self) -> None:
        """Stand, then lie down with the servos off (the link's parting command) and close."""
        self.stop()
        self._closing.set()
        if self._supervisor is not None and self._supervisor is not threading.current_thread():
            self._supervisor.join(timeout=2.0)
        self.link.close()

    # -- commands -----------------------------------------------------------------------------

    def cmd_vel(self, v: float, w: float) -> None:
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"a velocity command must be finite, got ({v}, {w})")
        v = max(-self.base.max_linear, min(self.base.max_linear, v))
        w = max(-self.base.max_angular, min(self.base.max_angular, w))
        choice = choose(self.gaits, v, w)
        with self._lock:
            self._last_command = self.monotonic()
            self.counters["commands"] += 1
            self._want(choice)

    def stop(self) -> None:
        with self._lock:
            self._last_command = self.monotonic()
            self._want(GaitChoice(self.gaits.stop, 0.0, 0.0, Direction.STOP))

    def _want(self, choice: GaitChoice) -> None:
        """Under the lock: make ``choice`` the wanted skill, sending it now if it changed."""
        if choice.skill == self._wanted and self._sent == choice.skill:
            return  # the article's rule: a token only on a change
        self._wanted = choice.skill
        self._send_wanted()

    def _send_wanted(self) -> None:
        skill = self._wanted
        if skill in self._refused:
            return
        if not self.link.motion_allowed and skill != self.gaits.stop:
            return
        if self.link.send(opencat.skill_command(skill)):
            if self._sent == skill and self._acked != skill:
                self.counters["resends"] += 1
            self._sent, self._sent_at = skill, self.monotonic()
            self._awaiting.append(skill)
            self.counters["tokens_sent"] += 1

    # -- the supervisor thread: watchdog and unacknowledged tokens ----------------------------

    def _supervise(self) -> None:
        while not self._closing.wait(SUPERVISE_S):
            now = self.monotonic()
            with self._lock:
                self._integrate(now)
                if now - self._last_command > self.watchdog_s and self._wanted != self.gaits.stop:
                    self.counters["watchdog_stops"] += 1
                    self.warn.warning("watchdog", f"bittle: no command for {self.watchdog_s:g} s: standing")
                    self._wanted = self.gaits.stop
                    self._send_wanted()
                elif self._acked != self._wanted and now - self._sent_at > self.ack_timeout_s:
                    self._send_wanted()
                self.supervised += 1

    def _integrate(self, now: float) -> None:
        """Under the lock: move the estimate on in the gait the board is in."""
        v, w = motion_of(self.gaits, self._acked) if self._acked is not None else (0.0, 0.0)
        self.odometry.advance(now - self._moved_at, v, w)
        self._moved_at = now

    # -- the link's listener (the reader thread) ----------------------------------------------

    def on_message(self, reply: opencat.Reply, received: float) -> None:
        with self._lock:
            self._integrate(received)
            match reply:
                case opencat.Ack(token="k"):  # the oldest token in flight is done (the board takes them in order)
                    if self._awaiting:
                        skill = self._awaiting.popleft()
                        if skill not in self._refused:
                            self._acked = skill
                            self.counters["acks"] += 1
                    else:
                        self.counters["acks_unasked"] += 1  # fall recovery, the IR remote
                case opencat.Ack(token=token):
                    self.counters[f"echo_{token}"] += 1
                case opencat.UnknownSkill():  # about the oldest token in flight (its "k" follows)
                    skill = self._awaiting[0] if self._awaiting else self._sent
                    self.counters["unknown_skills"] += 1
                    if skill is not None:
                        self._refused.add(skill)
                        self.warn.warning("unknown", f"bittle: the board does not know the skill {skill!r}")
                case opencat.Ready():
                    self.counters["board_boots"] += 1
                    self._acked = None  # it rests after booting: the wanted skill goes out again
                    self._awaiting.clear()
                    self._sent_at = -math.inf
                case opencat.LowBattery(volts=volts):
                    self.counters["low_battery_warnings"] += 1
                    self._low_volts = volts if volts is not None else int(self.profile.battery.empty_voltage)
                    self.warn.warning("battery", f"bittle: the board reports a low battery ({volts} V)")
                case opencat.Overflow():
                    self.counters["board_overflows"] += 1
                case _:
                    pass

    def on_connect(self) -> None:
        with self._lock:
            self._acked = None
            self._awaiting.clear()
            self._sent_at = -math.inf  # the supervisor sends the wanted skill (balance went out already)

    def on_disconnect(self) -> None:
        with self._lock:
            self._integrate(self.monotonic())
            self._acked = None  # the robot stands (the link's last try) or has lost power: not walking
            self._awaiting.clear()

    # -- readings -----------------------------------------------------------------------------

    def read_odometry(self) -> OdometryReading:
        with self._lock:
            self._integrate(self.monotonic())
            return OdometryReading(self.clock.now(), self.odometry.pose, self.odometry.twist, self.odometry.covariance)

    def read_battery(self) -> BatteryState:
        """No level is reported: full until the board warns, then the volts it printed."""
        battery = self.profile.battery
        with self._lock:
            volts = self._low_volts
        if volts is None:
            return BatteryState(self.clock.now(), battery.nominal_voltage, 100.0)
        span = battery.full_voltage - battery.empty_voltage
        percent = max(0.0, min(100.0, 100.0 * (volts - battery.empty_voltage) / span))
        return BatteryState(self.clock.now(), float(volts), percent)

    def summary(self) -> dict[str, Any]:
        with self._lock:
            pose = self.odometry.pose
            return {
                **self.link.stats(),
                **dict(sorted(self.counters.items())),
                "skill": self._acked,
                "refused_skills": sorted(self._refused),
                "odometry_pose": [round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)],
                "odometry_distance_m": round(self.odometry.distance, 4),
            }


class BittleDrive:
    def __init__(self, base: BittleBase) -> None:
        self.base = base

    def cmd_vel(self, v: float, w: float) -> None:
        self.base.cmd_vel(v, w)

    def stop(self) -> None:
        self.base.stop()


class BittleOdometry:
    measured = False  # reckoned from the acknowledged gaits: it cannot tell a blocked robot from a walking one

    def __init__(self, base: BittleBase) -> None:
        self.base = base

    def read(self) -> OdometryReading:
        return self.base.read_odometry()


class BittleBattery:
    def __init__(self, base: BittleBase) -> None:
        self.base = base

    def read(self) -> BatteryState:
        return self.base.read_battery()


def open_bittle(
    port: str,
    profile: Profile,
    clock: Clock,
    start: Pose2D | None = None,
    *,
    baud: int = opencat.BAUD,
    watchdog_s: float | None = None,
    ack_timeout_s: float = ACK_TIMEOUT_S,
    monotonic: Callable[[], float] = time.monotonic,
    **link_options: Any,
) -> BittleBase:
    """The chain on a port: the link's reader and the supervisor running (call ``close()``)."""
    stop = profile.gaits.stop if profile.gaits is not None else "balance"
    link = SerialLink(
        port,
        opencat.ReplyDecoder(),
        opencat.skill_command(stop),
        name="nyboard",
        parting_command=opencat.REST,
        baud=baud,
        silence_s=None,  # the board speaks only when spoken to
        start=False,
        monotonic=monotonic,
        **link_options,
    )
    base = BittleBase(
        link, profile, clock, start, watchdog_s=watchdog_s, ack_timeout_s=ack_timeout_s, monotonic=monotonic
    )
    link.listener = base
    link.start()
    base.start()
    return base
