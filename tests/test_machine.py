"""Hierarchical state machines: outcomes as transitions, nesting, guards, timeouts, preemptions."""

from __future__ import annotations

from typing import Any

import pytest
from py_trees.common import Status

from botstage.behaviors.builder import SpecError
from tests.conftest import index_of


def build(
    make_engine,
    machine: dict[str, Any],
    trees: dict | None = None,
    values: dict | None = None,
    machines: dict | None = None,
):
    engine = make_engine()
    for key, value in (values or {}).items():
        engine.blackboard.set(key, value)
    root = engine.builder(trees=trees, machines=machines).machine(machine, name="m")
    engine.set_root(root)
    return engine, root


def moves(engine) -> list[tuple[str, str, str]]:
    return [(e["source"], e["dest"], e["trigger"]) for e in engine.trace.of("transition")]


def test_outcomes_name_transitions_and_nested_outcomes_resolve_outwards(make_engine) -> None:
    machine = {
        "outcomes": ["done", "aborted"],
        "states": {
            "prepare": {"skill": "wait", "inputs": {"duration": 0.2}, "transitions": {"success": "work"}},
            "work": {
                "machine": {
                    "outcomes": ["finished", "broken"],
                    "states": {
                        "pick": {"skill": "liar", "transitions": {"failure": "broken"}},
                    },
                },
                "transitions": {"finished": "done", "broken": "aborted"},
            },
        },
    }
    engine, root = build(make_engine, machine)
    status = engine.run(max_ticks=20)
    assert status is Status.FAILURE  # `done` is the machine's success outcome; it ended `aborted`
    assert root.outcome.name == "aborted"
    assert "undeclared outcome 'banana'" in root.outcome.reason
    assert moves(engine) == [
        ("", "prepare", "start"),
        ("prepare", "work/pick", "prepare:success"),
        ("work/pick", "aborted", "work/pick:failure > work:broken"),
    ]


def test_guards_choose_the_transition(make_engine) -> None:
    machine = {
        "states": {
            "decide": {
                "skill": "wait",
                "inputs": {"duration": 0},
                "transitions": {"success": [{"to": "charge", "if": "battery_pct < 20"}, {"to": "work"}]},
            },
            "charge": {
                "skill": "set",
                "inputs": {"key": "went", "value": "charge"},
                "transitions": {"success": "success"},
            },
            "work": {"skill": "set", "inputs": {"key": "went", "value": "work"}, "transitions": {"success": "success"}},
        }
    }
    for battery, expected in ((10, "charge"), (90, "work")):
        engine, _root = build(make_engine, machine, values={"battery_pct": battery})
        assert engine.run(max_ticks=5) is Status.SUCCESS
        assert engine.blackboard.get("went") == expected


def test_no_guard_holding_fails_the_machine_with_a_reason(make_engine) -> None:
    machine = {
        "states": {
            "a": {
                "skill": "wait",
                "inputs": {"duration": 0},
                "transitions": {"success": [{"to": "success", "if": "ready"}]},
            }
        }
    }
    engine, root = build(make_engine, machine, values={"ready": False})
    assert engine.run(max_ticks=5) is Status.FAILURE
    assert root.outcome.reason == "state 'a' ended with 'success' but no guard of its transitions holds"


def test_unhandled_outcome_fails_with_reason(make_engine) -> None:
    machine = {"states": {"a": {"skill": "fail", "transitions": {"success": "success"}}}}
    engine, root = build(make_engine, machine)
    assert engine.run(max_ticks=5) is Status.FAILURE
    assert root.outcome.reason == (
        "state 'a' ended with outcome 'failure' but has no transition for it (handled: success); told to fail"
    )


def test_state_timeout_on_the_mission_clock_cancels_and_transitions(make_engine) -> None:
    machine = {
        "states": {
            "move": {"skill": "drive", "timeout": 60, "transitions": {"timeout": "rest"}},
            "rest": {"skill": "wait", "inputs": {"duration": 1}, "transitions": {"success": "success"}},
        }
    }
    engine, root = build(make_engine, machine)
    assert engine.run(max_ticks=1000) is Status.SUCCESS
    events = engine.trace.events
    cancel = index_of(events, ev="skill_cancel", node="m/move")
    assert events[cancel]["t"] == 60.0
    assert events[cancel]["reason"] == "state 'move' timed out after 60 s"
    assert (
        index_of(events, ev="log", message="motors stopped")
        < cancel
        < index_of(events, ev="skill_start", node="m/rest")
    )
    assert root.outcome.name == "success"


def test_preemption_cancels_the_running_skill_before_anything_else_starts(make_engine) -> None:
    machine = {
        "outcomes": ["done", "stopped"],
        "preemptions": [{"when": "estop", "to": "halted"}],
        "states": {
            "patrol": {
                "machine": {
                    "outcomes": ["finished"],
                    "states": {"cruise": {"tree": {"sequence": ["drive"]}, "transitions": {"success": "finished"}}},
                },
                "transitions": {"finished": "done"},
            },
            "halted": {"skill": "wait", "inputs": {"duration": 0.5}, "transitions": {"success": "stopped"}},
        },
    }
    engine, root = build(make_engine, machine, values={"estop": False})
    engine.run(max_ticks=10)
    engine.blackboard.set("estop", True, writer="operator")
    engine.run(max_ticks=20)
    events = engine.trace.events
    motors_off = index_of(events, ev="log", message="motors stopped")
    cancel = index_of(events, ev="skill_cancel", node="m/patrol/cruise/tree/drive")
    move = index_of(events, ev="transition", dest="halted")
    next_start = index_of(events, ev="skill_start", node="m/halted")
    assert motors_off < cancel < move < next_start
    assert events[cancel]["reason"] == "preempted: 'estop' holds"
    assert events[move]["source"] == "patrol/cruise"
    # the preemption does not fire again while the machine is already in its target
    assert root.outcome.name == "stopped"
    assert [m[1] for m in moves(engine)] == ["patrol/cruise", "halted", "stopped"]


def test_entry_and_exit_actions(make_engine) -> None:
    machine = {
        "states": {
            "a": {
                "skill": "wait",
                "inputs": {"duration": 0.1},
                "on_enter": [{"set": {"mode": "busy", "count": 1}}, {"log": "entering a"}],
                "on_exit": {"set": {"mode": "idle"}},
                "transitions": {"success": "success"},
            }
        }
    }
    engine, _ = build(make_engine, machine)
    engine.run(max_ticks=5)
    writes = [(e["key"], e["new"], e["writer"]) for e in engine.trace.of("bb_write")]
    assert writes == [("mode", "busy", "m"), ("count", 1, "m"), ("mode", "idle", "m")]
    assert engine.trace.of("log")[0]["message"] == "entering a"


def test_machine_in_tree_in_machine_in_tree(make_engine) -> None:
    machines = {
        "inner": {
            "states": {
                "work": {"tree": "leaf", "transitions": {"success": "success", "failure": "failure"}},
            }
        }
    }
    trees = {
        "leaf": {"sequence": [{"think": {"x": 4}, "outputs": {"y": "deep"}}]},
        "middle": {"sequence": [{"log": {"message": "middle"}}, {"machine": "inner"}]},
    }
    machine = {"states": {"outer": {"tree": "middle", "transitions": {"success": "success"}}}}
    engine = make_engine()
    engine.set_root(
        engine.builder(trees=trees, machines=machines).tree(
            {"sequence": [{"machine": machine}, {"check": {"condition": "deep == 8"}}]}
        )
    )
    assert engine.run(max_ticks=10) is Status.SUCCESS
    nodes = [e["node"] for e in engine.trace.of("skill_start")]
    assert nodes == [
        "root/machine/outer/middle/log",
        "root/machine/outer/middle/inner/work/leaf/think",
        "root/check",
    ]


def test_halting_a_machine_cancels_its_state(make_engine) -> None:
    machine = {"states": {"a": {"skill": "drive", "transitions": {"success": "success"}}}}
    spec = {"parallel": [{"machine": machine}, {"wait": {"duration": 0.3}}], "policy": "success_on_one"}
    engine = make_engine()
    engine.set_root(engine.builder().tree(spec))
    assert engine.run(max_ticks=10) is Status.SUCCESS
    assert engine.trace.of("skill_cancel")[0]["node"] == "root/machine/a"
    assert moves(engine)[-1] == ("a", "", "halt")
    # and it starts afresh when ticked again
    engine.run(max_ticks=1)
    assert moves(engine)[-1] == ("", "a", "start")


def test_machine_spec_errors(make_engine) -> None:
    engine = make_engine()
    machine = {
        "initial": "strat",
        "outcomes": ["done"],
        "states": {
            "start": {
                "skill": "wait",
                "inputs": {"duration": 1},
                "transitions": {"success": "ned", "no_crowd": "done"},
            },
            "nested": {
                "machine": {
                    "outcomes": ["ok", "meh"],
                    "states": {"x": {"skill": "fail", "transitions": {"failure": "meh"}}},
                },
                "transitions": {"ok": "done"},
            },
            "both": {"skill": "wait", "tree": "t"},
            "done": {"skill": "fail"},
        },
        "preemptions": [{"when": "estop", "to": "nowhere"}],
    }
    with pytest.raises(SpecError) as info:
        engine.builder().machine(machine)
    problems = {"/".join(map(str, p.path)): (p.message, p.hint) for p in info.value.problems}
    assert problems["initial"] == ("initial state 'strat' is not a state", "did you mean 'start'?")
    assert problems["states/start/transitions/success"] == (
        "transition to unknown state 'ned'",
        "did you mean 'nested'?",
    )
    assert problems["states/start/transitions/no_crowd"][0] == "state 'start' never ends with outcome 'no_crowd'"
    assert problems["states/both"][0] == "state 'both' needs exactly one of skill, tree or machine"
    assert problems["states/done"][0] == "state 'done' has the name of one of the machine's outcomes"
    assert problems["preemptions/0/to"][0] == "unknown state or outcome 'nowhere'"
    assert problems["states/nested"][0] == "state 'nested' can end with outcome 'meh' but has no transition for it"
