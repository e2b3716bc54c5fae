"""The live monitor over real HTTP on 127.0.0.1, driving a real run of the entertainer on its
thread: pausing, stepping, breakpoints, forced outcomes, key writes, the e-stop, the token, a
finished run at any tick, and a steered run replaying as a scenario. (The pages themselves are
tested in headless Chromium in test_monitor_browser.py.)"""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from botstage.behaviors.trace import read_jsonl
from botstage.missions.cli import app
from botstage.missions.monitor.hub import HISTORY, TIMELINE, Hub
from botstage.missions.monitor.pages import STATIC
from botstage.missions.monitor.replay import RunFolderError, load_run
from botstage.missions.monitor.server import MonitorError, start_monitor, start_overview, token_for
from botstage.missions.replay import from_trace
from botstage.missions.scenario import load_scenario, run_scenario
from tests.monitor_harness import ENTERTAINER, LISTENING, live_run, replayed_run, wait_until

PHOTO_MACHINE = "main/entertainer/interaction"


def active(snapshot: dict, state: str) -> bool:
    return any(path == state or path.startswith(state + "/") for path in snapshot["states"].values())


def test_a_breakpoint_on_a_state_holds_the_run_on_entry_and_forcing_listen_takes_it_to_the_photo(tmp_path) -> None:
    """Held before tick 0; a breakpoint on the listening state holds the run as it enters it;
    forcing `listen` to `heard` with command PHOTO takes the entertainer into the photo machine;
    the steered run's trace says so, and replays as a scenario."""
    folder = tmp_path / "run"
    with live_run(folder, until=120) as live:
        held = live.until(lambda s: s["paused"], "the run held before its first tick")
        assert held["tick"] == -1 and held["states"] == {}
        answer = live.act(action="break", kind="state", target=LISTENING)
        assert answer.status_code == 200, answer.text
        assert live.act(action="resume").status_code == 200
        hit = live.until(lambda s: s["paused"] and "breakpoint" in s["pause_reason"], "the breakpoint")
        assert active(hit, LISTENING), hit["states"]
        entered = [
            e for e in hit["timeline"] if e["ev"] == "transition" and e["text"].split(" on ")[0].endswith("listening")
        ]
        assert entered and entered[-1]["tick"] == hit["tick"]  # held in the tick it entered, before the next
        again = live.snapshot()
        assert again["tick"] == hit["tick"]  # and it stays there

        forced = live.act(action="force", node="listen", outcome="heard", outputs={"command": "PHOTO"})
        assert forced.status_code == 200, forced.text
        assert live.act(action="unbreak", id=1).status_code == 200
        assert live.act(action="resume").status_code == 200
        photo = live.until(lambda s: active(s, PHOTO_MACHINE), "the photo machine")
        said = [e["text"] for e in photo["timeline"] if e["ev"] == "skill_outcome"]
        assert any("listen → heard: forced by the operator" in text for text in said), said[-3:]
        result = live.finish()
    assert result.outcome == "time_limit"
    events = read_jsonl(folder / "trace.jsonl")
    outcome = next(e for e in events if e["ev"] == "skill_outcome" and e["reason"].startswith("forced"))
    assert (outcome["skill"], outcome["outcome"], outcome["outputs"]) == ("listen", "heard", {"command": "PHOTO"})
    said = [e["message"] for e in events if e["ev"] == "log" and e["node"] == "monitor"]
    assert said[0] == "paused by the operator" and any(m.startswith("breakpoint 1: entered state") for m in said)

    scenario = tmp_path / "steered.yaml"
    from_trace(folder / "trace.jsonl", scenario)
    loaded = load_scenario(scenario)
    assert loaded.problems == [], [str(p) for p in loaded.problems]
    replayed = run_scenario(loaded, tmp_path / "replayed")
    assert replayed.passed, replayed.report()


def test_step_runs_one_tick_and_holds_again_and_a_written_key_is_the_operators(tmp_path) -> None:
    with live_run(tmp_path / "run", until=30) as live:
        live.until(lambda s: s["paused"], "held")
        ticks = []
        for _ in range(3):
            version = live.snapshot()["version"]
            assert live.act(action="step").status_code == 200
            ticks.append(
                live.until(lambda s, v=version: s["version"] > v and s["paused"] and s["tick"] == len(ticks), "a step")[
                    "tick"
                ]
            )
        assert ticks == [0, 1, 2]
        assert live.act(action="write", key="information", value="closing at six").status_code == 200
        written = live.until(lambda s: s["blackboard"]["information"]["writer"] == "monitor", "the write")
        assert written["blackboard"]["information"]["value"] == "closing at six"
        assert written["tick"] == 2  # written while held, between two ticks
        history = live.http.get("/api/history", params={"key": "information"}).json()
        assert [(h["writer"], h["value"]) for h in history] == [("init", ""), ("monitor", "closing at six")]
        assert live.act(action="resume").status_code == 200
        live.finish()


def test_the_e_stop_cancels_every_skill_and_holds_the_run_until_released(tmp_path) -> None:
    folder = tmp_path / "run"
    with live_run(folder, until=60, paused=False) as live:
        live.until(lambda s: s["tick"] >= 50, "the robot under way")
        assert live.act(action="estop").status_code == 200
        stopped = live.until(lambda s: s["estopped"], "the e-stop")
        assert stopped["paused"] and "e-stop" in stopped["pause_reason"]
        running = [p for p, status in stopped["statuses"].items() if status == "RUNNING"]
        assert running == [], running
        refused = live.act(action="resume")
        assert refused.status_code == 422 and "release it first" in refused.json()["detail"]
        assert live.snapshot()["tick"] == stopped["tick"]
        assert live.act(action="release").status_code == 200
        live.until(lambda s: not s["estopped"] and s["tick"] > stopped["tick"], "running again")
        live.finish()
    cancels = [e for e in read_jsonl(folder / "trace.jsonl") if e["ev"] == "skill_cancel"]
    assert any(e["reason"] == "e-stop from the monitor" for e in cancels)


@pytest.mark.parametrize(
    ("body", "status", "says"),
    [
        ({"action": "fly"}, 422, "unknown action 'fly'"),
        ({"action": "break", "kind": "state", "target": "main/entertainer/nowhere"}, 422, "no state"),
        ({"action": "break", "kind": "sometimes", "target": "x"}, 422, "unknown breakpoint kind"),
        ({"action": "break", "kind": "condition", "target": "battery_pct <"}, 422, "not a condition"),
        ({"action": "force", "node": "fly", "outcome": "success"}, 422, "no skill node or skill 'fly'"),
        ({"action": "force", "node": "listen", "outcome": "maybe"}, 422, "listen has no outcome 'maybe'"),
        (
            {"action": "force", "node": "listen", "outcome": "heard", "outputs": {"volume": 3}},
            422,
            "no output 'volume'",
        ),
        ({"action": "force", "node": "listen", "outcome": "heard", "outputs": {"command": 3}}, 422, "output 'command'"),
        ({"action": "write", "key": "battery_pct", "value": "full"}, 422, "key 'battery_pct'"),
        ({"action": "unbreak", "id": 99}, 422, "no breakpoint 99"),
        (["pause"], 400, "a JSON object"),
    ],
)
def test_a_request_the_run_cannot_carry_out_is_refused_with_the_reason(tmp_path, body, status, says) -> None:
    with live_run(tmp_path / "run", until=5) as live:
        live.until(lambda s: s["paused"], "held")
        answer = live.http.post("/api/control", json=body)
        assert answer.status_code == status, answer.text
        assert says in answer.json()["detail"]
        assert live.act(action="resume").status_code == 200
        live.finish()


def test_with_a_token_control_needs_it_and_viewing_does_not(tmp_path) -> None:
    with live_run(tmp_path / "run", until=5, token="s3cret-token") as live:
        assert live.http.get("/api/info").json()["token_required"] is True
        assert live.http.get("/api/snapshot").status_code == 200
        assert live.act(action="resume").status_code == 401
        wrong = live.http.post("/api/control", json={"action": "resume"}, headers={"Authorization": "Bearer nope"})
        assert wrong.status_code == 401
        right = live.http.post(
            "/api/control", json={"action": "resume"}, headers={"Authorization": "Bearer s3cret-token"}
        )
        assert right.status_code == 200
        live.finish()


def test_listening_beyond_loopback_needs_a_token(monkeypatch) -> None:
    monkeypatch.delenv("BOTSTAGE_MONITOR_TOKEN", raising=False)
    with pytest.raises(MonitorError, match="BOTSTAGE_MONITOR_TOKEN"):
        start_monitor(Hub(), host="0.0.0.0", port=0)  # refused before anything is bound
    assert token_for("127.0.0.1") is None
    monkeypatch.setenv("BOTSTAGE_MONITOR_TOKEN", "from-env")
    assert token_for("0.0.0.0") == "from-env"


def test_the_pages_load_every_module_they_ship_as_javascript() -> None:
    """No build step: each page's scripts and the ES modules they import are the files served,
    each as JavaScript (a browser refuses a module script of any other type), none left over."""
    import re

    import httpx

    def scripts(http: httpx.Client, page: str) -> list[str]:
        answer = http.get(page)
        assert answer.status_code == 200, page
        return re.findall(r'<script[^>]* src="static/([^"]+)"', answer.text)

    monitor, overview = start_monitor(Hub(), port=0), start_overview([], port=0)
    reached: set[str] = set()
    try:
        with httpx.Client(base_url=monitor.url) as http, httpx.Client(base_url=overview.url) as overview_http:
            queue = [(http, name) for page in ("/", "/display") for name in scripts(http, page)]
            queue += [(overview_http, name) for name in scripts(overview_http, "/")]
            while queue:
                client, name = queue.pop()
                answer = client.get(f"/static/{name}")
                assert answer.status_code == 200, name
                assert answer.headers["content-type"].startswith("text/javascript"), (name, answer.headers)
                reached.add(name)
                imports = re.findall(r'^import [^;]* from "\./([^"]+)";$', answer.text, flags=re.M)
                queue += [(client, imported) for imported in imports if imported not in reached]
    finally:
        monitor.stop()
        overview.stop()
    shipped = {path.name for path in STATIC.iterdir() if path.name.endswith(".js")}
    assert reached == shipped
    assert {"monitor.js", "tree.js", "stream.js", "util.js"} <= reached


def test_a_finished_run_at_tick_n_is_what_botstage_tree_prints(tmp_path) -> None:
    import httpx

    with replayed_run(tmp_path / "run") as (folder, url), httpx.Client(base_url=url) as http:
        span = http.get("/api/range").json()
        assert span == {"first": 0, "last": read_jsonl(folder / "trace.jsonl")[-1]["tick"]}
        assert http.get("/api/info").json()["mode"] == "replay"
        assert http.post("/api/control", json={"action": "pause"}).status_code == 409
        assert http.get("/api/at", params={"tick": span["last"] + 1}).status_code == 422
        snapshot = http.get("/api/snapshot").json()
        assert {"robot", "visitor"} <= {line["who"] for line in snapshot["said"]}
        taken = [photo["file"] for photo in snapshot["photos"]]
        assert taken and taken[0].startswith("photos/")
        image = http.get("/api/photo", params={"file": taken[0]})
        assert image.status_code == 200 and image.content[:2] == b"\xff\xd8"
        for outside in ("summary.json", "../../etc/passwd", "photos/none.jpg"):
            assert http.get("/api/photo", params={"file": outside}).status_code == 404
        for tick in (0, 141, 340, span["last"]):
            at = http.get("/api/at", params={"tick": tick}).json()
            printed = CliRunner().invoke(
                app, ["tree", str(ENTERTAINER), "--trace", str(folder / "trace.jsonl"), "--at", str(tick)]
            )
            assert printed.exit_code == 0, printed.output
            assert at["text"] == printed.output


def test_a_folder_that_is_not_a_run_is_refused(tmp_path) -> None:
    with pytest.raises(RunFolderError, match=r"no trace\.jsonl"):
        load_run(tmp_path)


def test_the_hub_stays_bounded_over_an_hour_of_events() -> None:
    """An hour at 10 Hz of a busy run: the timeline and each key's history are rings."""
    hub = Hub()
    for tick in range(36_000):
        t = tick / 10
        hub.apply({"tick": tick, "t": t, "ev": "tick"})
        hub.apply(
            {
                "tick": tick,
                "t": t,
                "ev": "status",
                "node": f"main/n{tick % 50}",
                "old": "INVALID",
                "new": "RUNNING",
                "reason": "",
            }
        )
        hub.apply(
            {"tick": tick, "t": t, "ev": "bb_write", "key": "odom", "old": tick - 1, "new": tick, "writer": "main/n1"}
        )
        hub.apply({"tick": tick, "t": t, "ev": "log", "node": "main/n1", "level": "info", "message": f"line {tick}"})
    snapshot = hub.snapshot()
    assert len(snapshot["timeline"]) == TIMELINE and snapshot["timeline"][-1]["text"] == "line 35999"
    assert len(hub.key_history("odom")) == HISTORY
    assert len(snapshot["statuses"]) == 50
    assert hub.delta(snapshot["version"])["timeline"] == []


def test_teleop_drives_the_held_robot_and_stops_it_on_release_and_by_its_watchdog(tmp_path) -> None:
    """The page's teleop takes over only while the run is held; commands move the simulated robot
    (the world steps, the tree does not tick); a stop stops it, and so does silence."""
    folder = tmp_path / "run"
    with live_run(folder, until=30) as live:
        start = live.until(lambda s: s["paused"] and s["robot"]["teleop"]["allowed"], "held")["robot"]["pose"]
        malformed = ('{"v": "fast", "w": 0}', '{"v": 0.3}', '{"v": true, "w": 0}', '{"v": NaN, "w": 0}', '{"v": 1e999}')
        for bad in malformed:  # refused as the request's fault (422), whatever the run's state
            refused = live.http.post("/api/teleop", content=bad, headers={"content-type": "application/json"})
            assert refused.status_code == 422 and "finite numbers" in refused.json()["detail"], bad
        assert not live.snapshot()["robot"]["teleop"]["active"]

        def driven_forward() -> bool:
            assert live.http.post("/api/teleop", json={"v": 0.4, "w": 0.0}).status_code == 200
            return live.snapshot()["robot"]["pose"][0] > start[0] + 0.2

        wait_until(driven_forward, 60, "the robot driven forward")
        stop = live.http.post("/api/teleop", json={"v": 0.0, "w": 0.0})
        assert stop.json()["message"] == "stopped"
        stopped = live.until(lambda s: not s["robot"]["teleop"]["active"], "the stop")
        held_at = stopped["robot"]["pose"]
        assert live.snapshot()["robot"]["pose"] == held_at
        assert stopped["tick"] == -1  # the tree never ticked

        def turned_left() -> bool:
            assert live.http.post("/api/teleop", json={"v": 0.0, "w": 0.6}).status_code == 200
            return live.snapshot()["robot"]["pose"][2] > held_at[2] + 0.2

        wait_until(turned_left, 60, "the robot turned left")
        # then no more commands: the watchdog stops it, and it stays where it stopped
        quiet = live.until(lambda s: not s["robot"]["teleop"]["active"], "the watchdog")
        assert live.snapshot()["robot"]["pose"] == quiet["robot"]["pose"]

        assert live.http.get("/api/camera.jpg").status_code == 200
        assert live.act(action="resume").status_code == 200
        refused = live.http.post("/api/teleop", json={"v": 0.3, "w": 0.0})
        assert refused.status_code == 409 and "paused" in refused.json()["detail"]
        live.finish()
    said = [e["message"] for e in read_jsonl(folder / "trace.jsonl") if e["ev"] == "log" and e["node"] == "monitor"]
    driven = [m for m in said if m.startswith("teleop v=")]  # each command the page gave, as it changed
    assert driven[0] == "teleop v=0.4 w=0" and "teleop v=0 w=0.6" in driven and said.count("teleop ended") == 2


def test_the_map_is_served_as_map_server_draws_it(tmp_path) -> None:
    import cv2
    import numpy as np

    with live_run(tmp_path / "run", until=5) as live:
        live.until(lambda s: s["paused"], "held")
        meta = live.http.get("/api/map").json()
        image = cv2.imdecode(np.frombuffer(live.http.get("/api/map.png").content, np.uint8), cv2.IMREAD_GRAYSCALE)
        assert image.shape == (meta["height"], meta["width"])
        assert {"hall_centre", "exhibit_c"} <= set(meta["places"])
        assert set(np.unique(image)) <= {0, 205, 254}
        live.act(action="resume")
        live.finish()


WANDERING = "main/entertainer/wandering"


def _off_path(point: list[float], path: list[list[float]]) -> float:
    """How far ``point`` is from the polyline ``path`` (m)."""
    import itertools

    import numpy as np

    p = np.asarray(point[:2], dtype=float)
    best = float("inf")
    for a, b in itertools.pairwise(path):
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        along = float(np.clip(np.dot(p - a, b - a) / max(float(np.dot(b - a, b - a)), 1e-12), 0.0, 1.0))
        best = min(best, float(np.linalg.norm(p - (a + along * (b - a)))))
    return best


def test_the_map_shows_the_path_the_robot_drives_until_its_drive_ends(tmp_path) -> None:
    """The robot view carries the navigation stack's current plan: it starts where the robot
    stood when it planned, the robot then drives along it, and it goes when the drive is cancelled."""
    with live_run(tmp_path / "run", until=60) as live:
        live.until(lambda s: s["paused"], "held")
        assert live.snapshot()["robot"]["path"] == []  # nothing planned before the first tick
        assert live.act(action="break", kind="state", target=WANDERING).status_code == 200
        assert live.act(action="resume").status_code == 200
        hit = live.until(lambda s: s["paused"] and "breakpoint" in s["pause_reason"], "the wander starting")
        robot = hit["robot"]
        path = robot["path"]
        assert len(path) >= 2, path
        start = robot["estimate"]  # the stack plans from the localiser's estimate
        assert abs(path[0][0] - start[0]) < 0.05 and abs(path[0][1] - start[1]) < 0.05, (path[0], start)
        assert live.act(action="unbreak", id=1).status_code == 200
        for _ in range(15):  # 1.5 s of driving, one tick at a time
            version = live.snapshot()["version"]
            assert live.act(action="step").status_code == 200
            stepped = live.paused_after(version, "a step")
        moved = stepped["robot"]
        assert moved["path"][-1] == path[-1]  # the same goal
        assert abs(moved["pose"][0] - robot["pose"][0]) + abs(moved["pose"][1] - robot["pose"][1]) > 0.2
        assert _off_path(moved["pose"], moved["path"]) < 0.3  # the follower cuts corners a little
        assert live.act(action="estop").status_code == 200  # cancels the wander: its drive ends
        stopped = live.until(lambda s: s["estopped"], "the e-stop")
        assert stopped["robot"]["path"] == []
        live.finish()


def test_a_finished_run_shows_the_robot_where_it_was_at_each_tick_and_the_monitor_leaves_the_trace_as_it_was(
    tmp_path,
) -> None:
    """The monitor records poses.csv beside the trace without changing the trace (byte for byte
    against the same run without it); a replay serves the map and the poses at the scrubbed tick;
    a run made without the monitor replays with the simulation's true path."""
    import httpx

    from botstage.missions.monitor.robot_view import read_poses
    from botstage.missions.runner import run

    bare = tmp_path / "bare"
    run(ENTERTAINER, out=bare, until=60)
    with replayed_run(tmp_path / "run") as (folder, url), httpx.Client(base_url=url) as http:
        assert (folder / "trace.jsonl").read_bytes() == (bare / "trace.jsonl").read_bytes()
        rows = read_poses(folder / "poses.csv")
        assert [tick for tick, _, _ in rows] == list(range(0, 600, 2))  # every 0.2 s of mission time
        assert http.get("/api/info").json()["map"] is True
        assert {"hall_centre", "exhibit_c"} <= set(http.get("/api/map").json()["places"])
        for tick in (0, 141, 400):
            recorded = next(row for row in reversed(rows) if row[0] <= tick)
            robot = http.get("/api/at", params={"tick": tick}).json()["robot"]
            assert (robot["pose"], robot["estimate"]) == (recorded[1], recorded[2])
            assert abs(robot["pose"][0] - robot["estimate"][0]) + abs(robot["pose"][1] - robot["estimate"][1]) < 0.1
        assert robot != http.get("/api/at", params={"tick": 0}).json()["robot"]  # it moved
    without = load_run(bare).at(400)["robot"]  # no poses.csv: the true path, no estimate
    assert without["estimate"] is None
    assert abs(without["pose"][0] - robot["pose"][0]) + abs(without["pose"][1] - robot["pose"][1]) < 0.1


def test_botstage_up_serves_the_monitor_from_the_missions_process(tmp_path) -> None:
    """`botstage up DEPLOYMENT --monitor`: the five processes, the mission's process watched live."""
    import socket
    import subprocess
    import sys

    import httpx

    from tests.monitor_harness import ROOT

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    deployment = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "up",
        str(deployment),
        "--until",
        "40",
        "--out",
        str(tmp_path),
    ]
    up = subprocess.Popen(
        [*command, "--monitor", "--monitor-port", str(port)],
        cwd=ROOT,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        # the page on the port is the deployment's overview; the mission's monitor is under it
        mission = f"http://127.0.0.1:{port}/s/navigation_computer"

        def ticking() -> dict | None:
            try:
                answer = httpx.get(f"{mission}/api/snapshot", timeout=5)
            except httpx.HTTPError:
                return None
            snapshot = answer.json() if answer.status_code == 200 else None
            return snapshot if snapshot is not None and snapshot["tick"] >= 50 else None

        seen = wait_until(ticking, 240, "the distributed run on the monitor")
        assert seen["states"]["main/entertainer"].startswith("main/entertainer/")
        info = httpx.get(f"{mission}/api/info", timeout=5).json()
        assert (info["mission"], info["simulated"]) == ("peoplebot_entertainer", True)
        processes = httpx.get(f"http://127.0.0.1:{port}/api/processes", timeout=5).json()
        assert {p["name"]: p["state"] for p in processes} == dict.fromkeys(
            ["robot_computer", "navigation_computer", "kinect_speech_computer", "upload_computer", "display_computer"],
            "running",
        )
        assert "detect_crowd" in next(p for p in processes if p["name"] == "kinect_speech_computer")["skills"]
        output, _ = up.communicate(timeout=300)
    finally:
        up.kill()
    assert up.returncode == 0, output[-3000:]
    assert f"monitor: http://127.0.0.1:{port}/  (the mission: http://127.0.0.1:{port}/s/navigation_computer/)" in output
