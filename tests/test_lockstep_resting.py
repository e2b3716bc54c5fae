"""Lockstep skips a process that rests, and steps it again as soon as it has work.

Two real Zenoh nodes on loopback in this process: the mission's, with its ``LockstepObserver``,
and a skills process's, serving the real ``Lockstep`` handler over a run service whose after-tick
work the test controls (as an outbox with photos to send, or none). What is counted is how often
that work ran: a skipped step must be one that would have done nothing.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from botstage.missions.distributed.names import lockstep_service
from botstage.missions.distributed.process import (
    LOCKSTEP_TYPE,
    RECHECK_S,
    Lockstep,
    LockstepObserver,
)
from botstage.robots.clock import SimClock
from botstage.robots.ros2.node import Ros2Node
from botstage.skills.remote.protocol import State, TickReply, reply_fields, reply_of
from tests.test_ros2_interop import listening_node

FAILSAFE_S = 30.0


class Outbox:
    """A run service with after-tick work while ``pending`` photos wait, one sent per step."""

    def __init__(self) -> None:
        self.pending = 0
        self.steps = 0

    def after_tick(self, session: Any) -> None:
        self.steps += 1
        self.pending = max(0, self.pending - 1)

    def resting(self) -> bool:
        return self.pending == 0


class Counter:
    """A plug-in's run service with after-tick work and no say on resting: stepped every tick."""

    def __init__(self) -> None:
        self.steps = 0

    def after_tick(self, session: Any) -> None:
        self.steps += 1


@pytest.fixture
def nodes() -> Iterator[tuple[Ros2Node, Ros2Node]]:
    mission, endpoint = listening_node("mission")
    with mission, Ros2Node("skills_pc", connect=[endpoint]) as skills:
        yield mission, skills


def serve(node: Ros2Node, services: list[Any]) -> SimClock:
    clock = SimClock(10.0)
    lockstep = Lockstep(clock, services, SimpleNamespace(clock=clock, folder=Path(".")))
    node.service(lockstep_service(node.name), LOCKSTEP_TYPE, lockstep.handle)
    return clock


def ticks(observer: LockstepObserver, session: Any, count: int) -> None:
    for _ in range(count):
        session.clock.next_tick()
        observer.after_tick(session)


def test_a_resting_process_is_skipped_until_work_is_given_and_stepped_until_done(
    nodes: tuple[Ros2Node, Ros2Node],
) -> None:
    mission, skills = nodes
    outbox = Outbox()
    remote_clock = serve(skills, [outbox])
    given = {"skills_pc": 0}
    said: list[str] = []
    observer = LockstepObserver(mission, ["skills_pc"], said.append, lambda process: given[process])
    observer.wait_ready(FAILSAFE_S)
    session = SimpleNamespace(clock=SimClock(10.0))

    ticks(observer, session, 5)
    assert outbox.steps == 1  # the first step answered "resting": the next four were skipped
    assert (observer.steps, observer.skipped) == (1, 4)
    assert remote_clock.ticks == 1

    outbox.pending = 3  # a skill's reply said so: an upload was recorded over there
    given["skills_pc"] += 1
    ticks(observer, session, 6)
    assert outbox.steps == 1 + 3  # stepped until the last photo went, then resting again
    assert remote_clock.ticks == 8  # the tick of its last step
    assert (observer.steps, observer.skipped) == (4, 7)
    assert said == []


def test_work_from_outside_the_mission_is_picked_up_by_the_recheck(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    """A ROS 2 tool's goal to the process (no skill reply tells the mission): stepped within RECHECK_S."""
    mission, skills = nodes
    outbox = Outbox()
    serve(skills, [outbox])
    observer = LockstepObserver(mission, ["skills_pc"], lambda _: None)
    observer.wait_ready(FAILSAFE_S)
    session = SimpleNamespace(clock=SimClock(10.0))
    every = round(RECHECK_S / session.clock.period)

    ticks(observer, session, 2)
    assert outbox.steps == 1  # rested at tick 1
    outbox.pending = 2  # a goal from outside: nothing tells the mission
    ticks(observer, session, every - 2)
    assert outbox.steps == 1  # still skipped: its recheck falls on tick 1 + every
    ticks(observer, session, 1)
    assert outbox.steps == 2  # the recheck stepped it; it has work now, so it is stepped each tick
    ticks(observer, session, 3)
    assert outbox.steps == 3 and outbox.pending == 0  # done, resting again after the last photo
    assert observer.resting


def test_a_service_that_cannot_say_it_rests_is_stepped_every_tick(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    mission, skills = nodes
    counter = Counter()
    serve(skills, [Outbox(), counter])
    observer = LockstepObserver(mission, ["skills_pc"], lambda _: None)
    observer.wait_ready(FAILSAFE_S)
    session = SimpleNamespace(clock=SimClock(10.0))
    ticks(observer, session, 4)
    assert counter.steps == 4 and observer.skipped == 0


def test_the_end_of_the_run_asks_a_resting_process_for_its_summary(nodes: tuple[Ros2Node, Ros2Node]) -> None:
    mission, skills = nodes

    class Summarised(Outbox):
        def finished(self, session: Any, result: Any) -> None:
            result.summary["upload"] = {"photos_uploaded": 7}

    serve(skills, [Summarised()])
    observer = LockstepObserver(mission, ["skills_pc"], lambda _: None)
    observer.wait_ready(FAILSAFE_S)
    session = SimpleNamespace(clock=SimClock(10.0))
    ticks(observer, session, 3)
    assert observer.skipped == 2
    result = SimpleNamespace(summary={"counters": {}})
    observer.finished(session, result)  # type: ignore[arg-type]
    assert result.summary["upload"] == {"photos_uploaded": 7}
    assert result.summary["lockstep"] == {"steps": 1, "skipped": 2}


def test_a_skill_reply_carries_whether_its_process_has_after_tick_work() -> None:
    rested = reply_of(reply_fields(TickReply(State.ENDED, "success", pending_after_tick=False)))
    assert rested.pending_after_tick is False
    assert reply_of(reply_fields(TickReply(State.RUNNING))).pending_after_tick is True
    # a peer that does not say (a mapping without the field): stepped, as before resting existed
    assert reply_of({"state": 0, "outcome": "", "reason": "", "rng": b""}).pending_after_tick is True
