"""A microcontroller board on a pseudo-terminal: the plumbing every emulated board shares.

A board emulator plays a robot's firmware on the master side of a pty (``os.openpty``) while the
real driver opens the slave with pyserial, as it would open ``/dev/ttyACM0``. ``PtyBoard`` holds
what does not depend on the firmware:

- **A stable path**: a symlink in a private folder (as udev's ``/dev/serial/by-id`` names a USB
  board) that always points at the current pty, so a driver can reopen the same path after the
  board was unplugged and plugged back in (``unplug``/``replug``/``disconnect(for_s)``: a new pty
  each time, the path appearing and disappearing atomically).
- **The firmware's ``loop()``**: one thread waits on the pty with ``select`` until the next loop
  pass is due, hands the host's bytes to ``_received`` as they come, and calls ``_loop(now, dt)``
  every ``1/loop_hz`` seconds of ``monotonic`` (injectable, for tests) with ``dt`` the time since
  the last pass (at most 0.1 s: a stalled process does not make the world jump). A late pass
  starts the schedule again from now rather than bursting to catch up.
- **The line's faults**: ``inject_garbage`` (random bytes between two lines of the next pass),
  ``drop_lines`` (the next lines are lost), applied by ``_send_lines`` to what a pass prints; and a
  UART's indifference: bytes nobody reads are lost and counted (``bytes_lost``), never queued
  without bound. Every fault's argument is bounded (``MAX_GARBAGE``, ``MAX_DROP``,
  ``MAX_UNPLUG_S``; ``ValueError`` beyond), so a fault never asks for more memory or time than a
  test could want.

A subclass gives the firmware through four hooks: ``_received(data)`` (the host's bytes, in the
board's thread), ``_loop(now, dt)`` (one pass: move the world, print lines through
``_send_lines``), ``_boot(at)`` (the board starts over at ``at``; called on every plug when
``REBOOTS_ON_PLUG``) and ``_plugged()`` (a new link, after the path is in place).
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import shutil
import tempfile
import threading
import time
import tty
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Self

import numpy as np

MAX_GARBAGE = 2**20  # bytes waiting to go out at once: a megabyte is 90 s of a 115200-baud line
MAX_DROP = 1_000_000  # lines (over an hour of a chatty firmware's output)
MAX_UNPLUG_S = 3600.0
MAX_DT = 0.1  # s: the longest step one pass gives the world


class PtyBoard:
    """A board on a pty (see the module). ``start()`` (or a ``with`` block) plugs it in and runs it."""

    REBOOTS_ON_PLUG = False  # whether plugging in (``start``, ``replug``) boots the firmware again

    def __init__(
        self,
        *,
        name: str,
        link_name: str,
        loop_hz: float = 50.0,
        link_dir: Path | None = None,
        seed: int = 0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.name = name
        self.period = 1.0 / loop_hz
        self.rng = np.random.default_rng(seed)  # garbage bytes
        self.monotonic = monotonic
        self._own_dir = link_dir is None
        self.link_dir = Path(tempfile.mkdtemp(prefix=f"botstage-{name}-")) if link_dir is None else link_dir
        self.path = str(self.link_dir / link_name)
        self.pty_path: str | None = None
        self.counters: Counter[str] = Counter()
        self.loops = 0  # passes of the firmware's loop so far (tests wait on it, never on the clock)
        self._fresh_link = True  # nothing heard yet on this link: the next command is its first
        self._master: int | None = None
        self._slave: int | None = None
        self._garbage = b""
        self._drop = 0
        self._replug_at: float | None = None
        self._booting_until = 0.0
        self._fault_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> Self:
        self.replug()
        self._thread = threading.Thread(target=self._run, name=f"{self.name}-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self.unplug()
        if self._own_dir:
            shutil.rmtree(self.link_dir, ignore_errors=True)

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- faults -------------------------------------------------------------------------------

    def inject_garbage(self, count: int) -> None:
        """``count`` random bytes go out between two lines of the next loop (at most ``MAX_GARBAGE``
        waiting at once)."""
        with self._fault_lock:
            waiting = len(self._garbage)
            if not 0 <= count <= MAX_GARBAGE - waiting:
                raise ValueError(f"garbage of {count} bytes: 0 to {MAX_GARBAGE - waiting:,} more may wait to go out")
            self._garbage += self.rng.integers(0, 256, count, dtype=np.uint8).tobytes()

    def drop_lines(self, count: int) -> None:
        """The next ``count`` lines are lost (at most ``MAX_DROP`` waiting)."""
        with self._fault_lock:
            if not 0 <= count <= MAX_DROP - self._drop:
                raise ValueError(f"dropping {count} lines: 0 to {MAX_DROP - self._drop:,} more may wait")
            self._drop += count

    def unplug(self) -> None:
        """The board's USB goes away: the pty closes and the path disappears."""
        with self._fault_lock:
            master, slave, self._master, self._slave = self._master, self._slave, None, None
            self.pty_path = None
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        for fd in (master, slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        if master is not None:
            self.counters["unplugs"] += 1

    def replug(self) -> None:
        """A new pty behind the same path (a board plugged back in)."""
        self.unplug()
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no newline translation before the driver configures it
        os.set_blocking(master, False)
        pty_path = os.ttyname(slave)
        temporary = f"{self.path}.{os.getpid()}.tmp"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(pty_path, temporary)
        os.replace(temporary, self.path)
        with self._fault_lock:
            self._master, self._slave, self.pty_path = master, slave, pty_path
            self._replug_at = None
            self._fresh_link = True
        self.counters["plugs"] += 1
        if self.REBOOTS_ON_PLUG:
            self._boot(self.monotonic())
        self._plugged()

    def disconnect(self, for_s: float) -> None:
        """Unplug now and plug back in after ``for_s`` seconds (more than 0, at most ``MAX_UNPLUG_S``)."""
        if not (math.isfinite(for_s) and 0 < for_s <= MAX_UNPLUG_S):
            raise ValueError(f"unplugged for {for_s} s: more than 0 and at most {MAX_UNPLUG_S:g}")
        self.unplug()
        with self._fault_lock:
            self._replug_at = self.monotonic() + for_s

    # -- the firmware's hooks -----------------------------------------------------------------

    def _boot(self, at: float) -> None:
        """The firmware starts over at ``at`` (its state, its clock, its boot pause)."""
        self._booting_until = at

    def _plugged(self) -> None:
        """A new link is in place (after ``_boot`` when the board reboots on a plug)."""

    def _received(self, data: bytes) -> None:
        """The host's bytes, as they come (in the board's thread)."""
        raise NotImplementedError

    def _loop(self, now: float, dt: float) -> None:
        """One pass of the firmware's ``loop()``, ``dt`` seconds after the last."""
        raise NotImplementedError

    # -- the plumbing -------------------------------------------------------------------------

    def _run(self) -> None:
        next_loop = self.monotonic()
        last_step = next_loop
        while not self._stop.is_set():
            now = self.monotonic()
            if self._replug_at is not None and now >= self._replug_at:
                self.replug()
            master = self._master
            wait = max(0.0, next_loop - now)
            if master is None:
                self._stop.wait(wait)
            else:
                try:
                    ready, _, _ = select.select([master], [], [], wait)
                except (OSError, ValueError):  # closed under us by unplug()
                    continue
                if ready:
                    self._read_commands(master)
            now = self.monotonic()
            if now < next_loop:
                continue
            dt = min(max(now - last_step, 0.0), MAX_DT)
            last_step = now
            self._loop(now, dt)
            self.loops += 1
            next_loop += self.period
            if next_loop < now:  # late: start again from now rather than bursting
                next_loop = now + self.period

    def _read_commands(self, master: int) -> None:
        try:
            data = os.read(master, 4096)
        except BlockingIOError:
            return
        except OSError:  # EIO: nobody holds the slave (cannot happen while we hold it)
            return
        self._received(data)

    def _send_lines(self, lines: list[bytes]) -> None:
        """Print one pass's lines, with the line's faults: the waiting garbage goes out in the
        middle of them, and lines still to drop are lost from the front."""
        with self._fault_lock:
            garbage, self._garbage = self._garbage, b""
            if self._drop:
                dropped = min(self._drop, len(lines))
                self._drop -= dropped
                self.counters["lines_dropped"] += dropped
                lines = lines[dropped:]
        if garbage:
            lines = [*lines[: len(lines) // 2], garbage, *lines[len(lines) // 2 :]]
        self.counters["lines_sent"] += len(lines)
        self._write(b"".join(lines))

    def _write(self, data: bytes) -> None:
        master = self._master
        if master is None or not data:
            return
        try:
            written = os.write(master, data)
        except BlockingIOError:  # nobody reads: a UART's bytes are lost
            written = 0
        except OSError:
            return
        self.counters["bytes_sent"] += written
        self.counters["bytes_lost"] += len(data) - written
