"""Regressions found in review: each test failed before its fix."""

from __future__ import annotations

from typing import Any

import pytest
from py_trees.common import Status

from botstage.behaviors.builder import SpecError
from botstage.skills.base import Outcome, Skill, SkillContext, SkillRun
from tests.conftest import index_of


class Once(Skill):
    name = "once"

    def run(self, ctx: SkillContext) -> SkillRun:
        yield
        return Outcome.success()


class Blocked(Skill):
    name = "blocked"
    outcomes = ("blocked",)

    def run(self, ctx: SkillContext) -> Outcome:
        return Outcome("blocked", "door closed")


class Garbled(Skill):
    name = "garbled"

    def run(self, ctx: SkillContext) -> SkillRun:
        yield
        return Outcome("success", "", [("y", 1)])  # type: ignore[arg-type]


class Chatty(Skill):
    name = "chatty"

    def run(self, ctx: SkillContext) -> SkillRun:
        def work() -> int:
            ctx.logger.info("from the worker")  # another thread: must not reach the trace
            return 1

        yield ctx.submit(work)
        return Outcome.success()


@pytest.fixture
def engine(make_engine, registry):
    for cls in (Once, Blocked, Garbled, Chatty):
        registry.register(cls)
    return make_engine()


def motors_running(engine) -> int:
    logs = [e["message"] for e in engine.trace.of("log")]
    return logs.count("motors at 0.5") - logs.count("motors stopped")


def test_a_machine_that_fails_stops_what_runs_in_its_state(engine) -> None:
    machine = {"states": {"a": {"skill": "drive", "timeout": 0.3, "transitions": {"success": "success"}}}}
    root = engine.builder().machine(machine, name="m")
    engine.set_root(root)
    assert engine.run(max_ticks=10) is Status.FAILURE
    assert root.outcome.reason.startswith("state 'a' ended with outcome 'timeout' but has no transition")
    assert motors_running(engine) == 0
    assert [e["dest"] for e in engine.trace.of("transition")] == ["a", ""]


def test_a_retried_machine_restarts_its_state_cleanly(engine) -> None:
    machine = {"states": {"a": {"skill": "drive", "timeout": 0.3, "transitions": {"success": "success"}}}}
    engine.set_root(engine.builder().tree({"retry": 2, "child": {"machine": machine, "name": "m"}}))
    assert engine.run(max_ticks=20) is Status.FAILURE
    assert len(engine.trace.of("skill_start")) == 2
    assert motors_running(engine) == 0


def test_a_preemption_that_cannot_be_evaluated_stops_the_state(engine) -> None:
    machine = {
        "preemptions": [{"when": "stop > 1", "to": "failure"}],
        "states": {"a": {"skill": "drive", "transitions": {"success": "success"}}},
    }
    engine.blackboard.set("stop", 0)
    root = engine.builder().machine(machine, name="m")
    engine.set_root(root)
    engine.run(max_ticks=2)
    engine.blackboard.set("stop", "x")
    assert engine.run(max_ticks=3) is Status.FAILURE
    assert "cannot be evaluated" in root.outcome.reason
    assert motors_running(engine) == 0


def test_skills_inside_a_machine_preempt_lower_priority_branches_first(engine) -> None:
    tree = {
        "reactive_selector": [
            {
                "sequence": [
                    {"condition": "go"},
                    {
                        "machine": {
                            "states": {
                                "hi": {"skill": "drive", "transitions": {"success": "success", "failure": "failure"}}
                            }
                        },
                        "name": "m",
                    },
                ],
                "name": "high",
            },
            {"drive": {}, "name": "low"},
        ]
    }
    engine.blackboard.set("go", False)
    engine.set_root(engine.builder().tree(tree))
    engine.run(max_ticks=2)
    engine.blackboard.set("go", True)
    engine.run(max_ticks=1)
    events = engine.trace.events
    assert index_of(events, ev="skill_cancel", node="root/low") < index_of(
        events, ev="skill_start", node="root/high/m/hi"
    )


def test_an_action_failing_at_once_does_not_livelock_the_branch_below(engine) -> None:
    engine.set_root(engine.builder().tree({"reactive_selector": [{"fail": None}, {"wait": {"duration": 0.5}}]}))
    assert engine.run(max_ticks=30) is Status.SUCCESS
    assert len([e for e in engine.trace.of("skill_start") if e["skill"] == "wait"]) <= 2


@pytest.mark.parametrize("condition", ["people[0] == 'bob'", "pose['z'] > 0"])
def test_lookup_errors_inside_conditions_fail_the_guard_not_the_engine(engine, condition) -> None:
    engine.blackboard.update({"people": [], "pose": {"x": 1}})
    engine.set_root(
        engine.builder().tree(
            {"selector": [{"while": condition, "child": "drive"}, {"log": {"message": "fallback ran"}}]}
        )
    )
    assert engine.run(max_ticks=3) is Status.SUCCESS
    assert engine.error is None
    assert engine.trace.of("log")[-1]["message"] == "fallback ran"


def test_a_malformed_outcome_from_a_generator_is_a_failure(engine) -> None:
    engine.set_root(engine.builder().tree({"selector": ["garbled", {"log": {"message": "next"}}]}))
    assert engine.run(max_ticks=3) is Status.SUCCESS
    assert engine.error is None
    outcome = engine.trace.of("skill_outcome")[0]
    assert outcome["reason"] == "run() returned outputs as list, not a mapping"


def test_a_tree_state_reports_success_or_failure_whatever_its_root(engine) -> None:
    machine = {
        "states": {"a": {"tree": {"blocked": None}, "transitions": {"success": "success", "failure": "failure"}}}
    }
    root = engine.builder().machine(machine, name="m")
    engine.set_root(root)
    engine.run(max_ticks=3)
    assert root.outcome.name == "failure"
    assert root.outcome.reason == "door closed"


@pytest.mark.parametrize(
    ("trees", "machines", "message"),
    [
        (
            {"T": {"machine": {"states": {"a": {"tree": "T", "transitions": {"success": "success"}}}}}},
            {},
            "tree cycle: T -> T",
        ),
        (
            {"T": {"machine": "M"}},
            {"M": {"states": {"a": {"machine": "M", "transitions": {"success": "success"}}}}},
            "machine cycle: T -> machine M -> machine M",
        ),
    ],
)
def test_cycles_through_states_are_spec_errors(engine, trees, machines, message) -> None:
    with pytest.raises(SpecError, match=message):
        engine.builder(trees=trees, machines=machines).named_tree("T")


@pytest.mark.parametrize(
    ("machine", "message"),
    [
        ({"initial": ["a"], "states": {"a": {"skill": "once"}}}, "initial state ['a'] is not a state"),
        (
            {"preemptions": [{"when": "x", "to": ["a"]}], "states": {"a": {"skill": "once"}}},
            "unknown state or outcome ['a']",
        ),
        (
            {"states": {"a": {"skill": "once", "transitions": {"success": [["b"]]}}}},
            "transition to unknown state ['b']",
        ),
        ({"states": {"a": {"tree": {"log": {"message": "x"}}, "inputs": {"x": 1}}}}, "only a skill state takes"),
    ],
)
def test_malformed_machines_are_spec_errors(engine, machine, message) -> None:
    with pytest.raises(SpecError, match=message.replace("[", r"\[").replace("]", r"\]")):
        engine.builder().machine(machine)


def test_nested_outcome_guards_keep_their_meaning(engine) -> None:
    """Inner `success` picks `finished` (a holds); the outer guard b blocks: blocked, not `retry`."""
    machine = {
        "outcomes": ["done", "failure"],
        "states": {
            "work": {
                "machine": {
                    "outcomes": ["finished", "failure"],
                    "states": {
                        "p": {
                            "skill": "once",
                            "transitions": {"success": [{"to": "finished", "if": "a"}, {"to": "retry"}]},
                        },
                        "retry": {
                            "skill": "log",
                            "inputs": {"message": "wrong"},
                            "transitions": {"success": "failure"},
                        },
                    },
                },
                "transitions": {"finished": {"to": "done", "if": "b"}, "failure": "failure"},
            }
        },
    }
    engine.blackboard.update({"a": True, "b": False})
    root = engine.builder().machine(machine, name="m")
    engine.set_root(root)
    assert engine.run(max_ticks=5) is Status.FAILURE
    assert "no guard" in root.outcome.reason
    assert not engine.trace.of("log")
    engine.blackboard.set("b", True)
    assert engine.run(max_ticks=5) is Status.SUCCESS and root.outcome.name == "done"


def test_remapping_renames_namespaces_alike_in_conditions_and_guards(engine) -> None:
    trees = {
        "inner": {
            "sequence": [
                {"condition": "robot.mode == 'go'"},
                {"while": "robot.mode == 'go'", "child": {"log": {"message": "guard passed"}}},
            ]
        },
        "main": {"subtree": "inner", "remap": {"robot": "r2"}},
    }
    engine.blackboard.set("r2/mode", "go")
    root = engine.builder(trees=trees).named_tree("main")
    engine.set_root(root)
    assert engine.run(max_ticks=2) is Status.SUCCESS
    assert root.children[0].access.reads == {"r2/mode"}
    assert root.children[1].access.reads == {"r2/mode"}


def test_check_reasons_are_the_same_in_every_run(engine) -> None:
    engine.blackboard.set("ids", {"dave", "alice", "carol", "bob"})
    engine.set_root(engine.builder().tree({"condition": "'zed' in ids"}))
    engine.run(max_ticks=1)
    assert engine.trace.of("skill_outcome")[0]["reason"] == (
        "\"'zed' in ids\" is false (ids={'alice', 'bob', 'carol', 'dave'})"
    )


def test_logs_from_worker_threads_stay_out_of_the_trace(engine) -> None:
    engine.set_root(engine.builder().tree({"parallel": ["chatty", {"chatty": None, "name": "c2"}]}))
    assert engine.run(max_ticks=5) is Status.SUCCESS
    assert engine.trace.of("log") == []


def test_a_halt_is_a_status_change_and_a_restart_shows_again(engine) -> None:
    engine.blackboard.set("go", True)
    engine.set_root(engine.builder().tree({"reactive_sequence": [{"condition": "go"}, "drive"]}))
    engine.run(max_ticks=2)
    engine.blackboard.set("go", False)
    engine.run(max_ticks=1)
    engine.blackboard.set("go", True)
    engine.run(max_ticks=1)
    drive = [(e["old"], e["new"]) for e in engine.trace.of("status") if e["node"] == "root/drive"]
    assert drive == [("INVALID", "RUNNING"), ("RUNNING", "INVALID"), ("INVALID", "RUNNING")]


def test_a_restarted_skill_does_not_keep_its_old_reason(engine) -> None:
    engine.blackboard.set("n", 0)
    spec: dict[str, Any] = {"repeat": 2, "child": {"force_success": {"check": {"condition": "n > 0"}}}}
    engine.set_root(engine.builder().tree(spec))
    engine.run(max_ticks=1)
    engine.blackboard.set("n", 1)
    engine.run(max_ticks=3)
    reasons = [e["reason"] for e in engine.trace.of("status") if e["node"] == "root/force_success/check"]
    assert reasons[-1] == ""
