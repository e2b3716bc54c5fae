"""Test helpers for the Launchpad: the board's end of a real pty, written and read byte by byte,
and waits on what the driver has handled.

Nothing here waits for a length of time: every wait is for a condition or an event, with a
generous deadline that is only a failsafe (a test that hits it has failed, however slow the
machine is).
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from botstage.robots.drivers.launchpad_protocol import Message
from botstage.robots.profile import Profile, load_profile, profile_path

FAILSAFE_S = 30.0  # the longest any wait may take before the test fails


def chefbot() -> Profile:
    profile, problems, _ = load_profile(profile_path("chefbot"))  # type: ignore[arg-type]
    assert profile is not None, problems
    return profile


class Board:
    """A pty whose slave has a stable path (a symlink, as udev names a USB board); the test
    plays the board on the master."""

    def __init__(self, folder: Path) -> None:
        self.path = str(folder / "ttyTEST")
        self.master: int | None = None
        self.slave: int | None = None
        self.received = b""
        self.plug()

    def plug(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        temporary = self.path + ".tmp"
        os.symlink(os.ttyname(self.slave), temporary)
        os.replace(temporary, self.path)
        self.received = b""

    def unplug(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        for fd in (self.master, self.slave):
            if fd is not None:
                os.close(fd)
        self.master = self.slave = None

    def send(self, data: bytes) -> None:
        """Write all of ``data``, waiting while the driver has not read enough of it."""
        assert self.master is not None
        view = memoryview(data)
        while view:
            select.select([], [self.master], [], 1.0)
            try:
                written = os.write(self.master, view[:4096])
            except BlockingIOError:
                continue
            view = view[written:]

    def read(self) -> bytes:
        assert self.master is not None
        while select.select([self.master], [], [], 0)[0]:
            try:
                chunk = os.read(self.master, 4096)
            except (BlockingIOError, OSError):
                break
            if not chunk:
                break
            self.received += chunk
        return self.received

    def wait_for(self, predicate: Callable[[bytes], bool], timeout: float = FAILSAFE_S) -> bool:
        """Bounded wait until what the driver sent satisfies ``predicate``."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate(self.read()):
                return True
            time.sleep(0.005)
        return predicate(self.read())

    def close(self) -> None:
        if self.master is not None:
            self.unplug()


def wait_until(condition: Callable[[], bool], timeout: float = FAILSAFE_S) -> bool:
    """Poll ``condition`` (state that no event announces, like the simulated wheels) until it holds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return condition()


def commands(data: bytes) -> list[tuple[int, int]]:
    """The speed commands in what the driver sent."""
    found = []
    for part in data.split(b"\r"):
        fields = part.split()
        if len(fields) == 3 and fields[0] == b"s":
            found.append((int(fields[1]), int(fields[2])))
    return found


class Delivered:
    """Stands between a link and its listener and counts the messages handed over, by kind.

    The decoder counts a line as soon as it parses it, before the listener has handled it; a
    test that wants to read what the driver made of a line waits here instead, on an event.
    """

    def __init__(self, link: Any) -> None:
        self.link = link
        self.listener = link.listener
        self.counts: Counter[str] = Counter()
        self._changed = threading.Condition()
        link.listener = self

    def on_message(self, message: Message, received: float) -> None:
        self.listener.on_message(message, received)
        self._count(type(message).__name__)

    def on_connect(self) -> None:
        self.listener.on_connect()
        self._count("connect")

    def on_disconnect(self) -> None:
        self.listener.on_disconnect()
        self._count("disconnect")

    def _count(self, kind: str) -> None:
        with self._changed:
            self.counts[kind] += 1
            self._changed.notify_all()

    def reached(self, kind: str, count: int, timeout: float = FAILSAFE_S) -> bool:
        """Wait until ``count`` messages of ``kind`` (a message class name) have been handled."""
        with self._changed:
            return self._changed.wait_for(lambda: self.counts[kind] >= count, timeout)

    def more(self, kind: str, count: int = 1, timeout: float = FAILSAFE_S) -> bool:
        """Wait until ``count`` more messages of ``kind`` than now have been handled."""
        with self._changed:
            target = self.counts[kind] + count
        return self.reached(kind, target, timeout)
