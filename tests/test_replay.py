"""Record and replay: `from_trace` of a run gives a scenario that validates, passes and does what
the run did (every shipped mission, seeds 1-5; the face tracker 1-2); mocks that write, run until cancelled and replay
outputs; the replay of a scenario's run and of an interrupted run."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml

from botstage.behaviors.trace import read_jsonl
from botstage.missions.replay import BOOKKEEPING, from_trace
from botstage.missions.runner import run
from botstage.missions.scenario import load_scenario, run_scenario
from botstage.skills.registry import Registry

MISSIONS = sorted(Path("missions/examples").glob("*.yaml"))


def without_logs(folder: Path) -> list[dict[str, Any]]:
    """A run's trace but what skills logged (a mocked skill does not log what the real one did)."""
    return [e for e in read_jsonl(folder / "trace.jsonl") if e["ev"] != "log"]


def replay(run_folder: Path, tmp_path: Path, name: str = "replay") -> tuple[dict[str, Any], Path]:
    """The scenario from_trace writes for a run, checked and run; its spec and its run folder."""
    scenario_file = tmp_path / f"{name}.yaml"
    spec = from_trace(run_folder / "trace.jsonl", scenario_file)
    loaded = load_scenario(scenario_file)
    assert loaded.problems == [], [str(p) for p in loaded.problems]
    result = run_scenario(loaded, tmp_path / f"{name}-run")
    assert result.passed, result.report()
    return spec, tmp_path / f"{name}-run"


# Two seeds a mission keep CI's budget: seed 1 and a second that differs from mission to
# mission, so seeds 2 to 5 are all replayed somewhere. The face tracker renders and runs the
# chapter's detector on 600 frames a run (~40 s on two cores): seed 1 only.
HEAVY = {"face_tracker": (1,)}
RUNS = [(m, seed) for i, m in enumerate(MISSIONS) for seed in HEAVY.get(m.stem, (1, 2 + i % 4))]


@pytest.mark.parametrize(("mission", "seed"), RUNS, ids=[f"{m.stem}-{seed}" for m, seed in RUNS])
def test_every_shipped_mission_replays_its_run(tmp_path: Path, mission: Path, seed: int) -> None:
    """The replay validates, passes (the run's outcome, states in order, calls per skill, counters)
    and its trace is the run's, event for event and tick for tick: the same skill calls with the
    same outcomes, outputs and cancels, the same blackboard writes by the same nodes."""
    recorded = run(mission, seed=seed, out=tmp_path / "run")
    spec, replayed = replay(tmp_path / "run", tmp_path)
    assert spec["expect"]["outcome"] == recorded.outcome
    assert set(spec["mocks"]).isdisjoint(BOOKKEEPING)  # bookkeeping runs for real
    original, again = without_logs(tmp_path / "run"), without_logs(replayed)
    assert [e for e in again if e["ev"] == "transition"] == [e for e in original if e["ev"] == "transition"]
    assert again == original


@pytest.mark.parametrize(
    "path",
    [
        *sorted(Path("missions/scenarios/hello").glob("*.yaml")),
        "mock_all: true\n",  # bookkeeping mocked too: the replay mocks it as the recording did
        "seed: 3\nmocks: {check: {probability: {success: 0.7, failure: 0.3}}}\n",
        "mocks: {wait: [{duration: 1}, {raises: boom}]}\n",
        "events: [{t: 3, set: {battery_pct: 10}}, {t: 3, set: {battery_pct: 50}}, {t: 9.05, set: {estop: true}}]\n",
    ],
    ids=lambda p: p.stem if isinstance(p, Path) else p.split(":")[0],
)
def test_a_scenarios_own_run_replays(tmp_path: Path, path: Path | str) -> None:
    """Mocks, events and e-stops of a scenario come back in the replay of its run."""
    if isinstance(path, str):
        path = scenario_file(tmp_path, Path("missions/examples/hello.yaml").resolve(), path, "recording")
    result = run_scenario(load_scenario(path), tmp_path / "run")
    assert result.passed, result.report()
    _, replayed = replay(tmp_path / "run", tmp_path)
    assert without_logs(replayed) == without_logs(tmp_path / "run")


HERE = "mission: {mission}\n"


def mission_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def scenario_file(tmp_path: Path, mission: Path, text: str, name: str = "s") -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(HERE.format(mission=mission) + textwrap.dedent(text))
    return path


# A machine whose guards read what `count` and `set` write, and a world skill (spin) that a time
# box cancels: the two ways a replay went wrong.
GUARDED = """\
    name: guarded
    until: 20
    blackboard: {visits: 0, mode: idle}
    counters: [visits]
    trees:
      visit:
        sequence:
          - count: {key: visits}
          - set: {key: mode, value: busy}
          - timeout: 1.5
            child: {spin: {}}
    machine:
      initial: visiting
      outcomes: [done]
      states:
        visiting:
          tree: visit
          transitions:
            failure: [{to: done, if: "visits >= 3"}, {to: resting, if: "mode == 'busy'"}, {to: done}]
            success: done
        resting:
          skill: wait
          inputs: {duration: 1}
          transitions: {success: visiting, failure: done}
"""


def test_a_cancelled_call_is_replayed_as_running_until_the_same_cancel(tmp_path: Path) -> None:
    mission = mission_file(tmp_path, GUARDED)
    recording = scenario_file(tmp_path, mission, "mocks: {spin: {always: {duration: 5}}}\n", "recording")
    result = run_scenario(load_scenario(recording), tmp_path / "run")
    assert result.passed, result.report()
    cancels = [e for e in result.events if e["ev"] == "skill_cancel" and e["skill"] == "spin"]
    assert len(cancels) == 3
    spec, replayed = replay(tmp_path / "run", tmp_path)
    assert spec["mocks"]["spin"] == [{"until_cancelled": True, "times": 3}]  # never a made-up outcome
    assert spec["expect"]["states"] == [
        "visiting",
        "resting",
        "visiting",
        "resting",
        "visiting",
        "done",
    ]
    assert spec["expect"]["counters"] == {"visits": 3}
    assert without_logs(replayed) == without_logs(tmp_path / "run")


def test_until_cancelled_holds_running_until_the_engine_cancels(tmp_path: Path) -> None:
    mission = mission_file(tmp_path, GUARDED.replace("timeout: 1.5", "timeout: 7.5"))
    scenario = scenario_file(
        tmp_path,
        mission,
        """\
        until: 4
        mocks: {spin: [{until_cancelled: true}]}
        expect: {states: [visiting], calls: [{skill: spin, times: 1}]}
        """,
    )
    result = run_scenario(load_scenario(scenario), tmp_path / "run")
    assert result.passed, result.report()
    spin = [e for e in result.events if e.get("skill") == "spin"]
    assert [(e["ev"], e["t"]) for e in spin] == [("skill_start", 0.0), ("skill_cancel", 4.0)]
    assert spin[-1]["reason"] == "mission ended"


def test_mocks_replay_the_writes_and_outputs_the_real_call_made(tmp_path: Path) -> None:
    """A recording whose scenario mocked `count` (so the replay mocks it too): its writes come back
    at the same moments, and the guards that read them take the same branches."""
    mission = mission_file(tmp_path, GUARDED)
    recording = scenario_file(
        tmp_path,
        mission,
        """\
        mocks:
          count:
            - {duration: 0.3, writes: [{after: 0.2, set: {visits: 5}}]}
          spin: {always: {outcome: failure, duration: 0.5}}
        expect: {states: [visiting, done], counters: {visits: 5}}
        """,
        "recording",
    )
    result = run_scenario(load_scenario(recording), tmp_path / "run")
    assert result.passed, result.report()
    spec, replayed = replay(tmp_path / "run", tmp_path)
    assert spec["mocks"]["count"] == [
        {"outcome": "success", "duration": 0.3, "writes": [{"after": 0.2, "set": {"visits": 5}}]}
    ]
    assert "set" not in spec["mocks"]  # not mocked in the recording: runs for real
    assert without_logs(replayed) == without_logs(tmp_path / "run")


def test_outputs_and_their_writes_are_replayed_once(tmp_path: Path) -> None:
    mission = mission_file(
        tmp_path,
        """\
        name: outputs
        until: 5
        trees:
          main:
            sequence:
              - detect_crowd: {}
                outputs: {centre: centre, size: size}
              - condition: "size == 3 and centre[0] > 1"
        """,
    )
    recording = scenario_file(
        tmp_path,
        mission,
        """\
        mocks:
          detect_crowd: [{outcome: crowd_found, duration: 0.4, outputs: {centre: [1.5, 2.0], size: 3}}]
        expect: {outcome: success}
        """,
        "recording",
    )
    assert run_scenario(load_scenario(recording), tmp_path / "run").passed
    spec, replayed = replay(tmp_path / "run", tmp_path)
    (call,) = spec["mocks"]["detect_crowd"]
    assert call == {"outcome": "crowd_found", "duration": 0.4, "outputs": {"centre": [1.5, 2.0], "size": 3}}
    writes = [e for e in read_jsonl(replayed / "trace.jsonl") if e["ev"] == "bb_write"]
    assert [(e["key"], e["new"], e["t"]) for e in writes] == [("centre", [1.5, 2.0], 0.4), ("size", 3, 0.4)]


def test_an_interrupted_run_replays_up_to_where_it_was_stopped(tmp_path: Path) -> None:
    def stop_at_tick_42(engine: Any) -> None:
        if engine.clock.ticks == 42:
            raise KeyboardInterrupt  # what Ctrl-C does mid-run

    recorded = run(Path("missions/examples/hello.yaml"), out=tmp_path / "run", before_tick=stop_at_tick_42)
    assert recorded.outcome == "interrupted"
    spec, replayed = replay(tmp_path / "run", tmp_path)
    assert spec["until"] == 4.2 and spec["expect"]["outcome"] == "time_limit"
    assert spec["expect"]["states"] == ["greeting", "working/patrol"]
    transitions = [e for e in read_jsonl(replayed / "trace.jsonl") if e["ev"] == "transition" and e["dest"]]
    assert [e["dest"] for e in transitions] == ["greeting", "working/patrol"]


def test_a_recorded_run_replays_and_catches_a_change_to_the_tree(tmp_path: Path) -> None:
    mission = tmp_path / "hello.yaml"
    mission.write_text(Path("missions/examples/hello.yaml").read_text())
    run(mission, out=tmp_path / "run")
    spec, _ = replay(tmp_path / "run", tmp_path)
    assert spec["mission"] == "hello.yaml" and spec["mocks"] == {}  # hello's skills are all bookkeeping
    # a deliberate change to the tree: the patrol's time box shrinks below its wait
    mission.write_text(mission.read_text().replace("timeout: 10", "timeout: 3"))
    result = run_scenario(load_scenario(tmp_path / "replay.yaml"), tmp_path / "changed")
    assert not result.passed
    assert any(f.startswith("states: expected (-) vs actual (+):") for f in result.failures)


def test_repeated_calls_are_compacted_and_replayed_in_order(tmp_path: Path) -> None:
    mission = mission_file(tmp_path, GUARDED)
    recording = scenario_file(
        tmp_path,
        mission,
        "mocks: {spin: [{outcome: failure, duration: 0.2, times: 2}, {outcome: timeout, duration: 0.2}]}\n",
        "recording",
    )
    assert run_scenario(load_scenario(recording), tmp_path / "run").passed
    spec, replayed = replay(tmp_path / "run", tmp_path)
    assert spec["mocks"]["spin"] == [
        {"outcome": "failure", "duration": 0.2, "times": 2},
        {"outcome": "timeout", "duration": 0.2},
    ]
    assert without_logs(replayed) == without_logs(tmp_path / "run")


def test_a_skill_that_is_not_installed_is_a_clear_error(tmp_path: Path) -> None:
    mission = mission_file(tmp_path, GUARDED)
    recording = scenario_file(tmp_path, mission, "mocks: {spin: {always: {duration: 0.2}}}\n", "recording")
    run_scenario(load_scenario(recording), tmp_path / "run")
    builtin, registry = Registry.builtin(), Registry()
    for name in builtin:
        if name != "spin":
            registry.register(builtin.get(name))
    with pytest.raises(ValueError, match="skill 'spin', which is not installed"):
        from_trace(tmp_path / "run" / "trace.jsonl", tmp_path / "r.yaml", registry=registry)


def test_the_replay_file_is_plain_yaml_a_reader_can_follow(tmp_path: Path) -> None:
    mission = mission_file(tmp_path, GUARDED)
    recording = scenario_file(tmp_path, mission, "mocks: {spin: {always: {duration: 5}}}\n", "recording")
    run_scenario(load_scenario(recording), tmp_path / "run")
    from_trace(tmp_path / "run" / "trace.jsonl", tmp_path / "r.yaml")
    data = yaml.safe_load((tmp_path / "r.yaml").read_text())
    assert list(data) == ["mission", "description", "seed", "until", "mocks", "expect"]
    assert data["expect"]["calls"] == [
        {"skill": "count", "times": 3},
        {"skill": "set", "times": 3},
        {"skill": "spin", "times": 3},
        {"skill": "wait", "times": 2},
    ]


@pytest.mark.parametrize(
    ("summary", "says"),
    [
        ("[1, 2]", "summary.json: not a run's summary (the file: Input should be a valid dictionary"),
        ('{"mission_file": 5}', "summary.json: not a run's summary (mission_file: Input should be a valid string)"),
        ("{not json", "summary.json: not a run's summary (Expecting property name"),
    ],
)
def test_a_broken_summary_is_a_clear_error(tmp_path: Path, summary: str, says: str) -> None:
    (tmp_path / "trace.jsonl").write_text("")
    (tmp_path / "summary.json").write_text(summary)
    with pytest.raises(ValueError, match=re.escape(says)):
        from_trace(tmp_path / "trace.jsonl", tmp_path / "s.yaml")
    assert not (tmp_path / "s.yaml").exists()


@pytest.mark.parametrize(
    "line", ["[1]", '"text"', '{"ev": "skill_start", "tick": 0}', '{"ev": "bb_write", "tick": "x"}']
)
def test_a_line_that_is_not_an_event_is_a_located_error(tmp_path: Path, line: str) -> None:
    (tmp_path / "trace.jsonl").write_text('{"tick": 0, "t": 0.0, "ev": "tick"}\n' + line + "\n")
    (tmp_path / "summary.json").write_text(
        '{"mission_file": "missions/examples/hello.yaml", "outcome": "interrupted", "ticks": 5}'
    )
    with pytest.raises(ValueError, match=r"trace\.jsonl:2: not a trace event"):
        from_trace(tmp_path / "trace.jsonl", tmp_path / "s.yaml")
