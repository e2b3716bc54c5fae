"""The acceptance lines of the engine issue, one test each (preemption ordering is in
test_tree.py and test_machine.py; the plugin line in test_plugins.py)."""

from __future__ import annotations

import time

import pytest
from py_trees.common import Status

from botstage.behaviors.engine import Engine
from botstage.robots.clock import SimClock
from botstage.skills.registry import Registry
from tests.bench.bench_tick import timeouts_spec
from tests.conftest import TEST_SKILLS

TREES = {
    # generic skills only: the heartbeat the machine waits for
    "heartbeat": {
        "repeat": "forever",
        "child": {
            "sequence": [
                {"wait": {"duration": 0.25}},
                {"set": {"key": "beat", "value": True}},
                {"log": {"message": "beat"}},
                {"wait": {"duration": 0.25}},
                {"set": {"key": "beat", "value": False}},
            ]
        },
    },
    "fetch": {
        "sequence": [
            {"log": {"message": "fetching"}},
            {"think": {"x": "{count}"}, "outputs": {"y": "count"}},
            {"wait": {"duration": 0.4}},
        ]
    },
    "guarded": {
        "reactive_selector": [
            {"reactive_sequence": [{"condition": "count < 64"}, {"subtree": "fetch"}], "name": "work"},
            {"set": {"key": "full", "value": True}},
        ]
    },
}
MACHINE = {
    "outcomes": ["done", "aborted"],
    "preemptions": [{"when": "estop", "to": "aborted"}],
    "states": {
        "warmup": {  # waits, through the shared blackboard, for the heartbeat tree
            "tree": {"retry": 20, "child": {"sequence": [{"wait": {"duration": 0.1}}, {"condition": "beat"}]}},
            "transitions": {"success": "loop"},
        },
        "loop": {
            "machine": {
                "outcomes": ["full"],
                "states": {
                    "fill": {
                        "tree": "guarded",
                        "transitions": {"success": [{"to": "full", "if": "full"}, {"to": "fill"}]},
                    },
                },
            },
            "timeout": 30,
            "transitions": {"full": "done", "timeout": "aborted"},
        },
    },
}
ROOT = {"parallel": [{"subtree": "heartbeat"}, {"machine": MACHINE, "name": "mission"}], "policy": "success_on_one"}


def run_mission(seed: int) -> str:
    registry = Registry.default()
    for cls in TEST_SKILLS:
        registry.register(cls)
    clock = SimClock(20)
    engine = Engine(clock=clock, registry=registry, seed=seed)
    try:
        engine.blackboard.update({"count": 1, "full": False, "estop": False, "beat": False}, writer="init")
        engine.set_root(engine.builder(trees=TREES).tree(ROOT))
        assert engine.run(max_ticks=2000) is Status.SUCCESS
        return engine.trace.to_jsonl()
    finally:
        engine.close()


def test_same_seed_gives_a_byte_identical_trace() -> None:
    """A tree of generic skills and a two-level machine whose states hold trees, one blackboard.

    The `think` skill sleeps a random wall-clock time in the worker pool each run: completion
    is still observed at the same tick, so the traces match byte for byte.
    """
    first, second = run_mission(seed=3), run_mission(seed=3)
    assert first == second
    assert '"dest":"done"' in first  # it really ran to the end: 1 -> 64 by doubling
    assert first.count('"ev":"skill_start","node":"root/mission/loop/fill/guarded/work/fetch/think"') == 6
    assert '"ev":"bb_write","key":"beat","old":false,"new":true,"writer":"root/heartbeat/sequence/set"' in first
    assert '"ev":"skill_cancel","node":"root/heartbeat/sequence/wait' in first  # halted when the machine ended


@pytest.mark.parametrize(
    ("spec", "node", "reason"),
    [
        ({"boom": None}, "root", "raised RuntimeError: wheel jammed"),
        ({"liar": None}, "root", "returned undeclared outcome 'banana' (declared: failure, no_crowd, success)"),
        (
            {"wait": {"duration": "{delay}"}},
            "root",
            "blackboard key 'delay' was read by 'root' but nothing has written it",
        ),
        (
            {"check": {"condition": "ghost > 1"}},
            "root",
            "blackboard key 'ghost' was read by 'root' but nothing has written it",
        ),
        ({"while": "ghost", "child": "drive"}, "root", "guard 'ghost' cannot be evaluated: blackboard key 'ghost'"),
    ],
)
def test_failures_end_as_failure_with_a_reason_in_the_trace(make_engine, spec, node, reason) -> None:
    engine = make_engine()
    engine.set_root(engine.builder().tree(spec, name="root"))
    status = engine.run(max_ticks=5)
    assert status is Status.FAILURE
    failed = [e for e in engine.trace.of("status") if e["node"] == node and e["new"] == "FAILURE"]
    assert failed and failed[0]["reason"].startswith(reason)
    assert engine.error is None  # the engine itself never saw an exception


def test_a_failing_skill_does_not_stop_the_mission(make_engine) -> None:
    engine = make_engine()
    engine.set_root(
        engine.builder().tree({"sequence": [{"force_success": "boom"}, {"set": {"key": "after", "value": 1}}]})
    )
    assert engine.run(max_ticks=5) is Status.SUCCESS
    assert engine.blackboard.get("after") == 1


def test_ten_thousand_ticks_of_sixty_second_timeouts_never_touch_the_wall_clock(
    make_engine, monkeypatch: pytest.MonkeyPatch
) -> None:
    """10,000 ticks at 10 Hz are 1,000 s of mission time; 60 s timeouts fire on schedule.

    How long this takes in wall time is a figure of `python -m tests.bench tick` (`simclock_timeouts`;
    no timed assertions in tests); here we prove the structural reason it is fast: nothing ever
    sleeps or reads real time.
    """

    def forbidden(*_: object) -> None:
        raise AssertionError("the engine used real time on the sim clock")

    monkeypatch.setattr(time, "sleep", forbidden)
    monkeypatch.setattr(time, "time", forbidden)
    monkeypatch.setattr(time, "monotonic", forbidden)
    engine = make_engine(rate_hz=10)
    engine.set_root(engine.builder().tree(timeouts_spec()))
    engine.run(max_ticks=10_000)
    assert engine.clock.ticks == 10_000
    assert engine.clock.now() == 1000.0
    cancels = engine.trace.of("skill_cancel")
    tree_timeouts = [c["t"] for c in cancels if c["node"].startswith("root/repeat")]
    # each restart comes one tick after the previous timeout: 60.0, 120.1, 180.2, ...
    assert tree_timeouts == [round(60.0 * k + 0.1 * (k - 1), 6) for k in range(1, 17)]
    state_timeouts = [e["t"] for e in engine.trace.of("transition") if e["trigger"] == "work:timeout"]
    assert len(state_timeouts) == 16
    assert state_timeouts[:2] == [60.0, 120.0]  # the state re-enters at once: 60 s apart exactly
