"""The Python API: the same spec data as YAML, the same checks (located at the Python lines), the
same pictures and the same trace, and YAML loading into the same objects."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings

from botstage.missions.api import (
    Condition,
    Fallback,
    ForceFailure,
    ForceSuccess,
    If,
    Inverter,
    MachineRef,
    Mission,
    Node,
    OneShot,
    Parallel,
    ReactiveFallback,
    ReactiveSelector,
    ReactiveSequence,
    Repeat,
    Retry,
    Selector,
    Sequence,
    Skill,
    StateMachine,
    Subtree,
    Timeout,
    While,
    key,
)
from botstage.missions.check import check
from botstage.missions.examples import hello_api
from botstage.missions.loader import load
from botstage.missions.runner import MissionInvalid
from botstage.skills.base import In, Outcome
from botstage.skills.base import Skill as SkillBase
from botstage.skills.registry import Registry
from tests.test_mission_fuzz import mutated

ROOT = Path(__file__).resolve().parent.parent
TWIN = ROOT / "missions/examples/hello_api.yaml"
HERE = "tests/test_api.py"  # as problems show it: tests run from the checkout's root


def here() -> int:
    """The line of the caller (where a test builds the part it expects a problem at)."""
    return sys._getframe(1).f_lineno


WAIT = Skill("wait", duration=1)
WAIT_YAML = "{skill: wait, inputs: {duration: 1}}"

NODES: list[tuple[Any, str]] = [
    (Sequence(WAIT, "wait", name="s", memory=False), f"{{sequence: [{WAIT_YAML}, wait], name: s, memory: false}}"),
    (Selector(WAIT), f"{{selector: [{WAIT_YAML}]}}"),
    (Fallback(WAIT, memory=True), f"{{fallback: [{WAIT_YAML}], memory: true}}"),
    (ReactiveSequence(Condition("a"), WAIT), f"{{reactive_sequence: [{{condition: a}}, {WAIT_YAML}]}}"),
    (ReactiveSelector(WAIT), f"{{reactive_selector: [{WAIT_YAML}]}}"),
    (ReactiveFallback(WAIT), f"{{reactive_fallback: [{WAIT_YAML}]}}"),
    (
        Parallel(WAIT, Skill("log", message="x", name="b"), policy="success_on_selected", selected=["b"]),
        f"{{parallel: [{WAIT_YAML}, {{skill: log, inputs: {{message: x}}, name: b}}], "
        "policy: success_on_selected, selected: [b]}",
    ),
    (
        Parallel(WAIT, policy="success_on_all", synchronise=False),
        f"{{parallel: [{WAIT_YAML}], policy: success_on_all, synchronise: false}}",
    ),
    (Inverter(WAIT), f"{{inverter: {WAIT_YAML}}}"),
    (ForceSuccess(WAIT, name="f"), f"{{force_success: {WAIT_YAML}, name: f}}"),
    (ForceFailure(WAIT), f"{{force_failure: {WAIT_YAML}}}"),
    (OneShot(WAIT, policy="on_completion"), f"{{one_shot: {WAIT_YAML}, policy: on_completion}}"),
    (Retry(3, WAIT), f"{{retry: 3, child: {WAIT_YAML}}}"),
    (Repeat("forever", WAIT), f"{{repeat: forever, child: {WAIT_YAML}}}"),
    (Repeat(2, WAIT), f"{{repeat: 2, child: {WAIT_YAML}}}"),
    (Timeout(10, WAIT), f"{{timeout: 10, child: {WAIT_YAML}}}"),
    (While("battery_pct > 20", WAIT), f"{{while: 'battery_pct > 20', child: {WAIT_YAML}}}"),
    (If("greeted", WAIT), f"{{if: greeted, child: {WAIT_YAML}}}"),
    (Condition("not estop", name="ok"), "{condition: not estop, name: ok}"),
    (
        Skill("approach", target=key("crowd_centre"), outputs={"distance": "d"}, success_on=["succeeded", "blocked"]),
        "{skill: approach, inputs: {target: '{crowd_centre}'}, outputs: {distance: d}, "
        "success_on: [succeeded, blocked]}",
    ),
    (Skill("wait", inputs={"duration": 2}, params={"x": 1}), "{skill: wait, inputs: {duration: 2}, params: {x: 1}}"),
    (
        Subtree("greet_visitor", remap={"greeted": "first_greeted"}, name="first"),
        "{subtree: greet_visitor, remap: {greeted: first_greeted}, name: first}",
    ),
    (MachineRef("docking", success_on="docked"), "{machine: docking, success_on: docked}"),
    (Node("wait", {"duration": 5}), "{wait: {duration: 5}}"),  # the general form: any kind, plug-ins too
    (Node("my_kind", 3, child=WAIT, colour="red"), f"{{my_kind: 3, child: {WAIT_YAML}, colour: red}}"),
    (Node("clear_costmap"), "{clear_costmap: null}"),
]


@pytest.mark.parametrize(("node", "text"), NODES, ids=lambda x: x.kind if hasattr(x, "kind") else "")
def test_each_node_kind_is_the_spec_its_yaml_loads_as(node: Any, text: str) -> None:
    assert node.to_dict() == yaml.safe_load(text)


def test_a_machine_is_the_spec_its_yaml_loads_as() -> None:
    inner = StateMachine(outcomes=["finished"], initial="patrol")
    inner.add_state("patrol", tree="patrol", transitions={"success": "rest", "failure": "finished"})
    inner.add_state("rest", skill=Skill("wait", duration=1.5), transitions={"success": "patrol"})
    machine = StateMachine(outcomes=["done", "stopped"], initial="greeting")
    machine.add_preemption("estop", to="stopped")
    machine.add_state("greeting", tree=Sequence(WAIT), transitions={"success": "working", "failure": "stopped"})
    machine.add_state(
        "working",
        machine=inner,
        timeout=30,
        on_exit=[{"log": "leaving work"}],
        transitions={"finished": [{"to": "done", "if": "greeted"}, {"to": "greeting"}], "timeout": "done"},
    )
    machine.add_state("alone", skill="log", inputs={"message": "x"}, outputs={}, transitions={"success": "done"})
    assert machine.to_dict() == yaml.safe_load(
        textwrap.dedent(f"""\
        initial: greeting
        outcomes: [done, stopped]
        preemptions:
          - {{when: estop, to: stopped}}
        states:
          greeting:
            tree: {{sequence: [{WAIT_YAML}]}}
            transitions: {{success: working, failure: stopped}}
          working:
            timeout: 30
            on_exit: [{{log: leaving work}}]
            machine:
              initial: patrol
              outcomes: [finished]
              states:
                patrol: {{tree: patrol, transitions: {{success: rest, failure: finished}}}}
                rest: {{skill: wait, inputs: {{duration: 1.5}}, transitions: {{success: patrol}}}}
            transitions:
              finished: [{{to: done, if: greeted}}, {{to: greeting}}]
              timeout: done
          alone: {{skill: log, inputs: {{message: x}}, outputs: {{}}, transitions: {{success: done}}}}
        """)
    )
    # a machine among a tree's children is a machine node
    assert Sequence(inner).to_dict()["sequence"][0] == {"machine": inner.to_dict()}


def test_building_mistakes_python_cannot_represent_raise_at_once() -> None:
    machine = StateMachine()
    machine.add_state("a", skill="wait")
    with pytest.raises(ValueError, match="already has a state 'a'"):
        machine.add_state("a", skill="wait")
    with pytest.raises(TypeError, match="pass children one by one"):
        Sequence([WAIT, WAIT])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="use tree="):
        machine.add_state("b", skill=Sequence(WAIT))  # type: ignore[arg-type]
    mission = Mission("m")
    mission.add_tree("main", WAIT)
    with pytest.raises(ValueError, match="already has a tree 'main'"):
        mission.add_tree("main", WAIT)


def test_a_mistake_in_a_python_tree_is_reported_at_its_python_line() -> None:
    mission = Mission("m", blackboard={"battery_pct": 50})
    line = here() + 1
    mission.add_tree("main", Sequence(
        Condition("battery_pct > 20"),
        Skill("wiat", duration=1),
        Timeout(5, Skill("wait", duration="soon")),
        Skill("log", message=key("greting")),
    ))  # fmt: skip
    problems = [str(p) for p in mission.check().problems]
    assert problems == [
        f"{HERE}:{line + 2}:9: error: unknown skill 'wiat' (did you mean 'wait'?)",
        f"{HERE}:{line + 3}:20: error: input 'duration' of 'wait': expected float, got str 'soon' "
        "(Input should be a valid number)",
        f"{HERE}:{line + 4}:9: error: blackboard key 'greting' is read here but nothing writes or initialises it "
        "(initialise it under `blackboard:`)",
    ]


def test_machine_and_mission_mistakes_are_reported_where_python_made_them() -> None:
    first = here() + 1
    mission = Mission("m", robot="peoplbot", world="museum")
    machine = StateMachine(outcomes=["done"])
    machine.add_state("a", skill="wait", inputs={"duration": 1}, transitions={"success": "b", "failure": "done"})
    machine.add_state("orphan", skill="wait", inputs={"duration": 1}, transitions={"success": "done"})
    machine.add_preemption("estop", to="stoped")
    mission.machine = machine
    mission.seed = "many"
    assert [str(p) for p in mission.check().problems] == [
        f"{HERE}:{first}:15: error: unknown robot 'peoplbot' (did you mean 'peoplebot'?)",
        f"{HERE}:{first + 2}:5: error: transition to unknown state 'b'",
        f"{HERE}:{first + 3}:5: error: state 'orphan' can end with outcome 'failure' but has no transition for it "
        "(add `failure: <state or outcome>` to its transitions)",
        f"{HERE}:{first + 3}:5: error: state 'orphan' is unreachable: no transition or preemption leads to it",
        f"{HERE}:{first + 4}:5: error: blackboard key 'estop' is read here but nothing writes or initialises it "
        "(initialise it under `blackboard:`)",
        f"{HERE}:{first + 4}:5: error: unknown state or outcome 'stoped'",
        f"{HERE}:{first + 6}:5: error: seed: input should be a valid integer, unable to parse string as an integer",
    ]


def test_python_and_yaml_report_the_same_mistake_with_the_same_message(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("name: m\ntrees:\n  main:\n    skill: wiat\n    inputs: {duration: 1}\n")
    from_yaml = check(tmp_path / "m.yaml").problems
    from_python = Mission("m", trees={"main": Skill("wiat", duration=1)}).check().problems
    assert [(p.message, p.hint) for p in from_python] == [(p.message, p.hint) for p in from_yaml]
    assert from_yaml[0].location.line == 4 and from_python[0].location.file == HERE


def test_columns_count_characters_not_bytes() -> None:
    line = here() + 1
    tree = Sequence(Condition("'é' != 'e'"), Skill("wiat"))  # the skill is the 45th character
    (problem,) = Mission("m", trees={"main": tree}).check().problems
    assert str(problem).startswith(f"{HERE}:{line}:46: error: unknown skill 'wiat'")


def test_values_that_are_not_data_are_located_problems() -> None:
    line = here() + 1
    mission = Mission("m", trees={"main": Skill("wait", duration=object())})
    with pytest.raises(ValueError, match=r"object .* cannot be written in a mission"):
        mission.to_dict()
    (problem,) = mission.check().problems
    assert str(problem).startswith(f"{HERE}:{line}:43: error: object <object object")


def test_the_example_and_its_yaml_twin_check_draw_and_run_alike(tmp_path: Path) -> None:
    python, twin = hello_api.build(), Mission.from_yaml(TWIN)
    assert python.check().ok and twin.check().ok
    assert python.draw(machine=True) == twin.draw(machine=True)
    assert python.draw("mermaid") == twin.draw("mermaid")
    a = python.run(out=tmp_path / "python")
    b = twin.run(out=tmp_path / "yaml")
    assert (a.outcome, a.summary["counters"]) == (b.outcome, b.summary["counters"]) == ("done", {"laps": 3})
    assert (tmp_path / "python/trace.jsonl").read_bytes() == (tmp_path / "yaml/trace.jsonl").read_bytes()
    # the Python mission ran from the file it wrote; the unchanged YAML one from its own file
    assert a.summary["mission_file"] == str((tmp_path / "python/mission.yaml").resolve())
    assert b.summary["mission_file"] == str(TWIN.resolve())
    assert Mission.from_yaml(tmp_path / "python/mission.yaml").to_dict() == {**python.to_dict()}


def test_run_takes_the_runners_options_and_refuses_an_invalid_mission(tmp_path: Path) -> None:
    mission = hello_api.build()
    result = mission.run(out=tmp_path / "short", until=2.0, seed=3)
    assert result.outcome == "time_limit" and result.summary["seed"] == 3
    mission.trees["patrol"].children[1] = Skill("wiat")
    with pytest.raises(MissionInvalid, match=f"{HERE}:{here() - 1}:43: error: unknown skill 'wiat'"):
        mission.run(out=tmp_path / "never")
    assert not (tmp_path / "never").exists()


def test_a_yaml_mission_changed_in_python_runs_what_changed(tmp_path: Path) -> None:
    mission = Mission.from_yaml(TWIN)
    mission.machine.preemptions[0].when = "laps >= 1"
    result = mission.run(out=tmp_path)
    assert result.summary["counters"] == {"laps": 1}
    assert (tmp_path / "mission.yaml").exists()


def test_draw_gives_every_format_of_the_cli() -> None:
    mission = hello_api.build()
    assert mission.draw().startswith("machine hello_api")  # what runs: the machine, trees inside
    assert "└── count" in mission.draw(tree="patrol")
    assert mission.draw("json", tree="greet").startswith("{")
    assert "stateDiagram" in mission.draw("mermaid", machine=True) or "flowchart" in mission.draw(
        "mermaid", machine=True
    )
    assert mission.draw("dot", machine=True).startswith("digraph")
    assert mission.draw("unicode", machine=True).startswith("machine hello_api")
    with pytest.raises(ValueError, match="unknown format"):
        mission.draw("gif", machine=True)
    with pytest.raises(ValueError, match="no tree 'nope'"):
        mission.draw(tree="nope")


def test_to_yaml_is_a_mission_file_that_loads_back(tmp_path: Path) -> None:
    mission = hello_api.build()
    path = tmp_path / "saved.yaml"
    path.write_text(mission.to_yaml())
    assert load(path).data == mission.to_dict()
    assert check(path).ok
    assert "      - skill: count\n        inputs: {key: laps}\n" in mission.to_yaml()


@pytest.mark.parametrize(
    "path",
    sorted(Path("missions/examples").glob("*.yaml")) + sorted(Path("missions/lib").glob("*.yaml")),
    ids=lambda p: p.stem,
)
def test_every_shipped_mission_loads_into_the_api_unchanged(path: Path, tmp_path: Path) -> None:
    mission = Mission.from_yaml(path)
    assert mission.to_dict() == load(path).data
    assert [str(p) for p in mission.check().problems] == [str(p) for p in check(path).problems]
    saved = tmp_path / path.name
    saved.write_text(mission.to_yaml())
    assert load(saved).data == mission.to_dict()


def test_trees_and_machines_of_a_file_are_the_apis_objects() -> None:
    mission = Mission.from_yaml("missions/examples/hello.yaml")
    assert isinstance(mission.machine, StateMachine)
    assert isinstance(mission.trees["patrol"], ReactiveSequence)
    assert isinstance(mission.trees["patrol"].children[1], Timeout)
    working = mission.machine.states["working"].options["machine"]
    assert isinstance(working, StateMachine) and list(working.states) == ["patrol", "rest"]


def test_a_broken_file_is_reported_as_check_reports_it(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text("name: m\nname: n\ntrees:\n  main: {sequence: [{wiat: {duration: 1}}], memry: true}\nbogus: 1\n")
    assert [str(p) for p in Mission.from_yaml(path).check().problems] == [str(p) for p in check(path).problems]
    assert len(check(path).problems) == 4
    path.write_text("trees: [\n")
    with pytest.raises(MissionInvalid, match="YAML syntax"):
        Mission.from_yaml(path)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_files_check_the_same_through_the_api(text: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "mutant.yaml"
        path.write_text(text, encoding="utf-8")
        expected = [str(p) for p in check(path).problems]
        try:
            mission = Mission.from_yaml(path)
        except MissionInvalid as exc:
            assert [str(p) for p in exc.problems] == expected
            return
        assert [str(p) for p in mission.check().problems] == expected


class Wave(SkillBase):
    name = "wave"
    inputs = {"times": In(int, default=2)}

    def run(self, ctx: Any, times: int) -> Any:
        for _ in range(times):
            yield
        return Outcome.success()


def test_plugin_skills_take_the_general_form() -> None:
    registry = Registry.default()
    registry.register(Wave)
    mission = Mission("waving", until=5, trees={"main": Sequence(Node("wave", {"times": 3}), Skill("wave"))})
    assert not mission.check().ok  # the default registry does not know it
    assert mission.check(registry).ok
    assert "wave  times=3" in mission.draw(registry=registry)


def test_from_python_finds_a_modules_mission() -> None:
    by_module = Mission.from_python("botstage.missions.examples.hello_api")
    by_file = Mission.from_python(ROOT / "missions/examples/hello_api.py")
    assert by_module.to_dict() == by_file.to_dict() == hello_api.build().to_dict()


def test_the_example_module_runs(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "botstage.missions.examples.hello_api", "--out", str(tmp_path / "run")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "hello_api: outcome done after 3 laps" in result.stdout
    assert "preempt: laps >= 3 -> done" in result.stdout
    assert (tmp_path / "run/trace.jsonl").exists() and (tmp_path / "run/mission.yaml").exists()
