"""Preemptions in depth: nested, several at once, guarded, against a timeout, and what they cancel.

Every machine here is a small YAML mission that goes through the normal path (checked, then
built as a run builds it) and runs on the sim clock; the test writes the blackboard between
ticks, as an operator or a sensor would.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest
from py_trees.common import Status

from botstage.behaviors.engine import Engine
from botstage.missions.check import check
from botstage.missions.runner import build
from botstage.skills.registry import Registry
from tests.conftest import index_of


@pytest.fixture
def mission(tmp_path: Path, registry: Registry, make_engine):
    """Check a mission written as YAML text and build it on a sim-clock engine."""

    def start(text: str) -> tuple[Engine, Any]:
        path = tmp_path / "mission.yaml"
        path.write_text(textwrap.dedent(text))
        checked = check(path, registry=registry)
        assert checked.ok, "\n".join(str(p) for p in checked.problems)
        assert checked.mission is not None
        engine = make_engine(rate_hz=checked.mission.rate_hz, seed=checked.mission.seed)
        root = build(engine, checked)
        engine.set_root(root)
        return engine, root

    return start


def moves(engine: Engine) -> list[tuple[str, str, str]]:
    return [(e["source"], e["dest"], e["trigger"]) for e in engine.trace.of("transition")]


def write(engine: Engine, **values: Any) -> None:
    for key, value in values.items():
        engine.blackboard.set(key, value, writer="operator")


def step_to(engine: Engine, t: float) -> None:
    """Tick until the next tick is the one at mission time ``t``."""
    engine.run(until=t, stop_when_done=False)
    assert engine.clock.now() == pytest.approx(t)


NESTED = """
    name: nested
    blackboard: {estop: false, pause: false}
    machine:
      outcomes: [done, stopped]
      preemptions:
        - {when: estop, to: halted}
      states:
        work:
          on_exit: {log: "left work"}
          machine:
            initial: inner
            outcomes: [finished]
            preemptions:
              - {when: pause, to: paused}
            states:
              paused: {skill: drive, transitions: {success: finished, failure: finished}}
              inner:
                on_exit: {log: "left inner"}
                machine:
                  outcomes: [finished]
                  states:
                    deep: {skill: drive, transitions: {success: finished, failure: finished}}
                transitions: {finished: finished}
          transitions: {finished: done}
        halted: {skill: wait, inputs: {duration: 0.5}, transitions: {success: stopped, failure: stopped}}
"""


def test_an_outer_preemption_fires_two_levels_deep_and_cancels_what_runs_there(mission) -> None:
    engine, root = mission(NESTED)
    step_to(engine, 1.5)
    assert root.state == "work/inner/deep"
    write(engine, estop=True)
    assert engine.run(max_ticks=20) is Status.FAILURE  # `stopped` is not the machine's success
    assert root.outcome.name == "stopped"
    assert moves(engine) == [
        ("", "work/inner/deep", "start"),
        ("work/inner/deep", "halted", "preempt 'estop'"),
        ("halted", "stopped", "halted:success"),
    ]
    events = engine.trace.events
    cancel = index_of(events, ev="skill_cancel", node=f"{root.path}/work/inner/deep")
    assert events[cancel]["t"] == pytest.approx(1.5)
    assert events[cancel]["reason"] == "preempted: 'estop' holds"
    # the skill's finally, then the exit actions innermost first, then the move, then the next skill
    order = [
        index_of(events, ev="log", message="motors stopped"),
        cancel,
        index_of(events, ev="log", message="left inner"),
        index_of(events, ev="log", message="left work"),
        index_of(events, ev="transition", dest="halted"),
        index_of(events, ev="skill_start", node=f"{root.path}/halted"),
    ]
    assert order == sorted(order)
    assert not [e for e in engine.trace.of("skill_outcome") if e["node"] == f"{root.path}/work/inner/deep"]


def test_a_middle_machines_preemption_fires_from_deeper_and_leaves_only_what_it_must(mission) -> None:
    engine, root = mission(NESTED)
    step_to(engine, 1.0)
    write(engine, pause=True)
    engine.run(max_ticks=5)
    assert root.state == "work/paused"
    assert moves(engine)[1:] == [("work/inner/deep", "work/paused", "preempt 'pause'")]
    assert [e["message"] for e in engine.trace.of("log") if e["message"].startswith("left")] == ["left inner"]
    assert [e["node"] for e in engine.trace.of("skill_cancel")] == [f"{root.path}/work/inner/deep"]
    # the outer machine's preemption still reaches into it
    write(engine, estop=True)
    engine.run(max_ticks=1)
    assert moves(engine)[-1] == ("work/paused", "halted", "preempt 'estop'")


OUTER_AND_INNER = """
    name: outer_and_inner
    blackboard: {outer_alarm: false, inner_alarm: false}
    machine:
      outcomes: [done, stopped]
      preemptions:
        - {when: outer_alarm, to: safe}
      states:
        work:
          machine:
            outcomes: [finished]
            preemptions:
              - {when: inner_alarm, to: recover}
            states:
              busy: {skill: drive, transitions: {success: finished, failure: finished}}
              recover: {skill: wait, inputs: {duration: 0.3}, transitions: {success: finished, failure: finished}}
          transitions: {finished: done}
        safe: {skill: wait, inputs: {duration: 0.3}, transitions: {success: stopped, failure: stopped}}
"""


@pytest.mark.parametrize(
    ("alarms", "dest", "label"),
    [
        ({"outer_alarm": True, "inner_alarm": True}, "safe", "preempt 'outer_alarm'"),
        ({"outer_alarm": True}, "safe", "preempt 'outer_alarm'"),
        ({"inner_alarm": True}, "work/recover", "preempt 'inner_alarm'"),
    ],
)
def test_the_outermost_preemption_wins_when_several_levels_fire_in_one_tick(
    mission, alarms: dict[str, bool], dest: str, label: str
) -> None:
    engine, root = mission(OUTER_AND_INNER)
    step_to(engine, 1.0)
    write(engine, **alarms)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", dest, label)]
    cancel = engine.trace.of("skill_cancel")
    assert [(e["node"], e["reason"]) for e in cancel] == [(f"{root.path}/work/busy", f"preempted: {label[8:]} holds")]


def several(first: tuple[str, str], second: tuple[str, str]) -> str:
    return f"""
        name: several
        blackboard: {{estop: false, low_battery: false}}
        machine:
          outcomes: [done]
          preemptions:
            - {{when: {first[0]}, to: {first[1]}}}
            - {{when: {second[0]}, to: {second[1]}}}
          states:
            work: {{skill: drive, transitions: {{success: done, failure: done}}}}
            stopped: {{skill: drive, transitions: {{success: done, failure: done}}}}
            charging: {{skill: drive, transitions: {{success: done, failure: done}}}}
    """


@pytest.mark.parametrize(
    ("first", "second"),
    [(("estop", "stopped"), ("low_battery", "charging")), (("low_battery", "charging"), ("estop", "stopped"))],
)
def test_several_preemptions_of_one_machine_fire_in_the_order_written(
    mission, first: tuple[str, str], second: tuple[str, str]
) -> None:
    engine, root = mission(several(first, second))
    step_to(engine, 0.5)
    write(engine, estop=True, low_battery=True)
    engine.run(max_ticks=30)
    # the first one written wins, and holds the machine in its target while it holds:
    # the second, true all along, does not take it away
    assert moves(engine)[1:] == [("work", first[1], f"preempt {first[0]!r}")]
    assert root.state == first[1]
    write(engine, **{first[0]: False})
    engine.run(max_ticks=1)
    assert moves(engine)[2:] == [(first[1], second[1], f"preempt {second[0]!r}")]
    assert root.state == second[1]


def test_a_later_preemption_fires_alone_and_an_earlier_one_still_overrides_it(mission) -> None:
    engine, root = mission(several(("estop", "stopped"), ("low_battery", "charging")))
    step_to(engine, 0.5)
    write(engine, low_battery=True)
    engine.run(max_ticks=3)
    write(engine, estop=True)
    engine.run(max_ticks=3)
    assert moves(engine)[1:] == [
        ("work", "charging", "preempt 'low_battery'"),
        ("charging", "stopped", "preempt 'estop'"),
    ]
    assert root.state == "stopped"


GUARDED = """
    name: guarded
    blackboard: {alarm: false, armed: false, fallback: false}
    machine:
      outcomes: [done, stopped]
      states:
        work:
          machine:
            outcomes: [finished, aborted]
            preemptions:
              - {when: alarm, to: aborted}
            states:
              busy: {skill: drive, transitions: {success: finished, failure: finished}}
          transitions:
            finished: done
            aborted: [{to: safe, if: armed}, {to: elsewhere, if: fallback}]
        safe: {skill: wait, inputs: {duration: 0.3}, transitions: {success: stopped, failure: stopped}}
        elsewhere: {skill: wait, inputs: {duration: 0.3}, transitions: {success: stopped, failure: stopped}}
"""


def test_a_guarded_preemption_waits_for_its_guard_without_cancelling_anything(mission) -> None:
    engine, root = mission(GUARDED)
    step_to(engine, 0.5)
    write(engine, alarm=True)
    engine.run(max_ticks=10)
    # no guard on the way out holds: nothing fired, nothing was cancelled, the machine runs on
    assert root.status is Status.RUNNING
    assert root.state == "work/busy"
    assert moves(engine) == [("", "work/busy", "start")]
    assert engine.trace.of("skill_cancel") == []
    write(engine, armed=True)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", "safe", "preempt 'alarm'")]
    assert engine.trace.of("skill_cancel")[0]["node"] == f"{root.path}/work/busy"


@pytest.mark.parametrize(("guards", "dest"), [({"armed": True}, "safe"), ({"fallback": True}, "elsewhere")])
def test_a_guarded_preemption_takes_the_first_way_whose_guard_holds(
    mission, guards: dict[str, bool], dest: str
) -> None:
    engine, _root = mission(GUARDED)
    step_to(engine, 0.5)
    write(engine, alarm=True, **guards)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", dest, "preempt 'alarm'")]


def test_a_blocked_preemption_lets_the_next_one_fire(mission) -> None:
    text = GUARDED.replace(
        "              - {when: alarm, to: aborted}\n",
        "              - {when: alarm, to: aborted}\n              - {when: alarm, to: finished}\n",
    )
    engine, root = mission(text)
    step_to(engine, 0.5)
    write(engine, alarm=True)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", "done", "preempt 'alarm'")]
    assert root.outcome.name == "done"


def test_a_preemption_whose_guard_cannot_be_evaluated_fails_the_machine_with_its_reason(mission) -> None:
    engine, root = mission(GUARDED.replace("if: armed}", "if: 'armed > 2'}"))
    step_to(engine, 0.5)
    write(engine, alarm=True, armed="yes")
    assert engine.run(max_ticks=3) is Status.FAILURE
    assert root.outcome.reason.startswith("preemption 'alarm' cannot be evaluated: ")


TIMED = """
    name: timed
    blackboard: {outer_alarm: false, inner_alarm: false}
    machine:
      outcomes: [done, stopped, late]
      preemptions:
        - {when: outer_alarm, to: safe}
      states:
        work:
          timeout: {outer_timeout}
          machine:
            outcomes: [finished, slow]
            preemptions:
              - {when: inner_alarm, to: recover}
            states:
              busy:
                skill: drive
                timeout: {inner_timeout}
                transitions: {success: finished, failure: finished, timeout: slow}
              recover: {skill: drive, transitions: {success: finished, failure: finished}}
          transitions: {finished: done, slow: late, timeout: late}
        safe: {skill: drive, transitions: {success: stopped, failure: stopped}}
"""


def timed(outer: float, inner: float) -> str:
    return TIMED.replace("{outer_timeout}", str(outer)).replace("{inner_timeout}", str(inner))


@pytest.mark.parametrize(
    ("timeouts", "alarm", "dest", "label"),
    [
        # one level: the preemption (an interrupt) wins over the timeout due at the same tick
        ((2.0, 60.0), {"outer_alarm": True}, "safe", "preempt 'outer_alarm'"),
        ((60.0, 2.0), {"inner_alarm": True}, "work/recover", "preempt 'inner_alarm'"),
        # across levels the outermost wins: an outer preemption over an inner timeout ...
        ((60.0, 2.0), {"outer_alarm": True}, "safe", "preempt 'outer_alarm'"),
        # ... and an outer timeout over an inner preemption
        ((2.0, 60.0), {"inner_alarm": True}, "late", "work:timeout"),
    ],
)
def test_a_preemption_and_a_timeout_due_in_the_same_tick(
    mission, timeouts: tuple[float, float], alarm: dict[str, bool], dest: str, label: str
) -> None:
    engine, root = mission(timed(*timeouts))
    step_to(engine, 2.0)
    write(engine, **alarm)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", dest, label)]
    cancel = engine.trace.of("skill_cancel")
    assert [(e["node"], e["t"]) for e in cancel] == [(f"{root.path}/work/busy", 2.0)]


@pytest.mark.parametrize(
    ("timeouts", "dest", "label"),
    [((2.0, 60.0), "late", "work:timeout"), ((60.0, 2.0), "late", "work/busy:timeout > work:slow")],
)
def test_without_the_preemption_that_tick_times_out(
    mission, timeouts: tuple[float, float], dest: str, label: str
) -> None:
    engine, root = mission(timed(*timeouts))
    step_to(engine, 2.0)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [("work/busy", dest, label)]
    assert root.outcome.name == "late"


def test_an_inner_preemption_does_not_restart_the_outer_states_timeout(mission) -> None:
    engine, root = mission(timed(2.0, 60.0))
    step_to(engine, 1.0)
    write(engine, inner_alarm=True)
    engine.run(max_ticks=1)
    assert root.state == "work/recover"
    # the outer state's clock was not reset by moving inside it: it times out at 2 s
    step_to(engine, 2.0)
    engine.run(max_ticks=1)
    assert moves(engine)[1:] == [
        ("work/busy", "work/recover", "preempt 'inner_alarm'"),
        ("work/recover", "late", "work:timeout"),
    ]
