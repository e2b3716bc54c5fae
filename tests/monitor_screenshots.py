"""The README's screenshots of the monitor, made from real runs in headless Chromium:
``python -m tests.monitor_screenshots`` writes missions/monitor/screenshots/*.png."""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from playwright.sync_api import Page, sync_playwright

from botstage.missions.monitor.replay import RecordedRun, load_run
from botstage.missions.monitor.server import create_app, start_monitor, start_overview
from botstage.missions.monitor.sources import Source, remote_source
from tests.monitor_harness import LISTENING, ROOT, live_run

OUT = ROOT / "missions" / "monitor" / "screenshots"
SIZE = {"width": 1400, "height": 900}


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    chromium = shutil.which("chromium")
    if chromium is None:
        sys.exit("chromium is not installed (apt-get install chromium)")
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport=SIZE)
        folder = Path(tmp) / "run"
        with live_run(folder, until=120) as live:
            live.act(action="break", kind="state", target=LISTENING)
            live.act(action="resume")
            live.until(lambda s: s["paused"] and "breakpoint" in s["pause_reason"], "the breakpoint", 120)
            page.goto(live.url + "/")
            page.wait_for_function("() => window.monitor && window.monitor.ready")
            page.wait_for_selector("#map[data-pose]")
            page.wait_for_timeout(500)  # let the map draw its frame
            page.screenshot(path=str(OUT / "monitor.png"))
            for _ in range(15):  # held at the breakpoint: drive by hand, the camera shown
                live.http.post("/api/teleop", json={"v": 0.0, "w": 0.5})
                page.wait_for_timeout(100)
            page.wait_for_selector("#camera:not([hidden])")
            page.wait_for_timeout(300)
            page.locator("#teleop").screenshot(path=str(OUT / "teleop.png"))
            live.http.post("/api/teleop", json={"v": 0.0, "w": 0.0})
            page.goto(live.url + "/display")
            page.wait_for_function("() => document.querySelector('#layout').dataset.layout")
            page.screenshot(path=str(OUT / "display.png"))
            page.goto("about:blank")
            live.act(action="unbreak", id=1)
            live.act(action="resume")
            live.finish()
        run = load_run(folder)
        server = start_monitor(run.hub, port=0, run=run)
        try:
            page.goto(server.url + "/")
            page.wait_for_function("() => window.monitor && window.monitor.ready")
            page.fill("#tick", "560")
            page.press("#tick", "Enter")
            page.wait_for_timeout(500)
            page.screenshot(path=str(OUT / "replay.png"))
            page.goto("about:blank")
        finally:
            server.stop()
        overview(page, Path(tmp), run)
        browser.close()
    for shot in sorted(OUT.glob("*.png")):
        print(shot.relative_to(ROOT), shot.stat().st_size, "bytes")


def overview(page: Page, tmp: Path, finished: RecordedRun) -> None:
    """Two live runs (one under way, one held before it starts) and a finished one on one page."""
    with live_run(tmp / "a", until=120) as first, live_run(tmp / "b", until=120) as second:
        first.act(action="resume")
        first.until(lambda s: s["tick"] >= 300 and any("approach" in e["text"] for e in s["timeline"]), "under way")
        first.act(action="pause")
        sources = [
            remote_source(first.url, [], None, name="entertainer-1"),
            remote_source(second.url, [], None, name="entertainer-2"),
            Source("entertainer-finished", "finished", create_app(finished.hub, run=finished), "runs/…/"),
        ]
        server = start_overview(sources, port=0, title="three runs")
        try:
            page.goto(server.url + "/")
            page.wait_for_selector("article.card[data-source='entertainer-finished'] [data-role=tick]")
            page.wait_for_timeout(700)  # every card polled at least once
            page.screenshot(path=str(OUT / "overview.png"))
            page.goto("about:blank")
        finally:
            server.stop()
        first.finish()
        second.finish()


if __name__ == "__main__":
    main()
