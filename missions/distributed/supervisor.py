"""Start a set of processes, show their state and output, and stop them all together.

What ``botstage up`` needs of the processes of a deployment, and nothing about what they run: each
is a command line with a name. Their output is read line by line on threads and handed to
``on_line(name, line)`` (the console prefixes it with the name); ``states()`` says which are
starting, running or ended and how. ``stop()`` asks every process to end (SIGINT, as Ctrl-C in
its own terminal would), waits ``grace`` seconds, then terminates and finally kills what is left,
so no child outlives the supervisor. Processes are started in the order given and stopped in
the reverse order (the mission first, the robot last: the robot stops the drive when commands
end).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import IO

LineSink = Callable[[str, str], None]
GRACE_S = 5.0
MAX_LINE = 64 * 1024  # a process that prints without newlines cannot grow our memory without bound


@dataclass
class Child:
    """One process: its command, its Popen, and how it ended."""

    name: str
    command: list[str]
    popen: subprocess.Popen[bytes] | None = None
    returncode: int | None = None
    readers: list[threading.Thread] = field(default_factory=list)

    @property
    def state(self) -> str:
        if self.popen is None:
            return "not started"
        code = self.popen.poll()
        if code is None:
            return "running"
        if code < 0:
            return f"killed by {signal.Signals(-code).name}"
        return "exited" if code == 0 else f"failed (exit {code})"


class Supervisor:
    """Starts named commands, relays their output, and stops them together."""

    def __init__(
        self,
        commands: Mapping[str, Sequence[str]],
        on_line: LineSink,
        *,
        env: Mapping[str, str] | None = None,
        cwd: str | None = None,
    ) -> None:
        self.children = [Child(name, list(command)) for name, command in commands.items()]
        self.on_line = on_line
        self.env = dict(os.environ if env is None else env)
        self.cwd = cwd

    def start(self) -> None:
        """Start every process, in order; one that cannot start stops those already started."""
        try:
            for child in self.children:
                child.popen = subprocess.Popen(
                    child.command,
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    env=self.env,
                    cwd=self.cwd,
                    start_new_session=True,  # Ctrl-C in our terminal reaches us only: we stop them in order
                )
                reader = threading.Thread(target=self._relay, args=(child,), name=f"relay-{child.name}", daemon=True)
                reader.start()
                child.readers.append(reader)
        except OSError:
            self.stop()
            raise

    def _relay(self, child: Child) -> None:
        assert child.popen is not None and child.popen.stdout is not None
        stream: IO[bytes] = child.popen.stdout
        for raw in iter(lambda: stream.readline(MAX_LINE), b""):
            self.on_line(child.name, raw.decode("utf-8", "replace").rstrip("\r\n"))

    def states(self) -> dict[str, str]:
        return {child.name: child.state for child in self.children}

    def ended(self) -> list[Child]:
        """Processes that have ended by now."""
        return [c for c in self.children if c.popen is not None and c.popen.poll() is not None]

    def wait_any(self, timeout: float, poll_s: float = 0.1) -> Child | None:
        """The first process to end within ``timeout`` seconds, or None."""
        deadline = time.monotonic() + timeout
        pause = threading.Event()
        while True:
            ended = self.ended()
            if ended:
                return ended[0]
            if time.monotonic() >= deadline:
                return None
            pause.wait(poll_s)

    def wait(self, name: str, timeout: float | None = None) -> int:
        """Wait for one process to end; its exit code."""
        child = self._child(name)
        assert child.popen is not None
        code = child.popen.wait(timeout)
        self._finish(child)
        return code

    def _child(self, name: str) -> Child:
        for child in self.children:
            if child.name == name:
                return child
        raise KeyError(f"no process {name!r} (have: {', '.join(c.name for c in self.children)})")

    def signal(self, name: str, signum: int) -> None:
        """Send ``signum`` to one process (fault drills: SIGKILL a skills process)."""
        child = self._child(name)
        if child.popen is not None and child.popen.poll() is None:
            child.popen.send_signal(signum)

    def restart(self, name: str) -> None:
        """Start one ended process again with the same command."""
        child = self._child(name)
        if child.popen is not None and child.popen.poll() is None:
            raise RuntimeError(f"{name} is still running")
        self._finish(child)
        index = self.children.index(child)
        fresh = Child(child.name, child.command)
        self.children[index] = fresh
        saved, self.children = self.children, [fresh]
        try:
            self.start()
        finally:
            self.children = saved

    def stop(self, grace: float = GRACE_S) -> dict[str, int | None]:
        """Stop every process (reverse order): SIGINT, then SIGTERM, then SIGKILL; their exit codes."""
        running = [c for c in reversed(self.children) if c.popen is not None and c.popen.poll() is None]
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            for child in running:
                assert child.popen is not None
                with contextlib.suppress(ProcessLookupError):
                    child.popen.send_signal(signum)
            deadline = time.monotonic() + grace
            for child in running:
                assert child.popen is not None
                with contextlib.suppress(subprocess.TimeoutExpired):
                    child.popen.wait(max(0.0, deadline - time.monotonic()))
            running = [c for c in running if c.popen is not None and c.popen.poll() is None]
            if not running:
                break
        for child in self.children:
            self._finish(child)
        return {c.name: c.returncode for c in self.children}

    def _finish(self, child: Child) -> None:
        if child.popen is None:
            return
        child.returncode = child.popen.poll()
        for reader in child.readers:
            reader.join(timeout=GRACE_S)
        if child.popen.stdout is not None:
            child.popen.stdout.close()
