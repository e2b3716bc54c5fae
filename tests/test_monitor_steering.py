"""A run steered by hand from the monitor (an e-stop and its release, driving by hand while held)
replays as a scenario: the trace says what the operator did, `from_trace` turns it into the
scenario's events, and the replay, done the same way (`missions/steering.py`), passes."""

from __future__ import annotations

from pathlib import Path

import yaml

from botstage.behaviors.trace import read_jsonl
from botstage.missions.replay import from_trace
from botstage.missions.scenario import load_scenario, run_scenario
from botstage.missions.steering import ESTOP, TeleopStretch, read_teleop_note, teleop_note
from tests.monitor_harness import live_run, wait_until


def test_an_estopped_and_hand_driven_run_replays_as_a_scenario(tmp_path: Path) -> None:
    folder = tmp_path / "run"
    with live_run(folder, until=40) as live:
        live.until(lambda s: s["paused"], "held before the first tick")
        assert live.act(action="resume").status_code == 200
        wait_until(lambda: live.hub.flags.tick >= 60, what="the run under way")
        assert live.act(action="estop").status_code == 200
        live.until(lambda s: s["estopped"], "the e-stop")
        assert live.act(action="release").status_code == 200
        live.until(lambda s: not s["estopped"] and not s["paused"], "released")
        wait_until(lambda: live.hub.flags.tick >= 120, what="the mission started again")
        assert live.act(action="pause").status_code == 200
        held = live.until(lambda s: s["paused"], "paused")
        for v, w in ((0.2, 0.0), (0.2, 0.6)):  # each command until the world has moved a second on
            start = live.hub.flags.t

            def driven(v: float = v, w: float = w, start: float = start) -> bool:
                assert live.http.post("/api/teleop", json={"v": v, "w": w}).status_code == 200
                return live.hub.flags.t >= start + 1.0

            wait_until(driven, what=f"driving by hand at v={v} w={w}")
        assert live.http.post("/api/teleop", json={"v": 0.0, "w": 0.0}).status_code == 200
        wait_until(lambda: not live.control.teleop_state["active"], what="teleop ended")
        assert live.hub.flags.tick == held["tick"]  # the tree held while the world moved
        assert live.act(action="resume").status_code == 200
        result = live.finish()
    assert result.outcome == "time_limit"
    said = [e["message"] for e in read_jsonl(folder / "trace.jsonl") if e["ev"] == "log" and e["node"] == "monitor"]
    assert ESTOP in said and "teleop v=0.2 w=0.6" in said

    scenario = tmp_path / "steered.yaml"
    from_trace(folder / "trace.jsonl", scenario)
    events = yaml.safe_load(scenario.read_text())["events"]
    assert [e for e in events if e.get("estop")], events
    drives = next(e["teleop"] for e in events if "teleop" in e)
    assert [(d["v"], d["w"]) for d in drives][:2] == [(0.2, 0.0), (0.2, 0.6)]
    assert all(d["seconds"] >= 0.5 for d in drives[:2]), drives  # each held for about a second
    loaded = load_scenario(scenario)
    assert loaded.problems == [], [str(p) for p in loaded.problems]
    replayed = run_scenario(loaded, tmp_path / "replayed")
    assert replayed.passed, replayed.report()
    again = [e for e in replayed.events if e["ev"] == "skill_cancel" and e["reason"] == ESTOP]
    assert again, "the replay's e-stop cancelled the skills as the operator's did"


def test_teleop_lines_give_each_command_and_how_long_it_was_held() -> None:
    assert read_teleop_note(teleop_note(0.25, -0.5)) == (0.25, -0.5)
    assert read_teleop_note("teleop ended") is None and read_teleop_note("teleop v=x w=1") is None
    stretch = TeleopStretch.begin(5.0, 0.2, 0.0)
    stretch.change(6.5, 0.2, 0.5)
    stretch.change(8.0, 0.0, 0.0)
    stretch.end(8.1)
    assert stretch.commands == [(0.2, 0.0, 1.5), (0.2, 0.5, 1.5), (0.0, 0.0, 0.1)]
