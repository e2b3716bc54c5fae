"""Test helpers for the Launchpad: the board's end of a real pty, written and read byte by byte."""

from __future__ import annotations

import contextlib
import os
import select
import time
import tty
from collections.abc import Callable
from pathlib import Path

from robots.profile import Profile, load_profile, profile_path


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

    def wait_for(self, predicate: Callable[[bytes], bool], timeout: float = 5.0) -> bool:
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


def wait_until(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
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
