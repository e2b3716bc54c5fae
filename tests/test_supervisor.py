"""The supervisor behind `botstage up`: real child processes, their output, states and stopping."""

from __future__ import annotations

import queue
import signal
import sys

from botstage.missions.distributed.supervisor import Supervisor

FAILSAFE_S = 60.0

SERVE = """
import signal, sys, threading
stop = threading.Event()
signal.signal(signal.SIGINT, lambda *_: stop.set())
print("ready", flush=True)
stop.wait(120)
print("stopped cleanly", flush=True)
"""
STUBBORN = """
import signal, threading
signal.signal(signal.SIGINT, signal.SIG_IGN)
print("ready", flush=True)
threading.Event().wait(120)
"""


def py(code: str) -> list[str]:
    return [sys.executable, "-c", code]


class Lines:
    def __init__(self) -> None:
        self.queue: queue.Queue[tuple[str, str]] = queue.Queue()
        self.seen: list[tuple[str, str]] = []

    def __call__(self, name: str, line: str) -> None:
        self.queue.put((name, line))

    def wait_for(self, name: str, line: str) -> None:
        while (name, line) not in self.seen:
            self.seen.append(self.queue.get(timeout=FAILSAFE_S))


def test_processes_start_report_and_stop_in_order_with_their_output() -> None:
    lines = Lines()
    supervisor = Supervisor({"robot": py(SERVE), "mission": py(SERVE), "oops": py("import sys; sys.exit(3)")}, lines)
    try:
        supervisor.start()
        lines.wait_for("robot", "ready")
        lines.wait_for("mission", "ready")
        ended = supervisor.wait_any(FAILSAFE_S)
        assert ended is not None and ended.name == "oops"
        assert supervisor.states() == {"robot": "running", "mission": "running", "oops": "failed (exit 3)"}
    finally:
        codes = supervisor.stop()
    assert codes == {"robot": 0, "mission": 0, "oops": 3}
    lines.wait_for("robot", "stopped cleanly")
    lines.wait_for("mission", "stopped cleanly")


def test_a_process_that_ignores_ctrl_c_is_terminated() -> None:
    lines = Lines()
    supervisor = Supervisor({"stubborn": py(STUBBORN)}, lines)
    supervisor.start()
    lines.wait_for("stubborn", "ready")
    assert supervisor.stop(grace=1.0) == {"stubborn": -signal.SIGTERM}


def test_a_killed_process_is_reported_and_can_be_restarted() -> None:
    lines = Lines()
    supervisor = Supervisor({"skills": py(SERVE)}, lines)
    try:
        supervisor.start()
        lines.wait_for("skills", "ready")
        supervisor.signal("skills", signal.SIGKILL)
        assert supervisor.wait("skills", FAILSAFE_S) == -signal.SIGKILL
        assert supervisor.states() == {"skills": "killed by SIGKILL"}
        lines.seen.clear()
        supervisor.restart("skills")
        lines.wait_for("skills", "ready")
        assert supervisor.states() == {"skills": "running"}
    finally:
        assert supervisor.stop() == {"skills": 0}
