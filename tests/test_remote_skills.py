"""Remote skills without a network: the host, the proxy and the fields they exchange.

A skill run through ``remote_of`` and a ``SkillHost`` (over ``DirectLink``, which encodes every
request and reply as the wire does) must be indistinguishable from the local skill: outcomes,
outputs (tuples stay tuples), log lines and blackboard writes in their order, cancellation that
runs the skill's ``finally`` where it runs, the node's random state, and whole missions whose
trace is byte-identical to the local run's.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.runner import run
from botstage.robots.remote import values
from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.registry import Registry
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import DirectLink, Step, TickReply, TickRequest, reply_of, request_of
from botstage.skills.remote.proxy import RemoteLost, remote_of

ROOT = Path(__file__).resolve().parent.parent


# -- values ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "value",
    [
        None,
        True,
        3,
        -2.5,
        "é",
        [1, (2, 3), {"a": (4,)}],
        (1.0, 2.0),
        {"$tuple": 1},  # a dict that looks like a tag stays a dict
        {1: "a", (2, 3): "b"},
        b"\x00\xff",
        math.inf,
        {"nested": [[(), []]]},
    ],
)
def test_values_cross_unchanged(value: Any) -> None:
    back = values.loads(values.dumps(value))
    assert back == value and type(back) is type(value)
    if isinstance(value, list):
        assert type(back[1]) is tuple


def test_nan_crosses_as_nan() -> None:
    assert math.isnan(values.loads(values.dumps(math.nan)))


def test_values_that_are_not_data_are_refused_with_their_path() -> None:
    with pytest.raises(values.ValueCodecError, match=r"outputs\.pose\[1\]: a object cannot be sent"):
        values.dumps({"pose": [1, object()]}, "outputs")


def test_malformed_text_is_refused() -> None:
    with pytest.raises(values.ValueCodecError, match="not a value"):
        values.loads("{oops", "the call")


# -- a host and a proxy over the wire's fields ----------------------------------------------


class Count(Skill):
    """Counts ticks, logs and writes a key each tick, draws from the node's generator."""

    name = "count_up"
    inputs = {
        "n": In(int, doc="ticks to run"),
        "key": In(str, doc="the key written each tick", names_key="write"),
    }
    outputs = {"pair": Out(tuple[int, int]), "drawn": Out(int)}
    outcomes = ("short",)

    def run(self, ctx: SkillContext, n: int, key: str) -> SkillRun:
        drawn = ctx.rng.randrange(1_000_000)
        for i in range(n):
            ctx.logger.info(f"tick {i} at {ctx.clock.now():.1f}")
            ctx.blackboard.set(key, (i, ctx.clock.ticks))
            yield
        return Outcome("success" if n else "short", f"counted {n}", {"pair": (n, n + 1), "drawn": drawn})


class Stuck(Skill):
    """Runs until cancelled; its cleanup logs and writes the key it was given."""

    name = "stuck"
    inputs = {"key": In(str, names_key="write")}

    def run(self, ctx: SkillContext, key: str) -> SkillRun:
        try:
            while True:
                yield
        finally:
            ctx.logger.warning("cleaned up")
            ctx.blackboard.set(key, "stopped")


class Boom(Skill):
    name = "boom"

    def run(self, ctx: SkillContext) -> SkillRun:
        yield
        raise RuntimeError("the sensor caught fire")


class Board:
    def __init__(self) -> None:
        self.values: dict[str, Any] = {}
        self.writes: list[tuple[str, Any]] = []

    def get(self, key: str) -> Any:
        return self.values[key]

    def set(self, key: str, value: Any) -> None:
        self.values[key] = value
        self.writes.append((key, value))

    def exists(self, key: str) -> bool:
        return key in self.values


class Clock:
    simulated, period = True, 0.1

    def __init__(self) -> None:
        self.ticks = 0

    def now(self) -> float:
        return self.ticks * self.period

    def next_tick(self) -> None:
        self.ticks += 1


class Lines:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def sink(self, node: str, level: str, message: str) -> None:
        self.lines.append((level, message))


@pytest.fixture
def host() -> Any:
    host = SkillHost(Registry([Count, Stuck, Boom]), {})
    yield host
    host.close()


def drive(skill_cls: type[Skill], inputs: dict[str, Any], ticks: int = 20, seed: str = "7:/root/n") -> dict[str, Any]:
    """Run a skill through SkillExecution as a node does; what it did, tick by tick."""
    import random

    from botstage.skills.base import SkillLogger
    from botstage.skills.execution import SkillExecution

    clock, board, lines = Clock(), Board(), Lines()
    rng = random.Random(seed)
    ctx = SkillContext(
        clock=clock,
        params=skill_cls.Params(),
        logger=SkillLogger("/root/n", sink=lines.sink),
        blackboard=board,
        workers=None,  # type: ignore[arg-type]
        rng=rng,
        node="/root/n",
    )
    execution = SkillExecution(skill_cls(), ctx)
    outcome = execution.start(inputs)
    while outcome is None and clock.ticks < ticks:
        clock.next_tick()
        outcome = execution.step()
    problem = execution.cancel() if outcome is None else None
    return {"outcome": outcome, "writes": board.writes, "lines": lines.lines, "rng": rng.getstate(), "problem": problem}


def test_a_remote_run_is_the_local_run(host: SkillHost) -> None:
    local = drive(Count, {"n": 3, "key": "progress"})
    remote = drive(remote_of(Count, DirectLink(host)), {"n": 3, "key": "progress"})
    assert remote == local
    assert remote["outcome"] == Outcome(
        "success", "counted 3", {"pair": (3, 4), "drawn": local["outcome"].outputs["drawn"]}
    )
    assert remote["writes"][-1] == ("progress", (2, 2))  # a tuple, written at the tick it was made
    assert host.calls == 0


def test_an_outcome_of_the_first_step_comes_back_from_the_start(host: SkillHost) -> None:
    assert drive(remote_of(Count, DirectLink(host)), {"n": 0, "key": "k"})["outcome"].name == "short"


def test_cancelling_runs_the_cleanup_remotely_and_replays_it(host: SkillHost) -> None:
    local = drive(Stuck, {"key": "state"}, ticks=3)
    remote = drive(remote_of(Stuck, DirectLink(host)), {"key": "state"}, ticks=3)
    assert remote == local
    assert remote["writes"] == [("state", "stopped")] and ("warning", "cleaned up") in remote["lines"]
    assert host.calls == 0


def test_a_skill_that_raises_fails_with_the_same_reason(host: SkillHost) -> None:
    local, remote = drive(Boom, {}), drive(remote_of(Boom, DirectLink(host)), {})
    assert remote["outcome"] == local["outcome"] == Outcome("failure", "raised RuntimeError: the sensor caught fire")
    assert remote["lines"] == local["lines"]


class Gone:
    remote = "kinect_pc"

    def tick(self, request: TickRequest) -> TickReply:
        raise RemoteLost("remote 'kinect_pc' lost")


def test_a_lost_remote_fails_the_node_with_the_reason() -> None:
    assert drive(remote_of(Count, Gone()), {"n": 3, "key": "k"})["outcome"] == Outcome(
        "failure", "remote 'kinect_pc' lost"
    )


def test_a_host_that_forgot_the_call_fails_it(host: SkillHost) -> None:
    link = DirectLink(host, "upload_pc")

    class Forgetful:
        remote = "upload_pc"

        def tick(self, request: TickRequest) -> TickReply:
            reply = link.tick(request)
            if request.step is Step.START:
                host.handle(TickRequest(request.call_id, Step.CANCEL, 0.0, 0, 0.1, True))
            return reply

    outcome = drive(remote_of(Count, Forgetful()), {"n": 3, "key": "k"})["outcome"]
    assert outcome.name == "failure" and outcome.reason.startswith("remote 'upload_pc' lost the call: no call")


def test_a_host_refuses_skills_it_does_not_serve_and_bad_parameters() -> None:
    host = SkillHost(Registry([Count, Stuck]), {}, skills=["stuck"])
    try:
        outcome = drive(remote_of(Count, DirectLink(host)), {"n": 1, "key": "k"})["outcome"]
        assert outcome == Outcome("failure", "this host does not serve 'count_up'")
    finally:
        host.close()
    with pytest.raises(LookupError, match="unknown skill 'nope'"):
        SkillHost(Registry([Count]), {}, skills=["nope"])


def test_closing_the_host_cancels_what_runs() -> None:
    host = SkillHost(Registry([Stuck]), {})
    link = DirectLink(host)
    proxy = remote_of(Stuck, link)
    board = Board()
    from botstage.skills.base import SkillLogger
    from botstage.skills.execution import SkillExecution

    ctx = SkillContext(Clock(), Stuck.Params(), SkillLogger("/n"), board, None, node="/n")  # type: ignore[arg-type]
    execution = SkillExecution(proxy(), ctx)
    assert execution.start({"key": "s"}) is None and host.calls == 1
    host.close()
    assert host.calls == 0
    assert execution.step() == Outcome("failure", "remote 'local' lost the call: the skill host is closed")


def test_malformed_fields_are_refused() -> None:
    with pytest.raises(ValueError, match="step 9"):
        request_of({"step": 9})
    with pytest.raises(ValueError, match="state 7"):
        reply_of({"state": 7})


# -- whole missions --------------------------------------------------------------------------


class CountingLink(DirectLink):
    """A direct link that counts the calls started per skill (so the test knows they went remote)."""

    def __init__(self, host: SkillHost, remote: str) -> None:
        super().__init__(host, remote)
        self.started: dict[str, int] = {}

    def tick(self, request: TickRequest) -> TickReply:
        if request.call is not None:
            self.started[request.call.skill] = self.started.get(request.call.skill, 0) + 1
        return super().tick(request)


class Handover:
    """Gives a host the interfaces of the run it serves (in one process, for this test)."""

    def __init__(self, interfaces: dict[str, Any]) -> None:
        self.interfaces = interfaces

    def started(self, session: Any) -> None:
        self.interfaces.update(session.interfaces)


@pytest.mark.parametrize(
    ("mission", "until", "remote"),
    [
        (
            "peoplebot_entertainer.yaml",
            240.0,
            ["detect_crowd", "listen", "converse", "speak", "photo", "upload", "display"],
        ),
        ("chefbot_delivery.yaml", 120.0, ["speak", "wait_for", "navigate"]),
    ],
)
def test_a_mission_with_remote_skills_leaves_the_local_runs_trace(
    tmp_path: Path, mission: str, until: float, remote: list[str]
) -> None:
    local = run(ROOT / "missions" / "examples" / mission, seed=3, until=until, out=tmp_path / "local")
    interfaces: dict[str, Any] = {}
    registry = Registry.default()
    host = SkillHost(Registry.default(), interfaces, skills=remote)
    link = CountingLink(host, "remote_pc")
    try:
        for name in remote:
            registry.register(remote_of(registry.get(name), link), replace=True)
        distributed = run(
            ROOT / "missions" / "examples" / mission,
            seed=3,
            until=until,
            out=tmp_path / "remote",
            registry=registry,
            observers=[Handover(interfaces)],
        )
    finally:
        host.close()
    assert sorted(link.started) == sorted(remote), f"calls that went remote: {link.started}"
    assert (tmp_path / "remote/trace.jsonl").read_bytes() == (tmp_path / "local/trace.jsonl").read_bytes()
    counters = [json.loads((tmp_path / f"{r}/summary.json").read_text())["counters"] for r in ("local", "remote")]
    assert counters[0] == counters[1]
    assert local.summary["counters"] == distributed.summary["counters"]
