"""The live monitor on the command line: `botstage run … --monitor` and `botstage monitor RUN_FOLDER`."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path

import typer

from missions.cli.common import _fail, console

HOST_HELP = "address to listen on (default 127.0.0.1; any other needs BOTSTAGE_MONITOR_TOKEN)"


@contextlib.contextmanager
def live_monitor(host: str, port: int, paused: bool) -> Iterator[object]:
    """A monitor serving a run while it runs (yields its observer); stopped when the run is done."""
    from missions.monitor.control import Control
    from missions.monitor.hub import Hub
    from missions.monitor.observer import MonitorObserver
    from missions.monitor.server import PUSH_S, MonitorError, start_monitor

    hub = Hub()
    control = Control(hub, simulated=True)
    if paused:
        control.request({"action": "pause"})
    try:
        running = start_monitor(hub, control, host=host, port=port)
    except MonitorError as exc:
        raise _fail(f"error: {exc}", 2) from None
    console.print(f"monitor: {running.url}/  (the tablet: {running.url}/display)", highlight=False, soft_wrap=True)
    try:
        yield MonitorObserver(hub, control)
    finally:
        control.close()
        time.sleep(3 * PUSH_S)  # the pages hear that the run ended before the server goes
        running.stop()


def monitor(
    folder: Path = typer.Argument(..., help="a run folder (runs/<mission>-<time>/) to look through"),
    host: str = typer.Option("127.0.0.1", help=HOST_HELP),
    port: int = typer.Option(8470, help="port to listen on (0: a free one)", min=0, max=65535),
) -> None:
    """Open a finished run in the monitor: the same views as live, and a scrubber through its ticks
    (the tree at tick N is what `botstage tree --trace … --at N` prints). Ctrl-C stops it."""
    from missions.monitor.replay import RunFolderError, load_run
    from missions.monitor.server import MonitorError, start_monitor

    try:
        run = load_run(folder)
        running = start_monitor(run.hub, host=host, port=port, run=run)
    except (RunFolderError, MonitorError) as exc:
        raise _fail(f"error: {exc}", 1) from None
    console.print(f"monitor: {running.url}/  ({run.last + 1} ticks; Ctrl-C stops)", highlight=False, soft_wrap=True)
    try:
        while running.thread.is_alive():
            running.thread.join(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        running.stop()
