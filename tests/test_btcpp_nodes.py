"""BehaviorTree.CPP v4's built-in nodes, tick by tick, against BT.CPP's own tick()/halt().

Each case scripts its children (``S``, ``F``, ``R``: one status per tick of that child, the last
repeated) and lists, per tick of the tree, the root's status and what happened to the children:
``A`` A was ticked, ``A!`` A was halted while running. The expectations are read off BT.CPP's
sources (src/controls/*.cpp, src/decorators/*.cpp, include/behaviortree_cpp/*) as of v4; a tree
built by its factory gives every node a wake-up signal, hence the RUNNING after a child that
completed synchronously in SequenceWithMemory, RetryUntilSuccessful and Repeat.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from py_trees.common import Status

from botstage.behaviors.builder import SpecError
from botstage.behaviors.kinds import NodeKinds
from tests.scripted_nodes import LOG, A, B, C, Scripted, leaf, run


@pytest.fixture
def engine(make_engine: Any) -> Iterator[Any]:
    kinds = NodeKinds.default("btcpp")  # BT.CPP's IDs are what an XML file's trees see
    kinds.register(Scripted)
    LOG.clear()
    yield make_engine(rate_hz=10, kinds=kinds)


CASES: list[tuple[str, dict[str, Any], list[tuple[str, str]], int | None]] = [
    # -- Sequence: keeps its child while RUNNING; resets on SUCCESS and on FAILURE
    (
        "sequence resumes the running child",
        {"Sequence": [leaf(A, "S"), leaf(B, "RRS"), leaf(C, "S")]},
        [("R", "A B"), ("R", "B"), ("S", "B C")],
        None,
    ),
    (
        "sequence restarts from the first child after a failure",
        {"Sequence": [leaf(A, "S"), leaf(B, "RFS"), leaf(C, "S")]},
        [("R", "A B"), ("F", "B"), ("S", "A B C")],
        None,
    ),
    (
        "a halt resets a sequence",
        {"Sequence": [leaf(A, "S"), leaf(B, "R")]},
        [("R", "A B"), ("halt", "B!"), ("R", "A B")],
        1,
    ),
    # -- SequenceWithMemory: a failure is retried from the failed child; one synchronous child per tick
    (
        "sequence with memory does not go back after a failure",
        {"SequenceWithMemory": [leaf(A, "S"), leaf(B, "RFS"), leaf(C, "S")]},
        [("R", "A"), ("R", "B"), ("F", "B"), ("R", "B"), ("S", "C")],
        None,
    ),
    (
        "a halt does not reset a sequence with memory",
        {"SequenceWithMemory": [leaf(A, "S"), leaf(B, "RS")]},
        [("R", "A"), ("R", "B"), ("halt", "B!"), ("S", "B")],
        2,
    ),
    # -- ReactiveSequence: from the first child every tick; a failure halts the running child
    (
        "reactive sequence halts the running child when an earlier one fails",
        {"ReactiveSequence": [leaf(A, "SSF"), leaf(B, "R")]},
        [("R", "A B"), ("R", "A B"), ("F", "A B!")],
        None,
    ),
    (
        "reactive sequence halts a later child when an earlier one runs",
        {"ReactiveSequence": [leaf(A, "SR"), leaf(B, "R")]},
        [("R", "A B"), ("R", "A B!")],
        None,
    ),
    # -- Fallback and ReactiveFallback, the mirror images
    (
        "fallback resumes the running child",
        {"Fallback": [leaf(A, "F"), leaf(B, "RRF"), leaf(C, "S")]},
        [("R", "A B"), ("R", "B"), ("S", "B C"), ("S", "A B C")],
        None,
    ),
    (
        "reactive fallback halts the running child when an earlier one succeeds",
        {"ReactiveFallback": [leaf(A, "FFS"), leaf(B, "R")]},
        [("R", "A B"), ("R", "A B"), ("S", "A B!")],
        None,
    ),
    # -- Parallel: completed children are not ticked again; checks after each child
    (
        "parallel succeeds at success_count, halting the rest",
        {"Parallel": [leaf(A, "RS"), leaf(B, "RRS"), leaf(C, "R")], "success_count": 2},
        [("R", "A B C"), ("R", "A B C"), ("S", "B C!")],
        None,
    ),
    (
        "parallel by default needs every success and fails at the first failure",
        {"Parallel": [leaf(A, "S"), leaf(B, "RF")]},
        [("R", "A B"), ("F", "B")],
        None,
    ),
    (
        "parallel with failure_count -1 fails only when every child failed",
        {"Parallel": [leaf(A, "F"), leaf(B, "RS")], "success_count": 1, "failure_count": -1},
        [("R", "A B"), ("S", "B")],
        None,
    ),
    (
        "parallel fails as soon as success has become impossible",
        {"Parallel": [leaf(A, "F"), leaf(B, "R")], "failure_count": 2},
        [("F", "A")],
        None,
    ),
    # -- ParallelAll: every child completes; then max_failures decides
    (
        "parallel all waits for every child, then fails at max_failures",
        {"ParallelAll": [leaf(A, "F"), leaf(B, "RS")]},
        [("R", "A B"), ("F", "B")],
        None,
    ),
    (
        "parallel all succeeds below max_failures",
        {"ParallelAll": [leaf(A, "F"), leaf(B, "RS")], "max_failures": 2},
        [("R", "A B"), ("S", "B")],
        None,
    ),
    # -- IfThenElse: the condition is not ticked again once a branch runs
    (
        "if-then-else runs the then branch without re-checking",
        {"IfThenElse": [leaf(A, "RS"), leaf(B, "RS"), leaf(C, "S")]},
        [("R", "A"), ("R", "A B"), ("S", "B")],
        None,
    ),
    (
        "if-then-else runs the else branch",
        {"IfThenElse": [leaf(A, "F"), leaf(B, "S"), leaf(C, "RF")]},
        [("R", "A C"), ("F", "C")],
        None,
    ),
    (
        "if-then without else fails when the condition fails",
        {"IfThenElse": [leaf(A, "F"), leaf(B, "S")]},
        [("F", "A")],
        None,
    ),
    # -- WhileDoElse: the condition every tick, halting the branch it no longer picks
    (
        "while-do-else switches branch, halting the other",
        {"WhileDoElse": [leaf(A, "SSF"), leaf(B, "R"), leaf(C, "R")]},
        [("R", "A B"), ("R", "A B"), ("R", "A B! C")],
        None,
    ),
    (
        "while-do without else fails, halting the do branch",
        {"WhileDoElse": [leaf(A, "SF"), leaf(B, "R")]},
        [("R", "A B"), ("F", "A B!")],
        None,
    ),
    # -- decorators that map the child's status
    ("inverter", {"Inverter": leaf(A, "RSF")}, [("R", "A"), ("F", "A"), ("S", "A")], None),
    ("force success", {"ForceSuccess": leaf(A, "RSF")}, [("R", "A"), ("S", "A"), ("S", "A")], None),
    ("force failure", {"ForceFailure": leaf(A, "RSF")}, [("R", "A"), ("F", "A"), ("F", "A")], None),
    (
        "keep running until failure",
        {"KeepRunningUntilFailure": leaf(A, "SSF")},
        [("R", "A"), ("R", "A"), ("F", "A")],
        None,
    ),
    # -- RetryUntilSuccessful and Repeat: in-tick re-tick after a RUNNING child, RUNNING after a synchronous one
    (
        "retry: one synchronous attempt per tick",
        {"RetryUntilSuccessful": leaf(A, "FFS"), "num_attempts": 3},
        [("R", "A"), ("R", "A"), ("S", "A")],
        None,
    ),
    (
        "retry: a child that ran and failed is started again in the same tick",
        {"RetryUntilSuccessful": leaf(A, "RFRS"), "num_attempts": 3},
        [("R", "A"), ("R", "A A"), ("S", "A")],
        None,
    ),
    (
        "retry fails after num_attempts",
        {"RetryUntilSuccessful": leaf(A, "F"), "num_attempts": 2},
        [("R", "A"), ("F", "A")],
        None,
    ),
    (
        "a halt resets retry's count of attempts",
        {"RetryUntilSuccessful": leaf(A, "FRF"), "num_attempts": 2},
        [("R", "A"), ("R", "A"), ("halt", "A!"), ("R", "A")],
        2,
    ),
    (
        "repeat: one synchronous cycle per tick",
        {"Repeat": leaf(A, "S"), "num_cycles": 3},
        [("R", "A"), ("R", "A"), ("S", "A")],
        None,
    ),
    (
        "repeat: a child that ran and succeeded is started again in the same tick",
        {"Repeat": leaf(A, "RSRS"), "num_cycles": 2},
        [("R", "A"), ("R", "A A"), ("S", "A")],
        None,
    ),
    ("repeat ends at the first failure", {"Repeat": leaf(A, "SF"), "num_cycles": 5}, [("R", "A"), ("F", "A")], None),
    # -- RunOnce
    (
        "run once repeats the result without ticking",
        {"RunOnce": leaf(A, "RF"), "then_skip": False},
        [("R", "A"), ("F", "A"), ("F", "")],
        None,
    ),
    (
        "run once then skips (SKIPPED, a success to py_trees)",
        {"RunOnce": leaf(A, "F")},
        [("F", "A"), ("S", ""), ("S", "")],
        None,
    ),
    # -- time, from the run's clock (10 Hz here: tick n is at (n - 1) / 10 s)
    (
        "timeout halts the running child and fails",
        {"Timeout": leaf(A, "R"), "msec": 250},
        [("R", "A"), ("R", "A"), ("R", "A"), ("F", "A!")],
        None,
    ),
    ("timeout 0 is no timeout", {"Timeout": leaf(A, "RRRS"), "msec": 0}, [("R", "A")] * 3 + [("S", "A")], None),
    (
        "delay waits, then ticks the child",
        {"Delay": leaf(A, "S"), "delay_msec": 200},
        [("R", ""), ("R", ""), ("S", "A"), ("R", "")],
        None,
    ),
    ("sleep", {"Sleep": {"msec": 200}}, [("R", ""), ("R", ""), ("S", "")], None),
    ("sleep 0 succeeds at once", {"Sleep": {"msec": 0}}, [("S", "")], None),
    ("always success", {"AlwaysSuccess": {}}, [("S", "")], None),
    ("always failure", {"AlwaysFailure": None}, [("F", "")], None),
]


@pytest.mark.parametrize(("spec", "expected", "halt_after"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_node_ticks_as_in_btcpp(engine: Any, spec: dict[str, Any], expected: list, halt_after: int | None) -> None:
    assert run(engine, spec, len([e for e in expected if e[0] != "halt"]), halt_after) == expected


def test_switch_picks_the_case_and_halts_the_one_that_ran(engine: Any) -> None:
    spec = {
        "Switch2": [leaf(A, "R"), leaf(B, "R"), leaf(C, "S")],
        "variable": "{mode}",
        "case_1": "1",
        "case_2": "two",
    }
    engine.set_root(engine.builder().tree(spec))
    engine.blackboard.set("mode", 1.0)  # a number equal to the case's number matches (CheckStringEquality)
    assert engine.tick() is Status.RUNNING and LOG == [A]
    LOG.clear()
    engine.blackboard.set("mode", "two")
    assert engine.tick() is Status.RUNNING and LOG == ["A!", B]
    LOG.clear()
    engine.blackboard.set("mode", "other")
    assert engine.tick() is Status.SUCCESS and LOG == ["B!", C]


def test_switch_without_the_variable_takes_the_default(engine: Any) -> None:
    spec = {"Switch2": [leaf(A, "S"), leaf(B, "S"), leaf(C, "F")], "variable": "{unset}", "case_1": "1"}
    engine.set_root(engine.builder().tree(spec))
    assert engine.tick() is Status.FAILURE and LOG == [C]


def test_set_blackboard_writes_literals_and_copies_keys(engine: Any) -> None:
    spec = {
        "Sequence": [
            {"SetBlackboard": {"value": "42", "output_key": "answer"}},
            {"SetBlackboard": {"value": "{answer}", "output_key": "{copy}"}},
        ]
    }
    engine.set_root(engine.builder().tree(spec))
    assert engine.tick() is Status.SUCCESS
    assert engine.blackboard.get("answer") == "42" and engine.blackboard.get("copy") == "42"


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"IfThenElse": [leaf(A, "S")]}, "IfThenElse takes 2 or 3 children, got 1"),
        ({"Parallel": [leaf(A, "S")], "success_count": 2}, "success_count 2 is more than the 1 children"),
        ({"Switch2": [leaf(A, "S"), leaf(B, "S")], "variable": "{v}"}, "Switch2 takes 3 children"),
        ({"RetryUntilSuccessful": leaf(A, "S")}, "num_attempts of 'RetryUntilSuccessful': field required"),
        ({"Sleep": {"msec": 5, "sec": 1}}, "Sleep has no port 'sec'"),
        ({"Timeout": leaf(A, "S"), "msec": -1}, "msec of 'Timeout'"),
    ],
)
def test_bad_ports_are_reported_where_written(engine: Any, spec: dict[str, Any], message: str) -> None:
    with pytest.raises(SpecError) as caught:
        engine.builder().tree(spec)
    assert message in str(caught.value)


# -- scripts, Precondition, UnsetBlackboard and the pre/post-condition attributes ------------------
# (tree_node.cpp's executeTick/checkPreConditions/checkPostConditions, precondition_node.h,
# script_node.h, script_condition.h, unset_blackboard_node.h; SKIPPED is a SUCCESS with `skipped`)


def pre_post(child: dict[str, Any], **scripts: str) -> dict[str, Any]:
    return {"PrePostConditions": child, **{"_" + name: code for name, code in scripts.items()}}


SCRIPTED: list[tuple[str, dict[str, Any], dict[str, Any], list[tuple[str, str]], dict[str, Any]]] = [
    # (id, spec, blackboard before, per tick (status, log), blackboard after)
    (
        "script assigns, computes and joins strings",
        {"Script": {"code": "n := 2; n += 3; msg := 'n=' .. n; big := n > 4 ? true : false"}},
        {},
        [("S", "")],
        {"n": 5, "msg": "n=5", "big": 1},
    ),
    (
        "script fails (with its reason) on `=` to a missing key",
        {"Script": {"code": "missing = 1"}},
        {},
        [("F", "")],
        {},
    ),
    ("script condition true", {"ScriptCondition": {"code": "a > 1 && a < 3"}}, {"a": 2}, [("S", "")], {"a": 2}),
    ("script condition false", {"ScriptCondition": {"code": "a == 'x'"}}, {"a": "y"}, [("F", "")], {"a": "y"}),
    ("unset blackboard", {"UnsetBlackboard": {"key": "gone"}}, {"gone": 1, "kept": 2}, [("S", "")], {"kept": 2}),
    (
        "precondition false returns FAILURE by default without ticking the child",
        {"Sequence": [{"Script": {"code": "go = false"}, "name": "X"}, {"Precondition": leaf(A, "RRS"), "if_": "go"}]},
        {"go": True},
        [("F", ""), ("F", "")],
        {"go": False},
    ),
    (
        "precondition: a running child is not re-checked",
        {"Precondition": leaf(A, "RRS"), "if_": "go"},
        {"go": True},
        [("R", "A"), ("R", "A"), ("S", "A")],
        {"go": True},
    ),
    (
        "precondition false returns else (SKIPPED: a success)",
        {"Sequence": [{"Precondition": leaf(A, "F"), "if_": "go", "else": "SKIPPED"}, leaf(B, "S")]},
        {"go": False},
        [("S", "B")],
        {},
    ),
    (
        "_skipIf skips the node; a fallback moves past a skipped child as BT.CPP's does",
        {"Fallback": [pre_post(leaf(A, "S"), skipIf="n > 1"), leaf(B, "F")]},
        {"n": 2},
        [("F", "B")],
        {},
    ),
    (
        "_failureIf and _successIf decide without ticking; _onFailure/_onSuccess and _post follow",
        {
            "Sequence": [
                pre_post(leaf(A, "S"), successIf="n == 1", onSuccess="s := 1", post="p := 'a'"),
                pre_post(leaf(B, "S"), failureIf="n == 1", onFailure="f := 1", post="p := p .. 'b'"),
            ]
        },
        {"n": 1},
        [("F", "")],
        {"s": 1, "f": 1, "p": "ab"},
    ),
    (
        "pre-conditions are checked only when the node is idle",
        pre_post(leaf(A, "RRS"), failureIf="stop"),
        {"stop": False},
        [("R", "A"), ("R", "A"), ("S", "A")],
        {},
    ),
    (
        "_while false while running halts the node (SKIPPED) and runs _onHalted",
        pre_post(leaf(A, "R"), **{"while": "n < 2", "onHalted": "halted := true", "post": "n += 1"}),
        {"n": 0},
        [("R", "A"), ("R", "A"), ("S", "A!")],
        {"n": 3.0, "halted": 1},
    ),
    (
        "_while false before the start skips the node",
        {"Sequence": [pre_post(leaf(A, "F"), **{"while": "false"}), leaf(B, "S")]},
        {},
        [("S", "B")],
        {},
    ),
    (
        "keyed num_attempts, msec and delay_msec are read when the node starts",
        {"Sequence": [{"RetryUntilSuccessful": leaf(A, "F"), "num_attempts": "{tries}"}]},
        {"tries": "2"},
        [("R", "A"), ("F", "A")],
        {},
    ),
    (
        "keyed Sleep",
        {"Sleep": {"msec": "{ms}"}},
        {"ms": 200},
        [("R", ""), ("R", ""), ("S", "")],
        {},
    ),
    (
        "keyed Timeout",
        {"Timeout": leaf(A, "R"), "msec": "{ms}"},
        {"ms": 150},
        [("R", "A"), ("R", "A"), ("F", "A!")],
        {},
    ),
    (
        "a keyed count that is not a number fails the node with its reason",
        {"Repeat": leaf(A, "S"), "num_cycles": "{n}"},
        {"n": "many"},
        [("F", "")],
        {},
    ),
]


@pytest.mark.parametrize(
    ("spec", "before", "expected", "after"), [c[1:] for c in SCRIPTED], ids=[c[0] for c in SCRIPTED]
)
def test_scripted_node_ticks_as_in_btcpp(
    engine: Any, spec: dict[str, Any], before: dict[str, Any], expected: list, after: dict[str, Any]
) -> None:
    engine.blackboard.update(before)
    assert run(engine, spec, len(expected)) == expected
    snapshot = engine.blackboard.snapshot()
    assert {k: snapshot.get(k) for k in after} == after
    if "UnsetBlackboard" in spec:
        assert "gone" not in snapshot


def test_halting_a_running_node_runs_on_halted(engine: Any) -> None:
    spec = pre_post(leaf(A, "R"), onHalted="halts := 1", onSuccess="never := 1")
    assert run(engine, spec, 2, halt_after=1) == [("R", "A"), ("halt", "A!"), ("R", "A")]
    assert engine.blackboard.get("halts") == 1 and not engine.blackboard.exists("never")


def test_a_failed_script_says_why(engine: Any) -> None:
    engine.set_root(engine.builder().tree({"Script": {"code": "x = 1"}}))
    assert engine.tick() is Status.FAILURE
    assert "doesn't exist yet: use [:=]" in engine.root.feedback_message
