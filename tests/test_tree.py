"""Trees from specs: composites, decorators, subtrees, and the cancellation guarantees."""

from __future__ import annotations

from typing import Any

import pytest
from py_trees.common import Status

from botstage.behaviors.builder import SpecError
from tests.conftest import index_of


def run_tree(make_engine, spec: Any, ticks: int = 50, trees: dict | None = None, values: dict | None = None):
    engine = make_engine()
    for key, value in (values or {}).items():
        engine.blackboard.set(key, value)
    engine.set_root(engine.builder(trees=trees).tree(spec))
    status = engine.run(max_ticks=ticks)
    return engine, status


def skills_started(engine) -> list[str]:
    return [e["node"].rsplit("/", 1)[-1] for e in engine.trace.of("skill_start")]


def test_sequence_selector_and_bindings(make_engine) -> None:
    spec = {
        "sequence": [
            {"fail": {"reason": "first"}, "name": "a"} if False else {"set": {"key": "x", "value": 21}},
            {"think": {"x": "{x}"}, "outputs": {"y": "{answer}"}},
            {"selector": [{"fail": None}, {"check": {"condition": "answer == 42"}}]},
        ]
    }
    engine, status = run_tree(make_engine, spec)
    assert status is Status.SUCCESS
    assert engine.blackboard.get("answer") == 42
    assert skills_started(engine) == ["set", "think", "fail", "check"]


def test_yaml_style_key_reference(make_engine) -> None:
    # YAML reads `x: {speed}` as {"speed": None}: that is a key reference too
    engine, _status = run_tree(make_engine, {"drive": {"speed": {"speed": None}}}, ticks=2, values={"speed": 0.7})
    assert engine.trace.of("skill_start")[0]["inputs"] == {"speed": 0.7}


def test_parallel_policies(make_engine) -> None:
    one = {"parallel": [{"wait": {"duration": 0.3}}, "drive"], "policy": "success_on_one"}
    engine, status = run_tree(make_engine, one)
    assert status is Status.SUCCESS
    assert engine.trace.of("skill_outcome")[0]["t"] == 0.3  # finished at t=0.3, and the drive was cancelled
    assert [e["node"] for e in engine.trace.of("skill_cancel")] == ["root/drive"]
    everything = {"parallel": [{"wait": {"duration": 0.2}}, {"wait": {"duration": 0.5}, "name": "long"}]}
    engine, status = run_tree(make_engine, everything)
    assert status is Status.SUCCESS
    assert engine.trace.of("status")[-1]["t"] == 0.5
    selected = {
        "parallel": [{"wait": {"duration": 0.2}, "name": "short"}, "drive"],
        "policy": "success_on_selected",
        "selected": ["short"],
    }
    _, status = run_tree(make_engine, selected)
    assert status is Status.SUCCESS


def test_decorators(make_engine) -> None:
    cases: list[tuple[dict[str, Any], Status, int]] = [
        ({"inverter": "fail"}, Status.SUCCESS, 1),
        ({"force_success": "fail"}, Status.SUCCESS, 1),
        ({"force_failure": {"wait": {"duration": 0}}}, Status.FAILURE, 1),
        ({"retry": 3, "child": "fail"}, Status.FAILURE, 3),
        ({"repeat": 4, "child": {"wait": {"duration": 0}}}, Status.SUCCESS, 4),
        ({"timeout": 0.5, "child": "drive"}, Status.FAILURE, 1),
        ({"if": "go", "child": "drive"}, Status.FAILURE, 0),
    ]
    for spec, expected, runs in cases:
        engine, status = run_tree(make_engine, spec, values={"go": False})
        assert status is expected, spec
        assert len(engine.trace.of("skill_start")) == runs, spec


def test_timeout_runs_on_the_mission_clock_and_cancels(make_engine) -> None:
    engine, status = run_tree(make_engine, {"timeout": 2.5, "child": "drive"}, ticks=100)
    assert status is Status.FAILURE
    assert engine.clock.now() == pytest.approx(2.6)  # failed on the tick at t=2.5
    cancel = engine.trace.of("skill_cancel")[0]
    assert cancel["t"] == 2.5 and "timeout" in cancel["reason"]
    assert engine.trace.of("status")[-1]["reason"] == "timed out after 2.5 s"


def test_one_shot_runs_its_child_once(make_engine) -> None:
    spec = {"repeat": 3, "child": {"one_shot": {"log": {"message": "once"}}}}
    engine, status = run_tree(make_engine, spec)
    assert status is Status.SUCCESS
    assert len(engine.trace.of("log")) == 1


def test_subtree_with_remapping(make_engine) -> None:
    trees = {
        "double": {
            "sequence": [
                {"think": {"x": "{value}"}, "outputs": {"y": "result"}},
                {"check": {"condition": "result > value"}},
                {"set": {"key": "flag", "value": True}},
            ]
        }
    }
    spec = {
        "sequence": [
            {"subtree": "double", "remap": {"value": "a", "result": "b", "flag": "a_done"}, "name": "first"},
            {"subtree": "double", "remap": {"value": "b", "result": "c", "flag": "b_done"}, "name": "second"},
        ]
    }
    engine, status = run_tree(make_engine, spec, trees=trees, values={"a": 5})
    assert status is Status.SUCCESS
    assert {k: engine.blackboard.get(k) for k in ("a", "b", "c", "a_done", "b_done")} == {
        "a": 5,
        "b": 10,
        "c": 20,
        "a_done": True,
        "b_done": True,
    }
    assert not engine.blackboard.exists("result")
    assert engine.trace.of("skill_start")[0]["node"] == "root/first/think"


def test_spec_errors_are_collected_with_their_paths(make_engine) -> None:
    engine = make_engine()
    spec = {
        "sequence": [
            {"wiat": {"duration": 1}},
            {"wait": {"duraton": 1}},
            {"wait": {"duration": "long"}},
            {"timeout": -1, "child": "drive"},
            {"retry": 2},
            {"subtree": "missing"},
            {"while": "battery <", "child": "drive"},
            {"parallel": ["drive"], "policy": "success_on_any"},
            {"sequence": [], "memroy": False},
        ]
    }
    with pytest.raises(SpecError) as info:
        engine.builder().tree(spec)
    problems = {"/".join(map(str, p.path)): (p.message, p.hint) for p in info.value.problems}
    assert problems["sequence/0/wiat"] == ("unknown node or skill 'wiat'", "did you mean 'wait'?")
    assert problems["sequence/1/wait/duraton"] == ("skill 'wait' has no input 'duraton'", "did you mean 'duration'?")
    assert problems["sequence/1/wait"][0] == "skill 'wait' needs input 'duration'"
    assert problems["sequence/2/wait/duration"][0].startswith("input 'duration' of 'wait': expected float, got str")
    assert problems["sequence/3/timeout"][0] == "timeout: input should be greater than 0"
    assert problems["sequence/4"][0] == "'retry' needs a `child` node"
    assert problems["sequence/5/subtree"] == ("unknown tree 'missing'", "")
    assert problems["sequence/6/while"][0].startswith("syntax error")
    assert problems["sequence/7/policy"] == (
        "unknown parallel policy 'success_on_any'",
        "did you mean 'success_on_one'?",
    )
    assert problems["sequence/8/memroy"] == ("unknown option 'memroy' for 'sequence'", "did you mean 'memory'?")
    assert problems["sequence/8/sequence"][0] == "'sequence' needs a non-empty list of children"


def test_subtree_cycles_are_refused(make_engine) -> None:
    engine = make_engine()
    trees = {"a": {"subtree": "b"}, "b": {"sequence": [{"subtree": "a"}]}}
    with pytest.raises(SpecError, match="subtree cycle: a -> b -> a"):
        engine.builder(trees=trees).named_tree("a")


# -- preemption ordering ------------------------------------------------------------------


def test_reactive_guard_turning_false_cancels_before_the_fallback_starts(make_engine) -> None:
    spec = {
        "reactive_selector": [
            {"reactive_sequence": [{"condition": "battery_pct > 20"}, {"drive": {"speed": 0.5}}], "name": "work"},
            {"drive": {"speed": -0.2}, "name": "dock"},
        ]
    }
    engine = make_engine()
    engine.blackboard.set("battery_pct", 80)
    engine.set_root(engine.builder().tree(spec))
    engine.run(max_ticks=5)
    engine.blackboard.set("battery_pct", 10)
    engine.run(max_ticks=3)
    events = engine.trace.events
    cancelled = index_of(events, ev="skill_cancel", node="root/work/drive")
    motors_off = index_of(events, ev="log", node="root/work/drive", message="motors stopped")
    dock_start = index_of(events, ev="skill_start", node="root/dock")
    assert motors_off < cancelled < dock_start
    assert events[cancelled]["reason"] == "halted"
    failed = [e for e in engine.trace.of("status") if e["node"] == "root/work/condition" and e["new"] == "FAILURE"]
    assert failed[0]["reason"] == "'battery_pct > 20' is false (battery_pct=10)"


def test_while_guard_halts_the_child_with_the_condition_as_reason(make_engine) -> None:
    spec = {"selector": [{"while": "not estop", "child": "drive"}, {"log": {"message": "stopped"}}]}
    engine = make_engine()
    engine.blackboard.set("estop", False)
    engine.set_root(engine.builder().tree(spec))
    engine.run(max_ticks=3)
    engine.blackboard.set("estop", True)
    engine.run(max_ticks=1)
    events = engine.trace.events
    cancel = index_of(events, ev="skill_cancel", node="root/while/drive")
    assert events[cancel]["reason"] == "guard 'not estop' is false"
    assert (
        index_of(events, ev="log", message="motors stopped")
        < cancel
        < index_of(events, ev="skill_start", node="root/log")
    )


def test_higher_priority_action_starts_only_after_the_running_one_is_cancelled(make_engine) -> None:
    # py_trees alone would start `avoid` and only then halt `cruise`: two actions on the motors at once
    spec = {
        "reactive_selector": [
            {
                "reactive_sequence": [{"condition": "obstacle"}, {"drive": {"speed": -1.0}, "name": "avoid"}],
                "name": "safety",
            },
            {"drive": {"speed": 1.0}, "name": "cruise"},
        ]
    }
    engine = make_engine()
    engine.blackboard.set("obstacle", False)
    engine.set_root(engine.builder().tree(spec))
    engine.run(max_ticks=3)
    engine.blackboard.set("obstacle", True)
    engine.run(max_ticks=2)
    events = engine.trace.events
    cruise_off = index_of(events, ev="log", node="root/cruise", message="motors stopped")
    cancel = index_of(events, ev="skill_cancel", node="root/cruise")
    avoid_start = index_of(events, ev="skill_start", node="root/safety/avoid")
    assert cruise_off < cancel < avoid_start
    assert events[cancel]["reason"] == "preempted by higher-priority 'root/safety/avoid'"
    # a condition that keeps failing never disturbs the running action
    engine.blackboard.set("obstacle", False)
    engine.run(max_ticks=5)
    starts = [e["node"] for e in engine.trace.of("skill_start")]
    assert starts.count("root/cruise") == 2


def test_halting_the_engine_cancels_everything_running(make_engine) -> None:
    engine, _ = run_tree(make_engine, {"parallel": ["drive", "drive"]}, ticks=3)
    engine.halt("operator stop")
    cancels = engine.trace.of("skill_cancel")
    assert [c["reason"] for c in cancels] == ["operator stop", "operator stop"]
    assert len([e for e in engine.trace.of("log") if e["message"] == "motors stopped"]) == 2
