"""The skill contract on its own, without trees or machines (as a remote peer would use it)."""

from __future__ import annotations

from concurrent.futures import Future
from typing import Any

import pytest
from pydantic import BaseModel

from botstage.robots.clock import SimClock
from botstage.skills.base import In, NoParams, Out, Outcome, Skill, SkillContext, SkillLogger, SkillRun
from botstage.skills.execution import SkillExecution
from botstage.skills.testing import DictBoard
from botstage.skills.workers import Workers


def context(skill: Skill, logs: list[str] | None = None, workers: Workers | None = None) -> SkillContext:
    sink = (lambda node, level, message: logs.append(f"{level}:{message}")) if logs is not None else None
    return SkillContext(
        clock=SimClock(10),
        params=skill.params,
        logger=SkillLogger("test", sink=sink),
        blackboard=DictBoard(),
        workers=workers or Workers(),
    )


class Approach(Skill):
    name = "approach"
    outcomes = ("no_crowd",)
    inputs = {"target": In(list[float]), "speed": In(float, default=0.3)}
    outputs = {"distance": Out(float)}

    class Params(BaseModel):
        stop_distance: float = 0.8

    def run(self, ctx: SkillContext, target: list[float], speed: float) -> SkillRun:
        released = []
        try:
            for _ in range(3):
                yield
            return Outcome.success(distance=ctx.params.stop_distance)
        finally:
            released.append(True)
            ctx.logger.info("released")


def test_declaration_is_described() -> None:
    info = Approach.describe()
    assert info["outcomes"] == ["failure", "no_crowd", "success"]
    assert info["inputs"]["target"]["required"] is True
    assert info["inputs"]["speed"] == {"type": "float", "required": False, "doc": "", "default": 0.3}
    assert info["params"]["properties"]["stop_distance"]["default"] == 0.8


def test_bad_declarations_are_refused_at_class_creation() -> None:
    with pytest.raises(TypeError, match="must be declared with In"):

        class Bad(Skill):
            name = "bad"
            inputs = {"x": int}  # type: ignore[dict-item]

    with pytest.raises(TypeError, match="must be an identifier"):

        class Bad2(Skill):
            name = "no spaces"


def test_runs_over_ticks_and_returns_outputs() -> None:
    skill = Approach({"stop_distance": 1.5})
    run = SkillExecution(skill, context(skill))
    assert run.start({"target": [1.0, 2.0]}) is None
    assert run.step() is None
    assert run.step() is None
    outcome = run.step()
    assert outcome == Outcome("success", "", {"distance": 1.5})
    assert not run.running


def test_bad_params_are_a_validation_error() -> None:
    with pytest.raises(ValueError, match="stop_distance"):
        Approach({"stop_distance": "far"})
    with pytest.raises(ValueError, match="Extra inputs are not permitted"):
        NoParams(unknown=1)  # a skill without parameters refuses any


def test_cancel_runs_finally_now() -> None:
    logs: list[str] = []
    skill = Approach()
    run = SkillExecution(skill, context(skill, logs))
    run.start({"target": [0.0, 0.0]})
    assert logs == []
    assert run.cancel() is None
    assert logs == ["info:released"]
    assert not run.running
    assert run.cancel() is None  # idempotent


@pytest.mark.parametrize(
    ("inputs", "reason"),
    [
        ({}, "input 'target' is required"),
        ({"target": "here"}, "input 'target': expected list[float], got str"),
        ({"target": [1.0], "speed": "fast"}, "input 'speed': expected float, got str"),
        ({"target": [1.0], "sped": 1.0}, "unknown input 'sped'"),
    ],
)
def test_bad_inputs_fail_with_reason(inputs: dict[str, Any], reason: str) -> None:
    skill = Approach()
    outcome = SkillExecution(skill, context(skill)).start(inputs)
    assert outcome is not None and outcome.name == "failure"
    assert reason in outcome.reason


class Misbehaves(Skill):
    name = "misbehaves"
    inputs = {"how": In(str)}
    outputs = {"n": Out(int)}

    def run(self, ctx: SkillContext, how: str) -> SkillRun:
        yield
        if how == "raise":
            raise ValueError("sensor unplugged")
        if how == "outcome":
            return Outcome("maybe")
        if how == "output":
            return Outcome.success(m=1)
        if how == "output_type":
            return Outcome.success(n="one")
        if how == "none":
            return None
        if how == "name":
            return "failure"
        return Outcome.success(n=1)


@pytest.mark.parametrize(
    ("how", "name", "reason"),
    [
        ("raise", "failure", "raised ValueError: sensor unplugged"),
        ("outcome", "failure", "returned undeclared outcome 'maybe' (declared: failure, success)"),
        ("output", "failure", "returned undeclared output 'm'"),
        ("output_type", "failure", "output 'n': expected int, got str"),
        ("none", "failure", "run() returned NoneType instead of an Outcome"),
        ("name", "failure", ""),
        ("ok", "success", ""),
    ],
)
def test_every_misbehaviour_is_an_outcome_with_a_reason(how: str, name: str, reason: str) -> None:
    logs: list[str] = []
    skill = Misbehaves()
    run = SkillExecution(skill, context(skill, logs))
    assert run.start({"how": how}) is None
    outcome = run.step()
    assert outcome is not None
    assert outcome.name == name
    assert reason in outcome.reason if reason else outcome.reason == ""
    if how == "raise":
        assert logs == ["error:skill 'misbehaves' raised ValueError: sensor unplugged"]  # logged once


class Recognise(Skill):
    name = "recognise"
    outputs = {"text": Out(str)}

    def run(self, ctx: SkillContext) -> SkillRun:
        try:
            text = yield ctx.submit(lambda: "photo")
        except LookupError as exc:
            return Outcome.failure(f"recogniser: {exc}")
        return Outcome.success(text=text)


def test_yielding_a_future_waits_for_it_and_receives_its_result() -> None:
    workers = Workers()
    skill = Recognise()
    run = SkillExecution(skill, context(skill, workers=workers))
    assert run.start({}) is None
    workers.drain()
    assert run.step() == Outcome("success", "", {"text": "photo"})
    workers.shutdown()


def test_a_pending_future_keeps_the_skill_running() -> None:
    future: Future[str] = Future()

    class Pool:
        def submit(self, fn: Any, *args: Any, **kwargs: Any) -> Future[str]:
            return future

    skill = Recognise()
    run = SkillExecution(skill, context(skill, workers=Pool()))  # type: ignore[arg-type]
    run.start({})
    assert run.step() is None
    assert run.step() is None
    future.set_exception(LookupError("model missing"))
    assert run.step() == Outcome("failure", "recogniser: model missing")


def test_cleanup_that_raises_is_reported_not_raised() -> None:
    class Sticky(Skill):
        name = "sticky"

        def run(self, ctx: SkillContext) -> SkillRun:
            try:
                while True:
                    yield
            finally:
                raise OSError("brake did not engage")

    skill = Sticky()
    run = SkillExecution(skill, context(skill))
    run.start({})
    assert run.cancel() == "cleanup raised OSError: brake did not engage"
