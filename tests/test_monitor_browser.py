"""The monitor's pages in a real headless Chromium (Debian's `chromium`, driven by Playwright)
while a real run of the entertainer goes on: statuses change as it runs, a breakpoint set on the
page holds it, forcing `listen` from the page takes it into the photo machine, the tablet page
shows the layouts in the order the run set them, and a finished run scrubbed to tick N shows
what `botstage tree --trace … --at N` prints."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright import sync_api as playwright
from typer.testing import CliRunner

from botstage.behaviors.trace import read_jsonl
from botstage.missions.cli import app
from tests.monitor_harness import ENTERTAINER, LISTENING, live_run, replayed_run, wait_until
from tests.tools import require

WAIT_MS = 60_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    chromium = require("chromium", "chromium")
    with playwright.sync_playwright() as p:
        launched = p.chromium.launch(executable_path=chromium, args=["--no-sandbox", "--disable-gpu"])
        yield launched
        launched.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    """A page that fails the test on any console error or uncaught exception of its own."""
    opened = browser.new_page(viewport={"width": 1400, "height": 900})
    errors: list[str] = []
    opened.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    opened.on("pageerror", lambda error: errors.append(str(error)))
    opened.set_default_timeout(WAIT_MS)
    yield opened
    opened.close()
    assert errors == [], errors


def open_page(page: Any, url: str) -> None:
    """Open a monitor page and wait until it has its structure and first snapshot."""
    page.goto(url)
    page.wait_for_function("() => window.monitor && window.monitor.ready === true")


def ended(page: Any) -> None:
    """The page heard the run end (and so stops listening before its server goes)."""
    page.wait_for_function("() => document.querySelector('#status-line').textContent.includes('ENDED')")


def row(page: Any, path: str) -> Any:
    return page.locator(f'#tree [data-path="{path}"]').first


def status_is(page: Any, path: str, status: str) -> None:
    page.wait_for_function(
        '([p, s]) => document.querySelector(`#tree [data-path="${p}"]`).dataset.status === s', arg=[path, status]
    )


def test_the_page_shows_node_statuses_change_as_the_mission_runs(tmp_path, page) -> None:
    """Held at two states' entries in turn (breakpoints), the page shows each as it is."""
    wandering, detecting = "main/entertainer/wandering", "main/entertainer/crowd_detection"
    with live_run(tmp_path / "run", until=60) as live:
        for state in (wandering, detecting):
            assert live.act(action="break", kind="state", target=state).status_code == 200
        open_page(page, live.url + "/")
        row(page, wandering).wait_for(state="attached")
        assert "PAUSED" in page.inner_text("#status-line")
        page.click("#resume")
        status_is(page, wandering, "ACTIVE")
        status_is(page, "main/display", "RUNNING")
        assert row(page, detecting).get_attribute("data-status") == ""
        page.click("#resume")
        status_is(page, detecting, "ACTIVE")
        assert row(page, wandering).get_attribute("data-status") == ""
        assert page.locator("#blackboard tr[data-key='last_checkpoint']").count() == 1
        assert "breakpoint 2" in page.inner_text("#status-line")
        page.click("#resume")
        live.finish()
        ended(page)


def test_a_breakpoint_and_a_forced_outcome_from_the_page_take_the_entertainer_to_the_photo(tmp_path, page) -> None:
    with live_run(tmp_path / "run", until=120) as live:
        open_page(page, live.url + "/")
        row(page, LISTENING).wait_for(state="attached")
        page.select_option("#break-kind", "state")
        page.fill("#break-target", LISTENING)
        page.click("#break-add")
        page.locator("#breakpoints").get_by_text(LISTENING).wait_for()
        page.click("#resume")
        page.wait_for_function("() => /PAUSED.*breakpoint/.test(document.querySelector('#status-line').textContent)")
        assert row(page, LISTENING).get_attribute("data-status") == "ACTIVE"
        held = live.snapshot()["tick"]
        page.fill("#force-node", "listen")
        page.fill("#force-outcome", "heard")
        page.fill("#force-outputs", '{"command": "PHOTO"}')
        page.click("#force-send")
        page.wait_for_function("() => document.querySelector('#message').textContent.includes('heard')")
        assert live.snapshot()["tick"] == held  # forcing does not move the run
        for remove in page.locator("#breakpoints button").all():
            remove.click()
        page.wait_for_function("() => document.querySelectorAll('#breakpoints button').length === 0")
        page.click("#resume")
        status_is(page, "main/entertainer/interaction", "ACTIVE")
        live.finish()
        ended(page)


def test_the_display_page_shows_the_layouts_in_the_order_the_run_set_them(tmp_path, page) -> None:
    folder = tmp_path / "run"
    with live_run(folder, until=200) as live:
        page.goto(live.url + "/display")
        page.wait_for_selector("#layout")
        live.act(action="resume")
        result = live.finish()
        assert result.outcome == "time_limit"
        count = len(live.hub.current_layout()["shown"])
        page.wait_for_function(f"() => document.querySelector('#layout').dataset.count === '{count}'")
        shown = page.locator("#shown li").all_inner_texts()
        layout = page.locator("#layout").get_attribute("data-layout")
        page.goto("about:blank")  # the tablet polls: stop it before its server goes
    last_per_tick: dict[int, str] = {}  # the display skill shows what the key says once a tick
    for event in read_jsonl(folder / "trace.jsonl"):
        if event["ev"] == "bb_write" and event["key"] == "layout":
            last_per_tick[event["tick"]] = event["new"] or "Layout_0"  # empty: the default expression
    expected: list[str] = []
    for name in last_per_tick.values():
        if not expected or expected[-1] != name:
            expected.append(name)
    assert shown == expected
    assert {"Layout_0", "Layout_1", "Layout_2", "Layout_5"} <= set(shown)
    assert layout == shown[-1]


def test_a_finished_run_scrubbed_to_tick_n_shows_what_botstage_tree_prints(tmp_path, page) -> None:
    with replayed_run(tmp_path / "run") as (folder, url):
        open_page(page, url + "/")
        page.wait_for_selector("#scrubber")
        assert page.locator("#estop").is_hidden() or page.locator("#pause").is_hidden()
        for tick in (141, 350):
            page.fill("#tick", str(tick))
            page.press("#tick", "Enter")
            printed = CliRunner().invoke(
                app, ["tree", str(ENTERTAINER), "--trace", str(folder / "trace.jsonl"), "--at", str(tick)]
            )
            wait_until(lambda t=printed.output: page.inner_text("#tree-text").strip() == t.strip(), 30, f"tick {tick}")
            # the map follows the scrubber: the robot where the run recorded it at that tick
            pose = httpx.get(f"{url}/api/at", params={"tick": tick}).json()["robot"]["pose"]
            page.wait_for_function(
                """(want) => {
                  const shown = (document.querySelector("#map").dataset.pose || "").split(",").map(Number);
                  return shown.length === 3 && shown.every((v, i) => Math.abs(v - want[i]) < 0.0011);
                }""",
                arg=pose,
            )


def test_a_teleop_key_moves_the_held_robot_and_its_release_stops_it(tmp_path, page) -> None:
    with live_run(tmp_path / "run", until=30) as live:
        open_page(page, live.url + "/")
        page.wait_for_selector("#map[data-pose]")
        start = [float(v) for v in page.get_attribute("#map", "data-pose").split(",")]
        page.click("#panel-map")  # focus on the page, not on a text field
        page.keyboard.down("ArrowUp")
        page.wait_for_function(
            "x => parseFloat(document.querySelector('#map').dataset.pose.split(',')[0]) > x", arg=start[0] + 0.2
        )
        page.keyboard.up("ArrowUp")
        live.until(lambda s: not s["robot"]["teleop"]["active"], "the release")
        stopped = live.snapshot()["robot"]["pose"]
        page.wait_for_function(
            "p => document.querySelector('#map').dataset.pose === p", arg=",".join(f"{v:.3f}" for v in stopped)
        )
        assert live.snapshot()["robot"]["pose"] == stopped and live.snapshot()["tick"] == -1
        page.click("#resume")
        live.finish()
        ended(page)
