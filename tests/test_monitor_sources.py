"""Several runs on one page: two live runs' monitors (other servers, proxied over real HTTP) and a
finished run behind one overview on 127.0.0.1: each one's API, events and controls through it,
a source that does not answer said so, the token checked before anything is forwarded, and the
overview page in a real headless Chromium with the full monitor of a run under it."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from botstage.missions.monitor.replay import load_run
from botstage.missions.monitor.server import create_app, start_overview
from botstage.missions.monitor.sources import Source, check_remote_url, remote_source, source_name
from botstage.missions.runner import run
from tests.monitor_harness import ROOT, LiveRun, live_run, wait_until
from tests.test_monitor_browser import browser, open_page, page  # noqa: F401  (the browser's fixtures)

HELLO = ROOT / "missions" / "examples" / "hello.yaml"


def closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def overview(tmp_path: Path) -> Iterator[tuple[str, LiveRun, LiveRun]]:
    """Two entertainer runs held before their first tick, each with its monitor, and a finished
    run of hello.yaml, behind one overview: (its URL, the two live runs)."""
    run(HELLO, out=tmp_path / "hello")
    finished = load_run(tmp_path / "hello")
    with live_run(tmp_path / "a", until=30.0) as first, live_run(tmp_path / "b", until=30.0) as second:
        wait_until(lambda: first.hub.flags.paused and second.hub.flags.paused, what="both runs held")
        sources = [remote_source(first.url, [], None), remote_source(second.url, [], None)]
        sources[1].name = "second"
        app = create_app(finished.hub, run=finished)
        sources.append(Source("hello", "finished", app, str(tmp_path / "hello")))
        server = start_overview(sources, port=0, title="two and one")
        try:
            yield server.url, first, second
        finally:
            server.stop()


def test_each_run_is_served_whole_under_the_overview(overview: tuple[str, LiveRun, LiveRun]) -> None:
    url, first, second = overview
    http = httpx.Client(base_url=url, timeout=10.0)
    listed = http.get("/api/sources").json()
    names = [source["name"] for source in listed["sources"]]
    assert listed["title"] == "two and one" and names[1:] == ["second", "hello"]
    name = names[0]
    assert [s["kind"] for s in listed["sources"]] == ["remote", "remote", "finished"]
    assert http.get(f"/s/{name}").headers["location"] == f"{name}/"  # the page's relative URLs need it
    assert "botstage monitor" in http.get(f"/s/{name}/").text
    assert http.get(f"/s/{name}/static/monitor.js").status_code == 200

    # a live run: its summary, a control through the proxy, its events as they stream
    held = http.get(f"/s/{name}/api/summary").json()
    assert held["paused"] and held["tick"] == -1 and held["info"]["mission"] == "peoplebot_entertainer"
    version = http.get(f"/s/{name}/api/snapshot").json()["version"]
    assert http.post(f"/s/{name}/api/control", json={"action": "resume"}).json()["ok"]
    with http.stream("GET", f"/s/{name}/api/events", params={"since": version}) as events:
        delta = next(line for line in events.iter_lines() if line.startswith("data: "))
    assert '"statuses"' in delta
    moving = wait_until(
        lambda: (s := http.get(f"/s/{name}/api/summary").json())["running"] and s, what="a skill running"
    )
    assert moving["states"]["main/entertainer"].startswith("main/entertainer/")
    assert all(entry["path"].startswith("main/") and entry["skill"] for entry in moving["running"])
    assert second.hub.flags.tick == -1, "the other run was not touched"
    first.finish()
    assert http.get(f"/s/{name}/api/summary").json()["ended"]

    # the finished run: its replay API under its own name
    span = http.get("/s/hello/api/range").json()
    assert span["first"] == 0 and span["last"] > 0
    assert http.get("/s/hello/api/summary").json()["ended"]
    assert http.get("/api/processes").status_code == 404  # runs, not a deployment


def test_a_source_that_does_not_answer_is_said_so_and_control_needs_the_token(
    overview: tuple[str, LiveRun, LiveRun],
) -> None:
    _, first, _ = overview
    gone = remote_source(f"http://127.0.0.1:{closed_port()}", [], None, name="gone")
    live = remote_source(first.url, [], "secret", name="live")
    server = start_overview([gone, live], port=0, token="secret")
    try:
        http = httpx.Client(base_url=server.url, timeout=10.0)
        answer = http.get("/s/gone/api/summary")
        assert answer.status_code == 502 and "does not answer" in answer.json()["detail"]
        assert http.get("/api/sources").json()["token_required"]
        refused = http.post("/s/live/api/control", json={"action": "resume"})
        assert refused.status_code == 401 and first.hub.flags.paused
        allowed = http.post(
            "/s/live/api/control", json={"action": "resume"}, headers={"Authorization": "Bearer secret"}
        )
        assert allowed.json()["ok"]
        wait_until(lambda: first.hub.flags.tick >= 0, what="the run resumed")
        assert http.get("/s/live/api/summary").json()["paused"] is False  # viewing needs no token
    finally:
        server.stop()


def test_names_and_addresses() -> None:
    assert source_name("peoplebot_entertainer-2026 11 25") == "peoplebot_entertainer-2026-11-25"
    assert source_name("a", ["a", "a-2"]) == "a-3"
    assert check_remote_url("http://127.0.0.1:8470/") == "http://127.0.0.1:8470"
    for bad in ("127.0.0.1:8470", "ftp://host:1", "http://host:1/?x=1"):
        with pytest.raises(ValueError, match="monitor"):
            check_remote_url(bad)


def test_the_overview_page_shows_every_run_live_and_each_one_whole(
    overview: tuple[str, LiveRun, LiveRun],
    page: Any,  # noqa: F811
) -> None:
    url, first, second = overview
    page.goto(url + "/")
    page.wait_for_selector("article.card[data-source='second'] [data-role=state]")
    assert page.locator("article.card").count() == 3
    assert "paused" in page.locator("article.card[data-source='second'] [data-role=state]").text_content()
    second.act(action="resume")
    card = "article.card[data-source='second']"
    page.wait_for_function(  # the card follows the run: its tick advances
        f"""() => {{
            const t = document.querySelector("{card} [data-role=tick]");
            return t && parseInt(t.textContent.split(' ')[1]) > 20;
        }}"""
    )
    assert "finished" in page.locator("article.card[data-source='hello']").text_content()
    page.check("#side-by-side")
    assert page.locator("#frames iframe").count() == 3
    page.uncheck("#side-by-side")
    open_page(page, url + "/s/second/")  # the whole monitor of one run, under the overview
    page.wait_for_selector('#tree [data-path="main/entertainer"]')
    first.finish()
    second.finish()
