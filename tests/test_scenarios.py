"""Scenario tests: mocks, expectations, validation, the pytest plugin and `botstage test`."""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

import pytest
import yaml

from botstage.missions.scenario import load_scenario, mock_of, run_scenario
from botstage.skills.registry import Registry
from tests.test_cli import botstage

pytest_plugins = ["pytester"]
HELLO = Path("missions/examples/hello.yaml").resolve()


def scenario(tmp_path: Path, text: str):
    path = tmp_path / "s.yaml"
    path.write_text(f"mission: {HELLO}\n" + textwrap.dedent(text))
    return load_scenario(path)


def problems(tmp_path: Path, text: str) -> list[str]:
    return [str(p).replace(str(tmp_path) + "/", "") for p in scenario(tmp_path, text).problems]


def test_a_wrong_expectation_fails_with_a_readable_diff(pytester: pytest.Pytester) -> None:
    folder = pytester.mkdir("scenarios")
    shutil.copy(HELLO, pytester.path / "hello.yaml")
    (folder / "estop.yaml").write_text(
        textwrap.dedent("""\
        mission: ../hello.yaml
        events: [{t: 5, set: {estop: true}}]
        expect:
          outcome: done
          states: [greeting, working/rest, stopped]
    """)
    )
    # in its own process: an in-process run drops the modules it imported (numpy.fft among them),
    # and numpy refuses to load an extension module twice
    result = pytester.runpytest_subprocess("scenarios")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*scenario*estop.yaml failed:",
            "outcome: expected 'done', got 'stopped' (preempted: 'estop' holds)",
            "states: expected (-) vs actual (+):",
            "    greeting",
            "  - working/rest",
            "  + working/patrol",
            "    stopped",
            "trace around the first divergence:",
            '*"ev": "transition"*"dest": "working/patrol"*',
            "run folder: *scenario-estop*",
        ]
    )


def test_mocks_keep_the_real_contract() -> None:
    real = Registry.builtin().get("wait")
    mock = mock_of(real, [])
    assert (mock.name, mock.inputs, mock.outputs, mock.all_outcomes, mock.kind) == (
        real.name,
        real.inputs,
        real.outputs,
        real.all_outcomes,
        real.kind,
    )


def test_undeclared_outcomes_and_outputs_are_located_errors(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        mocks:
          wait: [{outcome: success}, {outcome: crowd_found}]
          check: {always: {outputs: {value: 1}}}
          log: {probability: {success: 0.5, maybe: 0.5}}
          wiat: [{}]
        expect: {never: ["estop and"]}
    """,
    ) == [
        "s.yaml:3:31: error: skill 'wait' has no outcome 'crowd_found' (declared: failure, success)",
        "s.yaml:4:30: error: skill 'check' has no output 'value' (declared: none)",
        "s.yaml:5:37: error: skill 'log' has no outcome 'maybe' (declared: failure, success)",
        "s.yaml:6:3: error: unknown skill 'wiat' (did you mean 'wait'?)",
        "s.yaml:7:18: error: syntax error: invalid syntax in 'estop and' (column 1)",
    ]
    assert problems(tmp_path, "mocks: {wait: [{outcome: success, durations: 2}]}\nexpct: {}\n") == [
        "s.yaml:2:35: error: unknown key 'durations'",
        "s.yaml:3:1: error: unknown key 'expct'",
    ]


def test_a_bad_scenario_is_a_failure_with_its_problems(tmp_path: Path) -> None:
    loaded = scenario(tmp_path, "mocks: {wait: [{outcome: nope}]}\n")
    result = run_scenario(loaded, tmp_path / "run")
    assert not result.passed and "has no outcome 'nope'" in result.failures[0]


def test_seeded_probability_mocks_are_deterministic(tmp_path: Path) -> None:
    text = "seed: 3\nmocks:\n  check: {probability: {success: 0.7, failure: 0.3}}\n"
    traces = []
    for name in ("a", "b"):
        result = run_scenario(scenario(tmp_path, text), tmp_path / name)
        traces.append((tmp_path / name / "trace.jsonl").read_bytes())
        outcomes = [e["outcome"] for e in result.events if e["ev"] == "skill_outcome" and e["skill"] == "check"]
    assert traces[0] == traces[1]
    assert "failure" in outcomes  # the rule really drew both outcomes


def test_never_conditions_stop_the_run_and_fail(tmp_path: Path) -> None:
    result = run_scenario(scenario(tmp_path, "expect: {never: ['greeted']}\n"), tmp_path / "run")
    assert not result.passed
    assert result.failures == ["never-condition 'greeted' held at t=2.1 s"]


def test_a_never_condition_that_cannot_be_evaluated_fails_with_the_reason(tmp_path: Path) -> None:
    result = run_scenario(scenario(tmp_path, "expect: {never: [\"battery_pct > 'low'\"]}\n"), tmp_path / "run")
    assert not result.passed
    assert result.failures == [
        "never-condition \"battery_pct > 'low'\" cannot be evaluated at t=0 s: "
        "TypeError: '>' not supported between instances of 'int' and 'str'"
    ]


def test_a_never_condition_on_a_key_not_written_yet_waits_for_it(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text(HELLO.read_text().replace("  greeted: false\n", ""))
    (tmp_path / "s.yaml").write_text(f"mission: {mission}\nexpect: {{never: ['greeted and estop']}}\n")
    assert run_scenario(load_scenario(tmp_path / "s.yaml"), tmp_path / "run").passed
    (tmp_path / "s.yaml").write_text(f"mission: {mission}\nexpect: {{never: ['greeted']}}\n")
    result = run_scenario(load_scenario(tmp_path / "s.yaml"), tmp_path / "run2")
    assert result.failures == ["never-condition 'greeted' held at t=2.1 s"]


def test_partial_call_matches_and_counts(tmp_path: Path) -> None:
    text = """\
        expect:
          calls:
            - {skill: wait, inputs: {duration: 2.0}, times: 1}
            - {skill: log, inputs: {message: bye}}
            - {skill: set, times: 2}
          blackboard: {greeted: false}
    """
    result = run_scenario(scenario(tmp_path, text), tmp_path / "run")
    assert result.failures == [
        "calls: log was never called with {'message': 'bye'}; it was called with [{'message': 'hello from botstage'}]",
        "calls: set  expected 2 time(s), called 1",
        "blackboard: 'greeted' expected False, got True",
    ]


def test_botstage_test_runs_a_suite_and_fails_on_a_bad_scenario(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs = tmp_path / "tmp"
    runs.mkdir()
    monkeypatch.setenv("TMPDIR", str(runs))  # where `botstage test` puts its run folders
    good = botstage("test", "missions/scenarios/hello")
    assert good.returncode == 0 and "7 passed, 0 failed" in good.stdout
    assert list(runs.iterdir()) == []  # passed scenarios leave nothing behind
    bad = tmp_path / "scenarios"
    bad.mkdir()
    (bad / "wrong.yaml").write_text(f"mission: {HELLO}\nexpect: {{outcome: stopped}}\n")
    result = botstage("test", str(bad))
    assert result.returncode == 1
    assert "0 passed, 1 failed" in result.stdout
    assert "outcome: expected 'stopped', got 'done'" in result.stderr
    (kept,) = runs.iterdir()  # the failure's run folder stays for a look, and its report names it
    assert f"run folder: {kept}" in result.stderr and (kept / "trace.jsonl").is_file()


def test_a_recorded_run_replays_and_catches_a_change_to_the_tree(tmp_path: Path) -> None:
    mission = tmp_path / "hello.yaml"
    shutil.copy(HELLO, mission)
    assert botstage("run", str(mission), "-q", "--out", str(tmp_path / "run")).returncode == 0
    replay = tmp_path / "scenarios" / "replay.yaml"
    replay.parent.mkdir()
    made = botstage("scenario", "from-trace", str(tmp_path / "run" / "trace.jsonl"), "-o", str(replay))
    assert made.returncode == 0, made.stderr
    assert "wrote" in made.stdout
    spec = yaml.safe_load(replay.read_text())
    assert spec["mission"] == "../hello.yaml"
    assert spec["mocks"] == {}  # hello's skills are bookkeeping: they run for real
    assert botstage("test", str(replay)).returncode == 0
    # a deliberate change to the tree: the patrol's time box shrinks below the recorded wait
    mission.write_text(mission.read_text().replace("timeout: 10", "timeout: 3"))
    failed = botstage("test", str(replay))
    assert failed.returncode == 1
    assert "states: expected (-) vs actual (+):" in failed.stderr


def test_from_trace_without_a_summary_asks_for_the_mission(tmp_path: Path) -> None:
    (tmp_path / "trace.jsonl").write_text("")
    result = botstage("scenario", "from-trace", str(tmp_path / "trace.jsonl"), "-o", str(tmp_path / "s.yaml"))
    assert result.returncode == 2 and "name the mission with --mission" in result.stderr


def test_from_trace_of_a_broken_trace_is_a_clear_error(tmp_path: Path) -> None:
    (tmp_path / "trace.jsonl").write_text('{"tick": 0, "ev": "skill_start"\nnot json\n')
    (tmp_path / "summary.json").write_text(json.dumps({"mission_file": str(HELLO)}))
    result = botstage("scenario", "from-trace", str(tmp_path / "trace.jsonl"), "-o", str(tmp_path / "s.yaml"))
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and "Traceback" not in result.stderr
    assert not (tmp_path / "s.yaml").exists()


def test_coverage_counts_and_pictures(tmp_path: Path) -> None:
    cov = tmp_path / "coverage.json"
    result = botstage("test", "missions/scenarios/hello/normal.yaml", "--coverage", "--coverage-file", str(cov))
    assert result.returncode == 0
    assert "44.4% (4/9)" in result.stdout and "untested transition: hello/preempt:estop" in result.stdout
    data = json.loads(cov.read_text())["missions/examples/hello.yaml"]
    assert data["nodes"] == {"covered": 9, "total": 9, "percent": 100.0}
    assert data["node_outcomes"]["hello/working/patrol/patrol/condition"] == {"success": 230}
    assert set(data["untested"]["transitions"]) == {
        "hello/greeting:failure",
        "hello/working:finished",
        "hello/working/patrol:failure",
        "hello/working/rest:failure",
        "hello/preempt:estop",
    }
    text = botstage("machine", "missions/examples/hello.yaml", "--coverage", str(cov)).stdout
    assert "failure -> stopped (untested)" in text and "preempt: estop -> stopped (untested)" in text
    dot = botstage("machine", "missions/examples/hello.yaml", "--coverage", str(cov), "--format", "dot").stdout
    assert dot.count('style=dashed, color="#999999"') == 5  # 4 untested transitions and the preemption
    whole = botstage("test", "missions/scenarios/hello", "--coverage", "--coverage-file", str(cov))  # the whole suite
    assert "100% (9/9)" in whole.stdout and "untested" not in whole.stdout


def test_coverage_of_another_mission_is_refused(tmp_path: Path) -> None:
    cov = tmp_path / "coverage.json"
    cov.write_text('{"other.yaml": {"untested": {"nodes": [], "states": [], "transitions": []}}}')
    result = botstage("tree", "--coverage", str(cov))
    assert result.returncode == 2 and "has no coverage of" in result.stderr


@pytest.mark.parametrize("path", sorted(Path("missions/scenarios").rglob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_scenario_is_deterministic(tmp_path: Path, path: Path) -> None:
    traces = []
    for name in ("a", "b"):
        result = run_scenario(load_scenario(path), tmp_path / name)
        assert result.passed, result.report()
        traces.append((tmp_path / name / "trace.jsonl").read_bytes())
    assert traces[0] == traces[1]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "mocks: {wait: []}\n",
            "s.yaml:2:9: error: mocks.wait: List should have at least 1 item after validation, not 0",
        ),
        (
            "mocks: {log: {probability: {success: 0}}}\n",
            "s.yaml:2:9: error: mocks.log: probability maps outcomes to non-negative weights, not all zero",
        ),
        (
            "events: [{t: 1, set: {'bad key!': 1}}]\n",
            "s.yaml:2:23: error: invalid blackboard key 'bad key!': use identifiers separated by '/', "
            "e.g. 'robot/battery_pct'",
        ),
        ("expect: {calls: [{skill: lgo}]}\n", "s.yaml:2:19: error: unknown skill 'lgo' (did you mean 'log'?)"),
        (
            "expect: {calls: [{skill: log, inputs: {mesage: hi}}]}\n",
            "s.yaml:2:40: error: skill 'log' has no input 'mesage'",
        ),
        (
            "blackboard: {batery_pct: 1}\n",
            "s.yaml:2:14: error: the mission never reads or writes 'batery_pct' (did you mean 'battery_pct'?)",
        ),
        (
            "expect: {never: ['greetd']}\n",
            "s.yaml:2:18: error: unknown blackboard key 'greetd' in 'greetd': the mission never declares, "
            "initialises or writes it (did you mean 'greeted'?)",
        ),
        (
            "expect: {never: ['battery_pct < 5 and robot.estp']}\n",
            "s.yaml:2:18: error: unknown blackboard key 'robot/estp' in 'battery_pct < 5 and robot.estp': "
            "the mission never declares, initialises or writes it",
        ),
        (
            "expect: {blackboard: {gretd: true}}\n",
            "s.yaml:2:23: error: the mission never declares, initialises or writes 'gretd' (did you mean 'greeted'?)",
        ),
        (
            "expect: {counters: {greeted: 1}}\n",
            "s.yaml:2:21: error: 'greeted' is not a counter of the mission (its counters: none)",
        ),
        (
            "expect: {states: [greting]}\n",
            "s.yaml:2:19: error: the mission has no state 'greting' (did you mean 'greeting'?)",
        ),
        (
            "expect: {states_in_order: [working/patrl]}\n",
            "s.yaml:2:28: error: the mission has no state 'working/patrl' (did you mean 'working/patrol'?)",
        ),
        (
            "expect: {within: [{from: {stat: greeting}, to: {state: stopped}, seconds: 2}]}\n",
            "s.yaml:2:27: error: events have no field 'stat' (did you mean 'state'?)",
        ),
        (
            "expect: {within: [{from: {state: greeting}, to: {ev: transtion}, seconds: 2}]}\n",
            "s.yaml:2:50: error: there is no event 'transtion' (did you mean 'transition'?)",
        ),
        (
            "expect: {within: [{from: {key: gretd}, to: {state: stopped}, seconds: 2}]}\n",
            "s.yaml:2:27: error: the mission never declares, initialises or writes 'gretd' (did you mean 'greeted'?)",
        ),
        (
            "mocks: {wait: [{until_cancelled: true, outcome: success}]}\n",
            "s.yaml:2:16: error: mocks.wait.0: a call that runs until cancelled has no outcome: the engine ends it, "
            "not the mock",
        ),
        (
            "mocks: {set: [{duration: 1, writes: [{after: 2, set: {greeted: true}}]}]}\n",
            "s.yaml:2:15: error: mocks.set.0: a write after 2 s never happens: the call ends after 1 s",
        ),
        (
            "mocks: {wait: [{writes: [{set: {greeted: true}}]}]}\n",
            "s.yaml:2:26: error: skill 'wait' writes no blackboard key itself: it has no key port",
        ),
        (
            "mocks: {set: [{writes: [{set: {gretd: true}}]}]}\n",
            "s.yaml:2:32: error: the mission never reads or writes 'gretd' (did you mean 'greeted'?)",
        ),
    ],
)
def test_scripts_and_keys_that_would_silently_do_nothing_are_errors(tmp_path: Path, text: str, expected: str) -> None:
    assert problems(tmp_path, text) == [expected]


def test_a_replay_keeps_the_scenarios_blackboard_overrides(tmp_path: Path) -> None:
    original = scenario(tmp_path, "blackboard: {estop: true}\nexpect: {outcome: stopped}\n")
    result = run_scenario(original, tmp_path / "run")
    assert result.passed, result.report()
    replay = tmp_path / "replay.yaml"
    assert botstage("scenario", "from-trace", str(tmp_path / "run" / "trace.jsonl"), "-o", str(replay)).returncode == 0
    assert yaml.safe_load(replay.read_text())["blackboard"] == {"estop": True}
    assert run_scenario(load_scenario(replay), tmp_path / "again").passed


def test_runs_stopped_by_a_never_condition_are_not_recorded(tmp_path: Path) -> None:
    run_scenario(scenario(tmp_path, "expect: {never: ['greeted']}\n"), tmp_path / "run")
    result = botstage("scenario", "from-trace", str(tmp_path / "run" / "trace.jsonl"), "-o", str(tmp_path / "r.yaml"))
    assert result.returncode == 2 and "stopped by a scenario's never-condition" in result.stderr


def test_the_plugin_only_collects_scenarios_inside_the_root(tmp_path: Path) -> None:
    from botstage.missions.pytest_plugin import is_scenario

    root = tmp_path / "scenarios" / "checkout"  # a checkout living under some folder named scenarios
    assert not is_scenario(root / "robots" / "profiles" / "chefbot.yaml", root)
    assert is_scenario(root / "missions" / "scenarios" / "hello" / "normal.yaml", root)
    assert not is_scenario(root / "missions" / "scenarios" / "notes.txt", root)
