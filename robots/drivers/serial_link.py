"""A robot board on a serial port (pyserial, 8N1): the link every serial driver shares.

A reader thread turns the board's bytes into messages (a protocol's ``Decoder``) and hands each
to a listener (the driver's controller chain); commands are written from any thread under a
lock. What goes wrong on a real robot is handled here, never raised into the mission:

- **Garbage** (noise, a board printing its boot text, a line cut by a reconnection) is the
  decoder's to drop and count by reason; the next good message is parsed.
- **The port disappears** (USB unplugged, board browned out): the read fails, the port is
  closed and reopened with exponential backoff (``backoff`` seconds, doubling) until it is
  back. A board that streams readings and stays silent for ``silence_s`` is treated the same
  way (a hung USB CDC link often needs a reopen); a board that only answers (``silence_s=None``)
  is not.
- **The safe command** (zero speed, a balance posture) goes out first on every (re)connection
  (the board keeps its last command while the PC is away), as a last try on every
  disconnection, and on ``close()`` (also at interpreter exit): nothing keeps a stale command.
  Once closing, ``motion_allowed`` is False and drivers send only the safe command; the last
  word on ``close()`` is the ``parting_command`` (the safe one unless a driver gives another:
  a legged robot lies down).

Warnings are logged at a limited rate (``RateLimitedLog``): a flood of garbage does not flood
the log; the counters in ``stats()`` say how much there was.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, Protocol

import serial

log = logging.getLogger(__name__)


class Decoder(Protocol):
    """A protocol's bytes-to-messages side: keeps partial input, counts what it parsed and dropped."""

    ok: Counter[str]
    bad: Counter[str]

    def feed(self, data: bytes) -> list[Any]: ...

    def resync(self) -> None: ...


class RateLimitedLog:
    """A warning per key at most every ``interval_s``; the ones held back are counted and
    reported with the next one that goes out."""

    def __init__(
        self, logger: logging.Logger, interval_s: float = 5.0, monotonic: Callable[[], float] = time.monotonic
    ) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self.monotonic = monotonic
        self._last: dict[str, float] = {}
        self._held: Counter[str] = Counter()

    def warning(self, key: str, message: str) -> bool:
        now = self.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.interval_s:
            self._held[key] += 1
            return False
        held = self._held.pop(key, 0)
        self._last[key] = now
        self.logger.warning(message + (f" ({held} more like it since the last report)" if held else ""))
        return True


class Listener(Protocol):
    """What the link tells the controller chain; called from the reader thread."""

    def on_message(self, message: Any, received: float) -> None: ...

    def on_connect(self) -> None: ...

    def on_disconnect(self) -> None: ...


class SerialLink:
    """The serial link to one board; see the module."""

    def __init__(
        self,
        port: str,
        decoder: Decoder,
        safe_command: bytes,
        listener: Listener | None = None,
        *,
        name: str = "board",
        parting_command: bytes | None = None,
        baud: int,
        backoff: tuple[float, float] = (0.05, 2.0),
        silence_s: float | None = 2.0,
        read_timeout: float = 0.02,
        start: bool = True,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.port = port
        self.name = name
        self.safe_command = safe_command
        self.parting_command = safe_command if parting_command is None else parting_command
        self.listener = listener
        self.baud = baud
        self.backoff = backoff
        self.silence_s = silence_s
        self.read_timeout = read_timeout
        self.monotonic = monotonic
        self.decoder = decoder
        self.warn = RateLimitedLog(log)
        self.counters: Counter[str] = Counter()
        self._serial: serial.Serial | None = None
        self._write_lock = threading.Lock()
        self._closing = threading.Event()
        self._connected = threading.Event()
        self._motion_allowed = True  # False once closing: only zero goes out
        self._last_rx = 0.0
        self._thread: threading.Thread | None = None
        self._atexit = False
        if start:
            self.start()

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> None:
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name=f"{self.name}-reader {self.port}", daemon=True)
        self._thread.start()
        atexit.register(self.close)
        self._atexit = True

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def wait_connected(self, timeout: float) -> bool:
        return self._connected.wait(timeout)

    def close(self) -> None:
        """The parting command (by default the safe one), stop the reader, close the port. Safe to
        call twice, from any thread."""
        self._motion_allowed = False
        self._write(self.parting_command)
        self._closing.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        with self._write_lock:
            port, self._serial = self._serial, None
        if port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                port.write(self.parting_command)  # anything the listener sent while the reader stopped is overridden
            _close_quietly(port)
        self._connected.clear()
        if self._atexit:
            atexit.unregister(self.close)
            self._atexit = False

    # -- commands -----------------------------------------------------------------------------

    @property
    def motion_allowed(self) -> bool:
        """False once closing: drivers send only the safe command then."""
        return self._motion_allowed

    def send(self, data: bytes) -> bool:
        """Write ``data`` now; False when the port is down (counted) or the write failed."""
        return self._write(data)

    def _write(self, data: bytes) -> bool:
        with self._write_lock:
            port = self._serial
            if port is None:
                self.counters["writes_while_down"] += 1
                return False
            try:
                port.write(data)
            except (serial.SerialException, OSError) as exc:
                self.counters["write_errors"] += 1
                self.warn.warning("write", f"{self.name} {self.port}: write failed: {exc}")
                return False
            self.counters["bytes_out"] += len(data)
            return True

    # -- the reader thread --------------------------------------------------------------------

    def _run(self) -> None:
        delay = self.backoff[0]
        while not self._closing.is_set():
            port = self._serial
            if port is None:
                if self._open():
                    delay = self.backoff[0]
                else:
                    self._closing.wait(delay)
                    delay = min(delay * 2, self.backoff[1])
                continue
            try:
                data = port.read(port.in_waiting or 1)
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                # TypeError/ValueError: pyserial on a port closed under it by close()
                if not self._closing.is_set():
                    self._lost(f"read failed: {exc}")
                continue
            now = self.monotonic()
            if data:
                self._last_rx = now
                self.counters["bytes_in"] += len(data)
                for message in self.decoder.feed(data):
                    self._deliver(message, now)
            elif self.silence_s is not None and now - self._last_rx > self.silence_s:
                self.counters["silences"] += 1
                self._lost(f"no data for {self.silence_s:g} s")

    def _open(self) -> bool:
        try:
            port = serial.Serial(
                self.port,
                self.baud,
                bytesize=serial.EIGHTBITS,
                parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE,
                timeout=self.read_timeout,
                write_timeout=0.5,
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            self.counters["open_failures"] += 1
            self.warn.warning("open", f"{self.name} {self.port}: cannot open: {exc}; retrying")
            return False
        if self._closing.is_set():
            _close_quietly(port)
            return False
        self.decoder.resync()  # the first bytes may be the middle of a line
        with self._write_lock:
            self._serial = port
        self._last_rx = self.monotonic()
        self._write(self.safe_command)  # the board kept whatever it was told before the link went down
        self.counters["connects"] += 1
        if self.counters["connects"] > 1:
            self.warn.warning("reconnect", f"{self.name} {self.port}: reconnected")
        self._connected.set()
        self._notify("on_connect")
        return True

    def _lost(self, why: str) -> None:
        with self._write_lock:
            port, self._serial = self._serial, None
        self._connected.clear()
        if port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                port.write(self.safe_command)  # a last try: a half-broken link may still carry it
            _close_quietly(port)
        self.counters["disconnects"] += 1
        self.warn.warning("lost", f"{self.name} {self.port}: link lost ({why}); reconnecting")
        self._notify("on_disconnect")

    def _deliver(self, message: Any, received: float) -> None:
        if self.listener is None:
            return
        try:
            self.listener.on_message(message, received)
        except Exception as exc:  # a bug in the chain must not stop the reader (and the zeroing)
            self.counters["listener_errors"] += 1
            self.warn.warning("listener", f"{self.name} {self.port}: handling {message!r} failed: {exc!r}")

    def _notify(self, event: str) -> None:
        if self.listener is None:
            return
        try:
            getattr(self.listener, event)()
        except Exception as exc:
            self.counters["listener_errors"] += 1
            self.warn.warning("listener", f"{self.name} {self.port}: {event} failed: {exc!r}")

    def stats(self) -> dict[str, Any]:
        """Counters for reports: lines parsed by kind, lines dropped by reason, link events."""
        return {
            "port": self.port,
            "connected": self.connected,
            "lines_ok": dict(sorted(self.decoder.ok.items())),
            "lines_bad": dict(sorted(self.decoder.bad.items())),
            **dict(sorted(self.counters.items())),
        }


def _close_quietly(port: serial.Serial) -> None:
    with contextlib.suppress(serial.SerialException, OSError):
        port.close()
