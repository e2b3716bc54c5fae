"""A mission running on a thread with the live monitor served over real HTTP on 127.0.0.1: what
the monitor's API tests and its browser tests drive."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

from botstage.missions.monitor.control import Control
from botstage.missions.monitor.hub import Hub
from botstage.missions.monitor.observer import MonitorObserver
from botstage.missions.monitor.replay import load_run
from botstage.missions.monitor.server import start_monitor
from botstage.missions.runner import RunResult, run

ROOT = Path(__file__).resolve().parent.parent
ENTERTAINER = ROOT / "missions" / "examples" / "peoplebot_entertainer.yaml"
LISTENING = "main/entertainer/near_com/listening"


def wait_until(condition: Callable[[], Any], timeout: float = 60.0, what: str = "the condition") -> Any:
    """A bounded poll for the run's thread (never a timing assertion)."""
    deadline = time.monotonic() + timeout
    while not (found := condition()):
        assert time.monotonic() < deadline, f"gave up waiting for {what}"
        time.sleep(0.01)
    return found


class LiveRun:
    """The run, its monitor's URL and an HTTP client; ``result`` once the run has ended."""

    def __init__(self, url: str, hub: Hub, control: Control, thread: threading.Thread) -> None:
        self.url = url
        self.hub = hub
        self.control = control
        self.thread = thread
        self.http = httpx.Client(base_url=url, timeout=10.0)
        self.result: RunResult | None = None
        self.error: BaseException | None = None

    def snapshot(self) -> dict[str, Any]:
        return self.http.get("/api/snapshot").json()

    def act(self, **body: Any) -> httpx.Response:
        return self.http.post("/api/control", json=body)

    def until(self, predicate: Callable[[dict[str, Any]], bool], what: str, timeout: float = 60.0) -> dict[str, Any]:
        def check() -> dict[str, Any] | None:
            snap = self.snapshot()
            return snap if predicate(snap) else None

        return wait_until(check, timeout, what)

    def paused_after(self, version: int, what: str) -> dict[str, Any]:
        """The run held again after ``version`` (a breakpoint, a step)."""
        return self.until(lambda s: s["paused"] and s["version"] > version and s["tick"] >= 0, what)

    def finish(self, timeout: float = 300.0) -> RunResult:
        self.control.close()
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the run did not end"
        if self.error is not None:
            raise self.error
        assert self.result is not None
        return self.result


@contextmanager
def live_run(
    folder: Path, mission: Path = ENTERTAINER, *, until: float = 200.0, paused: bool = True, token: str | None = None
) -> Iterator[LiveRun]:
    """Start ``mission`` held before its first tick (``paused``) with a monitor on a free port."""
    hub = Hub()
    control = Control(hub, simulated=True)
    if paused:
        control.request({"action": "pause"})
    server = start_monitor(hub, control, port=0, token=token)
    live: LiveRun

    def go() -> None:
        try:
            live.result = run(mission, out=folder, until=until, observers=[MonitorObserver(hub, control)])
        except BaseException as exc:  # said by finish()
            live.error = exc

    thread = threading.Thread(target=go, name="mission", daemon=True)
    live = LiveRun(server.url, hub, control, thread)
    thread.start()
    try:
        yield live
    finally:
        control.close()
        thread.join(300)
        live.http.close()
        server.stop()


@contextmanager
def replayed_run(folder: Path, until: float = 60.0) -> Iterator[tuple[Path, str]]:
    """The entertainer run to its end in ``folder``, then served as a finished run: (folder, URL)."""
    with live_run(folder, until=until, paused=False) as live:
        live.finish()
    run = load_run(folder)
    server = start_monitor(run.hub, port=0, run=run)
    try:
        yield folder, server.url
    finally:
        server.stop()
