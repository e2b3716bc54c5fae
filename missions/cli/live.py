"""The live monitor beside a running mission (`run --monitor`, `serve process --monitor-port`).

The monitor is the web set's: the options that start it are the core's, so a missing set is said
as a usage error naming the extra, not a traceback.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

from botstage.missions.cli.common import _fail, console
from botstage.missions.cli.verbs import missing_package

WEB_EXTRA = "pip install 'botstage[web]'"
HOST_HELP = "address to listen on (default 127.0.0.1; any other needs BOTSTAGE_MONITOR_TOKEN)"


@contextlib.contextmanager
def live_monitor(host: str, port: int, paused: bool) -> Iterator[object]:
    """A monitor serving a run while it runs (yields its observer); stopped when the run is done."""
    try:
        from botstage.missions.monitor.control import Control
        from botstage.missions.monitor.hub import Hub
        from botstage.missions.monitor.observer import MonitorObserver
        from botstage.missions.monitor.server import PUSH_S, MonitorError, start_monitor
    except ModuleNotFoundError as exc:
        if missing_package(exc) is None:
            raise
        raise _fail(f"error: the live monitor needs {exc.name}, which is not installed: {WEB_EXTRA}", 2) from None

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
