"""Shared fixtures: an engine on the sim clock with a few purpose-built skills."""

from __future__ import annotations

import random
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from botstage.behaviors.engine import Engine
from botstage.robots.clock import SimClock
from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.registry import Registry

# Property tests judge what is computed, never how long it took: a loaded CI machine (two cores,
# two workers) made a 200 ms example deadline fail a correct test.
settings.register_profile("botstage", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("botstage")


class Drive(Skill):
    """Drives until cancelled; its finally stops the motors (and says so in the trace)."""

    name = "drive"
    inputs = {"speed": In(float, default=0.5)}

    def run(self, ctx: SkillContext, speed: float) -> SkillRun:
        ctx.logger.info(f"motors at {speed}")
        try:
            while True:
                yield
        finally:
            ctx.logger.info("motors stopped")


class Boom(Skill):
    name = "boom"

    def run(self, ctx: SkillContext) -> SkillRun:
        yield
        raise RuntimeError("wheel jammed")


class Liar(Skill):
    name = "liar"
    outcomes = ("no_crowd",)

    def run(self, ctx: SkillContext) -> Outcome:
        return Outcome("banana", "not a declared outcome")


class Think(Skill):
    """Blocking work in the worker pool, of random wall-clock duration."""

    name = "think"
    inputs = {"x": In(int)}
    outputs = {"y": Out(int)}

    def run(self, ctx: SkillContext, x: int) -> SkillRun:
        delay = random.random() * 0.003  # wall-clock jitter must not change the trace

        def work() -> int:
            threading.Event().wait(delay)
            return x * 2

        y = yield ctx.submit(work)
        return Outcome.success(y=y)


class Fail(Skill):
    name = "fail"
    inputs = {"reason": In(str, default="told to fail")}

    def run(self, ctx: SkillContext, reason: str) -> Outcome:
        return Outcome.failure(reason)


TEST_SKILLS = (Drive, Boom, Liar, Think, Fail)


@pytest.fixture
def registry() -> Registry:
    registry = Registry.default()
    for cls in TEST_SKILLS:
        registry.register(cls)
    return registry


@pytest.fixture
def make_engine(registry: Registry) -> Iterator[Callable[..., Engine]]:
    engines: list[Engine] = []

    def make(rate_hz: float = 10.0, seed: int = 0, **kwargs: Any) -> Engine:
        engine = Engine(clock=SimClock(rate_hz), registry=registry, seed=seed, **kwargs)
        engines.append(engine)
        return engine

    yield make
    for engine in engines:
        engine.close()


def kinds(engine: Engine, *names: str) -> list[dict[str, Any]]:
    return engine.trace.of(*names)


def index_of(events: list[dict[str, Any]], **match: Any) -> int:
    for i, event in enumerate(events):
        if all(event.get(k) == v for k, v in match.items()):
            return i
    raise AssertionError(f"no event matching {match}")


@pytest.fixture
def gallery(tmp_path: Any) -> Iterator[Any]:
    """A real gallery server on a free loopback port, stopped after the test."""
    from botstage.missions.gallery.server import start_gallery

    running = start_gallery(tmp_path / "gallery")
    yield running
    running.stop()
