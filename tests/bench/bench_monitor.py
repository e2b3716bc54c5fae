"""The live monitor's four figures (the issue's acceptance), with a real page: Debian's headless
Chromium driven by Playwright on the monitor each run serves on 127.0.0.1. Run with
`python -m tests.bench monitor` (``--quick``: shorter runs, one repeat; a smoke test of about a minute).

Every run with a monitor is started as ``botstage run --monitor --paused`` starts one: a ``Hub``
and a ``Control`` with a pause queued, the monitor served on a free port, the mission on a thread
with a ``MonitorObserver``; the run holds before its first tick, the page is opened and waited for
(``window.monitor.ready``), then the control resumes it. A stopwatch observer placed after the
monitor's times the ticks from the first one after the hold (``time.perf_counter``), so neither
building the run nor loading the page counts. A paced run's clock is the wall clock, which runs on
while the run is held: those runs are given time to spare and stopped by the stopwatch once it has
counted their ticks.

- **tick_cost**: the entertainer (missions/examples/peoplebot_entertainer.yaml), seed 1, 600 s of mission
  time at full speed (quick: 120 s), wall time of its ticks without any monitor, with a monitor
  and a connected page, and (informative) with a monitor and no page; after an untimed warm-up of
  each way, the variants interleaved (each one first in turn), 3 repeats each (quick: 1), the
  browser running throughout. Target: best with a page / best without <= 1.1; the best because
  the machine may be shared and another job only ever slows a run down (the medians, the CPU
  time of this process, of the monitor's server thread and of the browser's, and the load average
  before are reported too: a page costs this process little, but on a small machine the browser
  takes cores from the run; the CPU seconds do not depend on what else the machine runs).
- **latency**: the entertainer paced at 10 Hz wall time (``realtime``) for 60 s of ticks (quick:
  15 s) with the page open. A second ``EventSource`` on ``/api/events?since=V&stamps=1`` in the
  page gets, for every status in every delta, the wall-clock time it changed in the hub; the page
  notes ``Date.now()`` minus it on arrival ("received"), and again in the next animation frame
  ("rendered": when the page's own flush, also done in an animation frame, has drawn it at the
  latest). Target: received p99 <= 200 ms.
- **tree_2000**: a generated mission of 2,001 nodes (a parallel of 100 ``repeat: forever``
  sequences of 18 ``wait`` skills of 0.1 to 0.5 s, so a few hundred statuses change every tick)
  paced at 10 Hz for 30 s of ticks (quick: 10 s) with the page open. A requestAnimationFrame
  counter in the page gives its frames per second over the run (and the worst one-second window,
  the longest frame, and the same counter on the held run before it: what this headless Chromium
  gives an idle page); the page must also keep up: ``window.monitor.applied`` deltas, and its last
  applied version equal to the hub's final one soon after the run ends. Target: >= 20 fps and
  caught up ("usable"). Why 20: the run changes at 10 Hz and the server pushes at most every 50 ms
  (``PUSH_S``), so 20 frames a second draws every push in its own frame, and below about 20 fps
  scrolling and clicking feel sluggish (60 is what an idle page gets here). The latency probe rides
  along (informative: latency under a 2,000-node tree).
- **memory**: the entertainer for 3,600 s of mission time at full speed (quick: 300 s) with the
  page open; every 5 s of wall time (quick: 2 s) the page's JS heap after a forced garbage
  collection (CDP ``HeapProfiler.collectGarbage`` then ``Performance.getMetrics``:
  ``JSHeapUsedSize``) and its element count (``document.getElementsByTagName('*').length``), with
  the hub's sizes (timeline, key histories, layouts shown; all rings). Rule: "bounded" when the
  heap's last sample of the run is less than 20 % above its sample at mid-run (by mission time):
  a leak grows in proportion to the events, which come as fast in both halves. The element count
  is reported, not judged: the page keeps up to 2,000 rows each of timeline, log and layouts
  (``MAX_ENTRIES``, ``MAX_DISPLAY`` in monitor.js) and the entertainer makes about 2,700 timeline
  entries an hour, so its rows still grow through the hour towards those caps.

Each figure is printed as one JSON line when measured; a table of all of them closes the run.
Needs Playwright (``pip install -e .[test]``) and Chromium (Debian package ``chromium``); without
either it says so and returns no figures.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from botstage.missions import DEFAULT_MISSION
from botstage.missions.monitor.control import Control
from botstage.missions.monitor.hub import Hub
from botstage.missions.monitor.observer import MonitorObserver
from botstage.missions.monitor.server import start_monitor
from botstage.missions.runner import RunResult, run
from botstage.missions.session.errors import StopRun

if TYPE_CHECKING:
    from botstage.missions.session.session import RunSession

SEED = 1
RATE_HZ = 10  # the entertainer's and the generated tree's
TARGET_TICK_RATIO = 1.1  # with a page / without, medians
TARGET_LATENCY_P99_MS = 200.0
TARGET_FPS = 20.0
TARGET_HEAP_GROWTH = 0.20  # over the second half of the run, relative to mid-run
TREE_GROUPS, TREE_STEPS = 100, 18  # 1 + 100 * (repeat + sequence + 18 waits) = 2,001 nodes
HOLD_MARGIN_S = 120.0  # paced runs: mission time the hold may take (a wall clock runs on while held)
READY_S = 60.0  # for the run to be built, the page to be ready
CATCH_UP_S = 10.0  # for the page to reach the hub's final version
JOIN_S = 300.0
VIEWPORT = {"width": 1400, "height": 900}

# -- in the page --------------------------------------------------------------------------------

PROBE_JS = """(since) => {
  const b = window.__bench = {received: [], rendered: [], deltas: 0, errors: 0, ended: false};
  const es = new EventSource(`/api/events?since=${since}&stamps=1`);
  b.close = () => es.close();
  es.onmessage = (m) => {
    const now = Date.now() / 1000;
    let d;
    try { d = JSON.parse(m.data); } catch (e) { return; }
    b.deltas++;
    const stamps = Object.values(d.stamps || {}).filter((s) => s > 0);
    for (const s of stamps) b.received.push(now - s);
    if (stamps.length) {
      requestAnimationFrame(() => {
        const drawn = Date.now() / 1000;
        for (const s of stamps) b.rendered.push(drawn - s);
      });
    }
    if (d.ended) { b.ended = true; es.close(); }
  };
  // a reconnection would resume from the first `since` and stamp old changes as new: not counted
  es.onerror = () => { b.errors++; es.close(); };
}"""

PROBE_READ_JS = "() => { const b = window.__bench; b.close(); return b; }"

FPS_START_JS = """() => {
  const f = window.__fps = {frames: 0, start: performance.now(), last: performance.now(), worst: 0,
                            counts: [], on: true};
  const step = (t) => {
    if (!f.on) return;
    f.frames++;
    f.worst = Math.max(f.worst, t - f.last);
    f.last = t;
    const k = Math.floor((t - f.start) / 1000);
    while (f.counts.length <= k) f.counts.push(0);
    f.counts[k]++;
    requestAnimationFrame(step);
  };
  requestAnimationFrame(step);
}"""

FPS_STOP_JS = """() => {
  const f = window.__fps;
  f.on = false;
  const seconds = (performance.now() - f.start) / 1000;
  const whole = f.counts.slice(0, Math.floor(seconds));  // full one-second windows only
  return {frames: f.frames, seconds, worst_gap_ms: f.worst,
          worst_second: whole.length ? Math.min(...whole) : null};
}"""

PAGE_STATE_JS = "() => ({version: window.monitor.version, applied: window.monitor.applied})"
ELEMENTS_JS = "() => document.getElementsByTagName('*').length"


# -- the run on a thread, held for the page -----------------------------------------------------


class Stopwatch:
    """Times the ticks (from the first one after the monitor's hold); ends the run after ``limit``
    ticks or when told to (``abort``)."""

    name = "bench_stopwatch"

    def __init__(self, limit: int | None = None) -> None:
        self.limit = limit
        self.abort = ""
        self.first: float | None = None
        self.last: float | None = None
        self.cpu_first = self.cpu_last = 0.0  # this process's CPU time (every thread)
        self.ticks = 0

    def before_tick(self, session: RunSession) -> None:
        if self.abort:
            raise StopRun(self.abort)
        if self.limit is not None and self.ticks >= self.limit:
            raise StopRun("the benchmark's ticks are done")
        if self.first is None:
            self.first, self.cpu_first = time.perf_counter(), time.process_time()

    def after_tick(self, session: RunSession) -> None:
        self.ticks += 1
        self.last, self.cpu_last = time.perf_counter(), time.process_time()

    @property
    def wall_s(self) -> float:
        return 0.0 if self.first is None or self.last is None else self.last - self.first

    @property
    def cpu_s(self) -> float:
        return self.cpu_last - self.cpu_first


class Live:
    """A run on a thread with its monitor and (when asked) a page open on it, held until ``go``."""

    def __init__(self, hub: Hub, control: Control, url: str, stopwatch: Stopwatch, server: Any = None) -> None:
        self.hub = hub
        self.control = control
        self.url = url
        self.stopwatch = stopwatch
        self.server = server  # the monitor's ServerThread: its thread's CPU is the server's cost
        self.page: Any = None
        self.thread: threading.Thread | None = None
        self.result: RunResult | None = None
        self.error: BaseException | None = None

    def go(self) -> float:
        """Resume the held run; returns when (perf_counter)."""
        self.control.request({"action": "resume"})
        return time.perf_counter()

    def running(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def finish(self) -> RunResult:
        assert self.thread is not None
        self.thread.join(JOIN_S)
        if self.thread.is_alive():
            raise RuntimeError("the benchmark's run did not end")
        if self.error is not None:
            raise self.error
        assert self.result is not None
        return self.result


def _wait(condition: Callable[[], Any], timeout: float, what: str) -> None:
    deadline = time.perf_counter() + timeout
    while not condition():
        if time.perf_counter() > deadline:
            raise RuntimeError(f"gave up waiting for {what}")
        time.sleep(0.01)


@contextlib.contextmanager
def live(
    mission: Path,
    folder: Path,
    browser: Any = None,
    *,
    until: float,
    realtime: bool = False,
    ticks: int | None = None,
) -> Iterator[Live]:
    """``mission`` held before its first tick with a monitor on a free port and, given a
    ``browser``, a page open on it and ready; stopped and closed on every way out."""
    hub = Hub()
    control = Control(hub, simulated=True)
    control.request({"action": "pause"})
    stopwatch = Stopwatch(ticks)
    server = start_monitor(hub, control, port=0)
    held = Live(hub, control, server.url, stopwatch, server)

    def go() -> None:
        try:
            held.result = run(
                mission,
                out=folder,
                until=until,
                seed=SEED,
                realtime=realtime,
                observers=[MonitorObserver(hub, control), stopwatch],
            )
        except BaseException as exc:  # said by finish()
            held.error = exc

    held.thread = threading.Thread(target=go, name="bench-mission", daemon=True)
    try:
        held.thread.start()
        _wait(lambda: hub.ready.is_set() or not held.running(), READY_S, "the run to be built")
        if held.error is not None:
            raise held.error
        if browser is not None:
            held.page = browser.new_page(viewport=VIEWPORT)
            held.page.set_default_timeout(READY_S * 1000)
            held.page.goto(server.url + "/")
            held.page.wait_for_function("() => window.monitor && window.monitor.ready === true")
        yield held
    finally:
        stopwatch.abort = "the benchmark stopped early"  # a run still going ends at its next tick
        control.close()  # and one still held goes on to it
        try:
            if held.thread.is_alive():
                held.thread.join(JOIN_S)
            if held.page is not None:
                held.page.close()
        finally:
            server.stop()


def children_cpu_s() -> float | None:
    """CPU time (user + system, s) of this process's descendants so far: the browser's processes
    and Playwright's driver (Linux's /proc; None elsewhere)."""
    try:
        tick = os.sysconf("SC_CLK_TCK")
        parents: dict[int, int] = {}
        used: dict[int, float] = {}
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue  # gone meanwhile
            pid = int(entry.name)
            parents[pid] = int(fields[1])
            used[pid] = (int(fields[11]) + int(fields[12])) / tick
    except (OSError, ValueError):
        return None
    ours, total = {os.getpid()}, 0.0
    grown = True
    while grown:
        grown = False
        for pid, parent in parents.items():
            if parent in ours and pid not in ours:
                ours.add(pid)
                total += used[pid]
                grown = True
    return total


def thread_cpu_s(thread: threading.Thread | None) -> float | None:
    """CPU time (user + system, s) of one thread of this process so far (Linux's /proc; None elsewhere)."""
    native = getattr(thread, "native_id", None)
    if native is None:
        return None
    try:
        fields = Path(f"/proc/self/task/{native}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def _entertainer_alone(folder: Path, until: float) -> tuple[Stopwatch, RunResult]:
    stopwatch = Stopwatch()
    result = run(DEFAULT_MISSION, out=folder, until=until, seed=SEED, observers=[stopwatch])
    return stopwatch, result


def _ms(values: list[float], q: float) -> float | None:
    return round(float(np.percentile(np.asarray(values) * 1000.0, q)), 1) if values else None


def _mb(value: float) -> float:
    return round(value / 1e6, 2)


# -- 1. tick cost -------------------------------------------------------------------------------

VARIANTS = ("without", "with_page", "monitor_no_page")


def bench_tick_cost(browser: Any, folder: Path, mission_s: float, repeats: int, warm_up_s: float) -> dict[str, Any]:
    """See the module's docstring. Judged on the best of each (the run least disturbed by whatever
    else the machine does: what is left is the page's and the monitor's own cost); the medians,
    and the process's CPU time (this process only: the run, the monitor's server), are reported."""
    walls: dict[str, list[float]] = {v: [] for v in VARIANTS}
    cpus: dict[str, list[float]] = {v: [] for v in VARIANTS}
    browser_cpus: dict[str, list[float]] = {v: [] for v in VARIANTS}
    server_cpus: dict[str, list[float]] = {v: [] for v in VARIANTS}
    ticks: set[int] = set()
    load = os.getloadavg()[0]
    _entertainer_alone(folder / "warm-up-alone", warm_up_s)  # imports, caches, the page's code: not timed
    with live(DEFAULT_MISSION, folder / "warm-up-page", browser, until=warm_up_s) as held:
        held.go()
        held.finish()
    for r in range(repeats):
        order = VARIANTS[r % 3 :] + VARIANTS[: r % 3]  # each variant first once in three
        for variant in order:
            out = folder / f"tick-{variant}-{r}"
            if variant == "without":
                before = children_cpu_s()
                stopwatch, _ = _entertainer_alone(out, mission_s)
                after = children_cpu_s()
            else:
                with live(DEFAULT_MISSION, out, browser if variant == "with_page" else None, until=mission_s) as held:
                    before, server_before = children_cpu_s(), thread_cpu_s(held.server.thread)
                    held.go()
                    held.finish()
                    after, server_after = children_cpu_s(), thread_cpu_s(held.server.thread)
                    stopwatch = held.stopwatch
                    if server_before is not None and server_after is not None:
                        server_cpus[variant].append(server_after - server_before)
            walls[variant].append(stopwatch.wall_s)
            cpus[variant].append(stopwatch.cpu_s)
            if before is not None and after is not None:
                browser_cpus[variant].append(after - before)
            ticks.add(stopwatch.ticks)
    count = max(ticks)

    def figures(variant: str) -> dict[str, Any]:
        best = min(walls[variant])
        return {
            "wall_s": [round(w, 2) for w in walls[variant]],
            "best_s": round(best, 2),
            "median_s": round(statistics.median(walls[variant]), 2),
            "ms_per_tick": round(best / count * 1000.0, 3),
            "cpu_s_best": round(min(cpus[variant]), 2),
            "browser_cpu_s": round(statistics.median(browser_cpus[variant]), 2) if browser_cpus[variant] else None,
            # the monitor's web server (its thread): building and sending the deltas
            "server_cpu_s": round(statistics.median(server_cpus[variant]), 2) if server_cpus[variant] else None,
        }

    base, page, bare = (figures(v) for v in VARIANTS)
    ratio = round(page["best_s"] / base["best_s"], 3)
    return {
        "bench": "tick_cost",
        "mission": DEFAULT_MISSION.stem,
        "seed": SEED,
        "mission_s": mission_s,
        "ticks": count if len(ticks) == 1 else sorted(ticks),  # one number: every run ticked the same
        "repeats": repeats,
        "load_before": round(load, 2),  # the 1-minute load average: another job on the machine shows here
        "without": base,
        "with_page": page,
        "monitor_no_page": bare,
        "ratio": ratio,
        "ratio_median": round(page["median_s"] / base["median_s"], 3),
        "ratio_monitor_no_page": round(bare["best_s"] / base["best_s"], 3),
        "ratio_cpu": round(page["cpu_s_best"] / base["cpu_s_best"], 3),
        "target_ratio": TARGET_TICK_RATIO,
        "meets_target": ratio <= TARGET_TICK_RATIO,
    }


# -- 2. latency (and 3. the 2,000-node tree, which measures it too) ------------------------------


def _probe_figures(probe: dict[str, Any]) -> dict[str, Any]:
    received, rendered = probe["received"], probe["rendered"]
    return {
        "deltas": probe["deltas"],
        "statuses": len(received),
        "p50_ms": _ms(received, 50),
        "p99_ms": _ms(received, 99),
        "max_ms": _ms(received, 100),
        "rendered_p50_ms": _ms(rendered, 50),
        "rendered_p99_ms": _ms(rendered, 99),
        "stream_errors": probe["errors"],
    }


def _paced(
    browser: Any, folder: Path, mission: Path, seconds: float, during: Callable[[Live], Any] | None = None
) -> tuple[Live, dict[str, Any], Any]:
    """``mission`` paced at 10 Hz for ``seconds`` of ticks with the page and the probe; what
    ``during`` returns (called with the run held, and again once it ended)."""
    with live(
        mission, folder, browser, until=seconds + HOLD_MARGIN_S, realtime=True, ticks=round(seconds * RATE_HZ)
    ) as held:
        page = held.page
        page.evaluate(PROBE_JS, held.hub.version)
        before = during(held) if during is not None else None
        held.go()
        held.finish()
        after = during(held) if during is not None else None
        page.wait_for_function("() => window.__bench.ended || window.__bench.errors > 0", timeout=CATCH_UP_S * 1000)
        probe = page.evaluate(PROBE_READ_JS)
        return held, probe, (before, after)


def _overruns(held: Live) -> int:
    """Ticks that ended after their deadline, the first one after the hold included."""
    summary = held.result.summary if held.result is not None else {}
    return int((summary.get("overruns") or {}).get("count", 0))


def bench_latency(browser: Any, folder: Path, seconds: float) -> dict[str, Any]:
    held, probe, _ = _paced(browser, folder / "latency", DEFAULT_MISSION, seconds)
    figures = _probe_figures(probe)
    p99 = figures["p99_ms"]
    return {
        "bench": "latency",
        "mission": DEFAULT_MISSION.stem,
        "rate_hz": RATE_HZ,
        "mission_s": seconds,
        "ticks": held.stopwatch.ticks,
        **figures,
        "overruns": _overruns(held),
        "target_p99_ms": TARGET_LATENCY_P99_MS,
        "meets_target": p99 is not None and p99 <= TARGET_LATENCY_P99_MS and not probe["errors"],
    }


def tree_mission(path: Path) -> Path:
    """A mission of 2,001 nodes whose statuses keep changing (see the module's docstring)."""
    groups = []
    for g in range(TREE_GROUPS):
        steps = [{"wait": {"duration": round(0.1 * (1 + (g + i) % 5), 1)}} for i in range(TREE_STEPS)]
        groups.append({"name": f"group{g:03d}", "repeat": "forever", "child": {"sequence": steps}})
    mission = {
        "name": "monitor_bench_tree",
        "description": "2,001 nodes for `python -m tests.bench monitor`: 100 sequences of 18 waits, repeated",
        "seed": SEED,
        "rate_hz": RATE_HZ,
        "until": 3600,
        "trees": {"main": {"parallel": groups, "policy": "success_on_all"}},
    }
    path.write_text(yaml.safe_dump(mission, sort_keys=False), encoding="utf-8")
    return path


def _count_nodes(item: dict[str, Any]) -> int:
    return 1 + sum(_count_nodes(child) for child in item.get("children", ()))


def bench_tree(browser: Any, folder: Path, seconds: float) -> dict[str, Any]:
    mission = tree_mission(folder / "monitor_bench_tree.yaml")
    idle: dict[str, Any] = {}
    running: dict[str, Any] = {}
    caught: dict[str, Any] = {}

    def during(held: Live) -> None:
        page = held.page
        if not idle:  # held: what an idle page gets, then count while it runs
            page.evaluate(FPS_START_JS)
            time.sleep(1.5)
            idle.update(page.evaluate(FPS_STOP_JS))
            page.evaluate(FPS_START_JS)
            return
        running.update(page.evaluate(FPS_STOP_JS))  # stopped as soon as the run ended
        began, final = time.perf_counter(), held.hub.version
        try:
            page.wait_for_function(f"() => window.monitor.version >= {final}", timeout=CATCH_UP_S * 1000)
            caught["after_s"] = round(time.perf_counter() - began, 2)
        except Exception:  # Playwright's timeout: said as not caught up
            caught["after_s"] = None
        caught.update(page.evaluate(PAGE_STATE_JS), final=final)

    held, probe, _ = _paced(browser, folder / "tree", mission, seconds, during)
    fps = running["frames"] / running["seconds"] if running["seconds"] > 0 else 0.0
    caught_up = caught["after_s"] is not None
    latency = _probe_figures(probe)
    return {
        "bench": "tree_2000",
        "nodes": _count_nodes(held.hub.structure),
        "rate_hz": RATE_HZ,
        "mission_s": seconds,
        "ticks": held.stopwatch.ticks,
        "overruns": _overruns(held),
        "fps": round(fps, 1),
        "fps_worst_second": running["worst_second"],
        "longest_frame_ms": round(running["worst_gap_ms"], 1),
        "fps_idle": round(idle["frames"] / idle["seconds"], 1) if idle.get("seconds") else None,
        "applied": caught["applied"],
        "last_version": caught["version"],
        "hub_version": caught["final"],
        "caught_up": caught_up,
        "caught_up_after_s": caught["after_s"],
        "latency_p50_ms": latency["p50_ms"],
        "latency_p99_ms": latency["p99_ms"],
        "rendered_p99_ms": latency["rendered_p99_ms"],
        "statuses_stamped": latency["statuses"],
        "target_fps": TARGET_FPS,
        "meets_target": fps >= TARGET_FPS and caught_up,
    }


# -- 4. memory over a simulated hour -------------------------------------------------------------


def hub_sizes(hub: Hub) -> dict[str, int]:
    with hub.lock:
        return {
            "version": hub.version,
            "statuses": len(hub.statuses),
            "states": len(hub.states),
            "keys": len(hub.blackboard),
            "history_writes": sum(len(writes) for writes in hub.history.values()),
            "timeline": len(hub.timeline),
            "display": len(hub.display),
        }


def _rss_mb() -> float | None:
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return None
    return _mb(pages * os.sysconf("SC_PAGE_SIZE"))


def bench_memory(browser: Any, folder: Path, mission_s: float, every_s: float) -> dict[str, Any]:
    samples: list[dict[str, Any]] = []
    with live(DEFAULT_MISSION, folder / "memory", browser, until=mission_s) as held:
        page = held.page
        cdp = page.context.new_cdp_session(page)
        try:
            cdp.send("Performance.enable")

            def sample() -> None:
                cdp.send("HeapProfiler.collectGarbage")
                metrics = {m["name"]: m["value"] for m in cdp.send("Performance.getMetrics")["metrics"]}
                samples.append(
                    {
                        "t": held.hub.flags.t,
                        "heap_mb": _mb(metrics["JSHeapUsedSize"]),
                        "elements": page.evaluate(ELEMENTS_JS),
                        "hub": hub_sizes(held.hub),
                        "rss_mb": _rss_mb(),
                    }
                )

            sample()  # the page ready, the run held
            began = held.go()
            while held.running():
                held.thread.join(every_s)  # type: ignore[union-attr]
                if held.running():
                    sample()
            wall = time.perf_counter() - began
            held.finish()
            sample()  # the run ended (the page heard it, or will at once)
        finally:
            cdp.detach()
    during = samples[1:-1] or samples
    end_t = held.hub.flags.t
    mid = min(during, key=lambda s: abs(s["t"] - end_t / 2))
    last = during[-1]
    growth = round((last["heap_mb"] - mid["heap_mb"]) / mid["heap_mb"], 3) if mid["heap_mb"] else None
    heaps = [s["heap_mb"] for s in samples]
    elements = [s["elements"] for s in samples]
    return {
        "bench": "memory",
        "mission": DEFAULT_MISSION.stem,
        "mission_s": mission_s,
        "wall_s": round(wall, 1),
        "samples": len(samples),
        "heap_mb": {"first": heaps[0], "mid": mid["heap_mb"], "peak": max(heaps), "last": last["heap_mb"]},
        "heap_growth_second_half": growth,
        "elements": {"first": elements[0], "peak": max(elements), "last": elements[-1]},
        "hub_first": samples[0]["hub"],
        "hub_last": samples[-1]["hub"],
        "process_rss_mb": {"first": samples[0]["rss_mb"], "last": samples[-1]["rss_mb"]},
        "series": [[round(s["t"]), s["heap_mb"], s["elements"]] for s in samples],
        "target_growth": TARGET_HEAP_GROWTH,
        "meets_target": growth is not None and growth < TARGET_HEAP_GROWTH,
    }


# -- the run ------------------------------------------------------------------------------------


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The figures that missed their target."""
    return [r["bench"] for r in results if not r.get("meets_target", True)]


def _mark(result: dict[str, Any]) -> str:
    return "met" if result.get("meets_target", True) else "MISSED"


def table(results: list[dict[str, Any]]) -> str:
    """One block per figure: what was measured, its target, and whether it was met."""
    lines = [f"{'bench':<10} {'figure':<100} {'target':<14} met"]

    def line(name: str, figure: str, target: str = "", mark: str = "") -> None:
        lines.append(f"{name:<10} {figure:<100} {target:<14} {mark}".rstrip())

    for r in results:
        name = r["bench"]
        if name == "tick_cost":
            w, p, b = r["without"], r["with_page"], r["monitor_no_page"]
            line(
                name,
                f"with a page {p['best_s']:.2f} s ({p['ms_per_tick']:.3f} ms/tick) vs without "
                f"{w['best_s']:.2f} s ({w['ms_per_tick']:.3f} ms/tick): {r['ratio']:.3f}x (best of {r['repeats']})",
                f"<= {TARGET_TICK_RATIO:g}x",
                _mark(r),
            )
            line(
                "",
                f"medians {p['median_s']:.2f} vs {w['median_s']:.2f} s: {r['ratio_median']:.3f}x; this process's "
                f"CPU {p['cpu_s_best']:.2f} vs {w['cpu_s_best']:.2f} s: {r['ratio_cpu']:.3f}x",
            )
            line(
                "",
                f"meanwhile the browser and Playwright's driver used {p['browser_cpu_s']} s of CPU "
                f"(without a page: {w['browser_cpu_s']} s) on {os.cpu_count()} cores; the monitor's server "
                f"thread {p['server_cpu_s']} s",
            )
            line(
                "",
                f"a monitor without a page {b['best_s']:.2f} s ({b['ms_per_tick']:.3f} ms/tick): "
                f"{r['ratio_monitor_no_page']:.3f}x",
            )
            line(
                "",
                f"{r['mission']}, seed {r['seed']}, {r['mission_s']:g} s of mission time, {r['ticks']} ticks; "
                f"load average before {r['load_before']}",
            )
        elif name == "latency":
            line(
                name,
                f"status change -> page: p50 {r['p50_ms']} ms, p99 {r['p99_ms']} ms, max {r['max_ms']} ms "
                f"(rendered p50 {r['rendered_p50_ms']}, p99 {r['rendered_p99_ms']})",
                f"p99 <= {TARGET_LATENCY_P99_MS:g} ms",
                _mark(r),
            )
            line(
                "",
                f"{r['statuses']} statuses in {r['deltas']} deltas, {r['ticks']} ticks at {r['rate_hz']} Hz "
                f"wall ({r['overruns']} overruns, the hold's included), stream errors {r['stream_errors']}",
            )
        elif name == "tree_2000":
            caught = f"caught up {r['caught_up_after_s']} s after the end" if r["caught_up"] else "NOT caught up"
            line(
                name,
                f"{r['nodes']} nodes: {r['fps']} fps (worst second {r['fps_worst_second']}, longest frame "
                f"{r['longest_frame_ms']} ms; idle {r['fps_idle']} fps) -> "
                + ("usable" if r["meets_target"] else "NOT usable"),
                f">= {TARGET_FPS:g} fps",
                _mark(r),
            )
            line(
                "",
                f"{r['applied']} deltas applied, {caught} (version {r['last_version']} of {r['hub_version']}); "
                f"latency p50 {r['latency_p50_ms']} / p99 {r['latency_p99_ms']} ms, {r['ticks']} ticks "
                f"({r['overruns']} overruns, the hold's included)",
            )
        elif name == "memory":
            h, e, hub = r["heap_mb"], r["elements"], r["hub_last"]
            line(
                name,
                f"JS heap {h['first']} -> mid {h['mid']} -> peak {h['peak']} -> last {h['last']} MB: "
                f"{r['heap_growth_second_half'] * 100:+.1f} % over the second half -> "
                + ("bounded" if r["meets_target"] else "NOT bounded"),
                f"< {TARGET_HEAP_GROWTH * 100:g} %",
                _mark(r),
            )
            line(
                "",
                f"elements {e['first']} -> peak {e['peak']} -> last {e['last']}; {r['mission_s']:g} s of "
                f"mission in {r['wall_s']} s wall, {r['samples']} samples",
            )
            line(
                "",
                f"hub at the end: timeline {hub['timeline']}, key writes {hub['history_writes']}, "
                f"layouts {hub['display']}, statuses {hub['statuses']}, keys {hub['keys']}, version {hub['version']}",
            )
    return "\n".join(lines)


def chromium() -> str | None:
    return shutil.which("chromium")


def main(quick: bool = False) -> list[dict[str, Any]]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        print("Playwright is missing: the monitor benchmark drives a real page with it (pip install -e .[test])")
        return []
    executable = chromium()
    if executable is None:
        print("chromium is missing: the monitor benchmark opens its page in it (apt-get install chromium)")
        return []
    results: list[dict[str, Any]] = []

    def report(result: dict[str, Any]) -> None:
        results.append(result)
        print(json.dumps(result), flush=True)

    with tempfile.TemporaryDirectory(prefix="botstage-bench-monitor-") as tmp, sync_playwright() as p:
        folder = Path(tmp)
        browser = p.chromium.launch(executable_path=executable, args=["--no-sandbox"])
        try:
            if quick:
                report(bench_tick_cost(browser, folder, 120.0, 1, 10.0))
                report(bench_latency(browser, folder, 15.0))
                report(bench_tree(browser, folder, 10.0))
                report(bench_memory(browser, folder, 300.0, 2.0))
            else:
                report(bench_tick_cost(browser, folder, 600.0, 3, 30.0))
                report(bench_latency(browser, folder, 60.0))
                report(bench_tree(browser, folder, 30.0))
                report(bench_memory(browser, folder, 3600.0, 5.0))
        finally:
            browser.close()
    print(table(results), flush=True)
    return results


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
