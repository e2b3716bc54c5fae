"""Scenario tests: run a mission with mocked skills, scripted events and expectations.

A scenario file (YAML, usually `missions/scenarios/<mission>/<name>.yaml`)::

    mission: ../../examples/hello.yaml # relative to the scenario file
    seed: 7
    until: 60
    mocks:
      wait:                            # a script of calls, in order; the last one repeats
        - {outcome: success, duration: 2}
        - {outcome: failure, reason: "motor stalled"}
      count:                           # writes go through the node's key ports, at `after` s
        - {duration: 0.3, writes: [{after: 0.2, set: {visits: 5}}]}
      spin: [{until_cancelled: true}]  # RUNNING until the engine cancels it
      log: {always: {outcome: success}}
      check: {cycle: [{outcome: success}, {outcome: failure}]}
      detect: {probability: {success: 0.7, no_crowd: 0.3}}   # seeded: same every run
    mock_all: false                    # true: every skill not listed succeeds at once
    blackboard: {battery_pct: 15}      # overrides of the mission's initial values
    events:
      - {t: 12, set: {estop: true}}
      - {t: 40, gallery: down}       # the run's own gallery goes down (and `up` brings it back)
      - {t: 50, estop: true}         # an operator's e-stop (the mission restarts from its root)
      - {t: 60, teleop: [{v: 0.2, w: 0, seconds: 1.5}]}   # driven by hand, the tree held meanwhile
    expect:
      outcome: stopped
      states: [greeting, working/patrol, stopped]       # exact
      states_in_order: [greeting, stopped]              # or an ordered subsequence
      calls: [{skill: log, inputs: {message: "hello from botstage"}}]
      blackboard: {greeted: true}
      counters: {photos_uploaded: 2}                    # summary.json's, at the end
      within: [{from: {state: working/patrol}, to: {state: stopped}, seconds: 15}]
      never: ["estop and greeted == false"]

Mocks have the real skill's ports and outcomes: a scripted outcome or output the skill does not
declare is a located validation error, so trees and machines cannot tell the difference. Every
key, state, counter and skill a scenario names is checked against the mission
(``missions/scenario_check.py``); a `never` condition that cannot be evaluated fails the run.
Mocks are ``missions/mocks.py``; ``from_trace`` (``missions/replay.py``) writes a scenario that
replays a recorded run.
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from botstage.behaviors.blackboard import MissingKeyError
from botstage.missions.loader import Loaded, Location, Problem, load
from botstage.missions.mocks import Call, Rule, Write, calls_of, mock_of
from botstage.missions.replay import from_trace
from botstage.missions.runner import MissionInvalid, RunError, StopRun, run
from botstage.missions.scenario_check import MissionFacts, check_against_mission, mission_facts
from botstage.missions.session.observers import EventRecorder
from botstage.missions.session.session import RunSession
from botstage.missions.session.uploads import set_gallery
from botstage.missions.steering import drive_one_step, stop_everything
from botstage.robots.suggest import did_you_mean
from botstage.skills.base import Skill
from botstage.skills.expression import EvaluationError, compile_expression
from botstage.skills.registry import Registry

__all__ = [
    "Call",
    "Result",
    "Rule",
    "Scenario",
    "ScenarioSpec",
    "Write",
    "from_trace",
    "load_scenario",
    "location",
    "mock_of",
    "run_scenario",
]


class Drive(BaseModel):
    """A command held while driving by hand (the run's tree held meanwhile)."""

    model_config = ConfigDict(extra="forbid")
    v: float
    w: float
    seconds: float = Field(gt=0, description="mission seconds the command is held")


class Event(BaseModel):
    model_config = ConfigDict(extra="forbid")
    t: float = Field(ge=0, description="sim seconds")
    set: dict[str, Any] = Field(default_factory=dict)
    gallery: Literal["down", "up"] | None = Field(
        default=None, description="take the run's own gallery down, or bring it back on the same port"
    )
    estop: bool = Field(default=False, description="an operator's e-stop: every skill cancelled, the drive stopped")
    teleop: list[Drive] = Field(
        default_factory=list, description="an operator drives the robot by hand, the tree held meanwhile"
    )


class Span(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    from_: dict[str, Any] = Field(alias="from")
    to: dict[str, Any]
    seconds: float = Field(gt=0)


class CallExpectation(BaseModel):
    model_config = ConfigDict(extra="forbid")
    skill: str
    inputs: dict[str, Any] = Field(default_factory=dict)
    times: int | None = Field(default=None, ge=0)


class Expect(BaseModel):
    model_config = ConfigDict(extra="forbid")
    outcome: str | None = None
    states: list[str] | None = None
    states_in_order: list[str] | None = None
    calls: list[CallExpectation] = Field(default_factory=list)
    blackboard: dict[str, Any] = Field(default_factory=dict)
    counters: dict[str, Any] = Field(default_factory=dict, description="summary.json counters at the end")
    within: list[Span] = Field(default_factory=list)
    never: list[str] = Field(default_factory=list)


class ScenarioSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    mission: str
    description: str = ""
    seed: int | None = None
    until: float | None = Field(default=None, gt=0)
    mocks: dict[str, Annotated[list[Call], Field(min_length=1)] | Rule] = Field(default_factory=dict)
    mock_all: bool = False
    blackboard: dict[str, Any] = Field(default_factory=dict)
    events: list[Event] = Field(default_factory=list)
    expect: Expect = Field(default_factory=Expect)


# -- loading ------------------------------------------------------------------------------


@dataclass
class Scenario:
    path: Path
    spec: ScenarioSpec | None
    problems: list[Problem]
    loaded: Loaded

    @property
    def name(self) -> str:
        return self.path.stem

    @property
    def mission_path(self) -> Path:
        assert self.spec is not None
        return (self.path.parent / self.spec.mission).resolve()


def load_scenario(path: str | Path, registry: Registry | None = None) -> Scenario:
    """Load and check a scenario file; problems are located, never raised."""
    path = Path(path)
    loaded = load(path)
    problems = list(loaded.problems)
    if loaded.data is None:
        return Scenario(path, None, problems, loaded)

    def at(where: tuple[str | int, ...], message: str, hint: str = "") -> None:
        problems.append(Problem(loaded.locations.find(where), message, hint))

    try:
        spec = ScenarioSpec.model_validate(loaded.data)
    except ValidationError as exc:
        for error in exc.errors():
            raw = tuple(error["loc"])
            if raw[:1] == ("mocks",) and len(raw) > 2:
                # a mock is a list of calls or a rule: report only the branch the author wrote
                written = (
                    loaded.data.get("mocks", {}).get(raw[1]) if isinstance(loaded.data.get("mocks"), dict) else None
                )
                if str(raw[2]).startswith("list[") != isinstance(written, list):
                    continue
                raw = raw[:2] + raw[3:]
            loc = raw
            if error["type"] == "extra_forbidden":
                at(loc, f"unknown key {loc[-1]!r}")
            else:
                at(loc, f"{'.'.join(map(str, loc))}: {error['msg'].removeprefix('Value error, ')}")
        return Scenario(path, None, _unique(problems), loaded)
    registry = registry or Registry.default()
    mission = (path.parent / spec.mission).resolve()
    if not mission.exists():
        at(("mission",), f"mission file {spec.mission!r} does not exist", f"looked for {mission}")
    for name, script in spec.mocks.items():
        if name not in registry:
            at(("mocks", name), f"unknown skill {name!r}", did_you_mean(name, registry))
            continue
        real = registry.get(name)
        base: tuple[str | int, ...] = ("mocks", name)
        for index, call in enumerate(calls_of(script)):
            where = base + ((index,) if isinstance(script, list) else ("cycle", index) if script.cycle else ("always",))
            _check_call(real, call, where, at)
        if isinstance(script, Rule) and script.probability:
            for outcome in script.probability:
                if outcome not in real.all_outcomes:
                    at(
                        base + ("probability", outcome),
                        f"skill {name!r} has no outcome {outcome!r}",
                        "declared: " + ", ".join(sorted(real.all_outcomes)),
                    )
    facts = mission_facts(mission, registry) if mission.exists() else MissionFacts()
    check_against_mission(spec, facts, registry, at)
    for index, call in enumerate(spec.expect.calls):
        if call.skill not in registry:
            at(("expect", "calls", index, "skill"), f"unknown skill {call.skill!r}", did_you_mean(call.skill, registry))
        else:
            for port in call.inputs:
                if port not in registry.get(call.skill).inputs:
                    at(("expect", "calls", index, "inputs", port), f"skill {call.skill!r} has no input {port!r}")
    return Scenario(path, spec, _unique(problems), loaded)


def _check_call(real: type[Skill], call: Call, where: tuple[str | int, ...], at: Any) -> None:
    if call.outcome is not None and call.outcome not in real.all_outcomes:
        at(
            where + ("outcome",),
            f"skill {real.name!r} has no outcome {call.outcome!r}",
            did_you_mean(call.outcome, real.all_outcomes) or "declared: " + ", ".join(sorted(real.all_outcomes)),
        )
    for port in call.outputs:
        if port not in real.outputs:
            at(
                where + ("outputs", port),
                f"skill {real.name!r} has no output {port!r}",
                did_you_mean(port, real.outputs) or "declared: " + (", ".join(real.outputs) or "none"),
            )


def _unique(problems: list[Problem]) -> list[Problem]:
    return sorted({(p.location, p.message): p for p in problems}.values(), key=lambda p: (p.location, p.message))


# -- running and judging --------------------------------------------------------------------


@dataclass
class Result:
    scenario: Scenario
    passed: bool
    failures: list[str] = field(default_factory=list)
    folder: Path | None = None
    events: list[dict[str, Any]] = field(default_factory=list)

    def report(self) -> str:
        """What a failing scenario prints: each failed expectation, then where the run is."""
        lines = [f"scenario {self.scenario.path} failed:"]
        lines += self.failures
        if self.folder is not None:
            lines.append(f"run folder: {self.folder}")
        return "\n".join(lines)


class _BeforeTick:
    """The scenario's events and `never` conditions, before every tick (may raise StopRun)."""

    name = "scenario events"

    def __init__(self, hook: Callable[[RunSession], None]) -> None:
        self.before_tick = hook


def _drive_by_hand(session: RunSession, drives: list[Drive]) -> None:
    """As the operator drove: each command for its seconds, a tick period a step, then stopped."""
    period = session.clock.period
    for drive in drives:
        for _ in range(max(1, round(drive.seconds / period))):
            drive_one_step(session, drive.v, drive.w)
    hands = session.interfaces.get("drive")
    if hands is not None:
        hands.stop()


def run_scenario(scenario: Scenario, out: Path, registry: Registry | None = None) -> Result:
    if scenario.problems or scenario.spec is None:
        return Result(scenario, False, [str(p) for p in scenario.problems])
    spec = scenario.spec
    base = registry or Registry.default()
    mocked, names = Registry(), []
    for name in base:
        real = base.get(name)
        if name in spec.mocks:
            mocked.register(mock_of(real, spec.mocks[name]))
        elif spec.mock_all:
            mocked.register(mock_of(real, Rule(always=Call())))
        else:
            mocked.register(real)
            continue
        names.append(name)
    never = [compile_expression(c) for c in spec.expect.never]
    pending = sorted(spec.events, key=lambda e: e.t)

    def before_tick(session: RunSession) -> None:
        engine = session.engine
        assert engine is not None
        now = engine.clock.now()
        while pending and pending[0].t <= now + 1e-9:
            event = pending.pop(0)
            for key, value in event.set.items():
                engine.blackboard.set(key, value, writer="scenario")
            if event.gallery is not None:
                set_gallery(engine.interfaces["uploads"], up=event.gallery == "up")
            if event.estop:
                stop_everything(session)
            if event.teleop:
                _drive_by_hand(session, event.teleop)
        for condition in never:
            try:
                held = condition.test(engine.blackboard.get)
            except MissingKeyError:
                continue  # a key not written yet: the condition cannot hold
            except EvaluationError as exc:
                raise StopRun(
                    f"never-condition {condition.source!r} cannot be evaluated at t={now:g} s: "
                    + str(exc).removeprefix(f"{condition.source!r}: ")
                ) from None
            if held:
                raise StopRun(f"never-condition {condition.source!r} held at t={now:g} s")

    recorder = EventRecorder()
    try:
        result = run(
            scenario.mission_path,
            seed=spec.seed,
            until=spec.until,
            out=out,
            registry=mocked,
            blackboard=spec.blackboard,
            observers=[_BeforeTick(before_tick), recorder, _ScenarioBlock(scenario.path, names)],
        )
    except MissionInvalid as exc:
        return Result(scenario, False, ["the mission is invalid:", *(str(p) for p in exc.problems)])
    except RunError as exc:
        return Result(scenario, False, [f"the mission cannot run: {exc}"])
    events = recorder.events
    failures = list(_judge(spec.expect, result.summary, result.blackboard, result.reason, events))
    return Result(scenario, not failures, failures, result.folder, events)


class _ScenarioBlock:
    """summary.json's `scenario` block: the file and the skills it mocked (what a replay of this
    run must mock too)."""

    name = "scenario"

    def __init__(self, path: Path, mocked: list[str]) -> None:
        self.block = {"file": str(path), "mocked": sorted(mocked)}

    def finished(self, session: Any, result: Any) -> None:
        result.summary["scenario"] = self.block


def _judge(
    expect: Expect, summary: dict[str, Any], blackboard: dict[str, Any], reason: str, events: list[dict[str, Any]]
) -> Iterator[str]:
    if summary["outcome"] == "stopped_by_test":
        yield reason
    if expect.outcome is not None and summary["outcome"] != expect.outcome:
        yield f"outcome: expected {expect.outcome!r}, got {summary['outcome']!r}" + (f" ({reason})" if reason else "")
    actual = summary["states_visited"]
    if expect.states is not None and actual != expect.states:
        yield "states: expected (-) vs actual (+):\n" + _diff(expect.states, actual)
        yield _excerpt(events, _divergence(expect.states, actual))
    if expect.states_in_order is not None:
        missing = _first_missing(expect.states_in_order, actual)
        if missing is not None:
            yield (
                f"states_in_order: {expect.states_in_order[missing]!r} (expected #{missing + 1}) never came after "
                f"{expect.states_in_order[missing - 1]!r}"
                if missing
                else f"states_in_order: {expect.states_in_order[0]!r} was never entered"
            ) + f"\n  actual: {actual}"
    starts = [e for e in events if e["ev"] == "skill_start"]
    for call in expect.calls:
        matching = [e for e in starts if e["skill"] == call.skill and _partial(call.inputs, e["inputs"])]
        if call.times is not None and len(matching) != call.times:
            yield f"calls: {call.skill} {call.inputs or ''} expected {call.times} time(s), called {len(matching)}"
        elif call.times is None and not matching:
            seen = [e["inputs"] for e in starts if e["skill"] == call.skill]
            yield f"calls: {call.skill} was never called with {call.inputs}" + (
                f"; it was called with {seen[:5]}" if seen else "; it was never called"
            )
    for key, value in expect.blackboard.items():
        if key not in blackboard:
            yield f"blackboard: {key!r} was never written (expected {value!r})"
        elif blackboard[key] != value:
            yield f"blackboard: {key!r} expected {value!r}, got {blackboard[key]!r}"
    for key, value in expect.counters.items():
        if key not in summary["counters"]:
            yield f"counters: {key!r} is not a counter of the mission (its counters: {sorted(summary['counters'])})"
        elif summary["counters"][key] != value:
            yield f"counters: {key!r} expected {value!r}, got {summary['counters'][key]!r}"
    for span in expect.within:
        start = next((e for e in events if _matches(span.from_, e)), None)
        if start is None:
            yield f"within: no event matched from={span.from_}"
            continue
        end = next((e for e in events if e["t"] >= start["t"] and e is not start and _matches(span.to, e)), None)
        if end is None:
            yield f"within: after {span.from_} at t={start['t']:g} s, no event matched to={span.to}"
        elif end["t"] - start["t"] > span.seconds + 1e-9:
            yield (
                f"within: {span.to} came {end['t'] - start['t']:g} s after {span.from_} "
                f"(t={start['t']:g} s), more than {span.seconds:g} s"
            )


def _partial(expected: dict[str, Any], actual: dict[str, Any]) -> bool:
    return all(k in actual and actual[k] == v for k, v in expected.items())


def _matches(matcher: dict[str, Any], event: dict[str, Any]) -> bool:
    """A matcher names event fields; `state: X` means entering state X, named as in `states:`
    (its full path, `main/entertainer/goodbye`) or as its machine names it (`goodbye`)."""
    for key, value in matcher.items():
        if key == "state":
            if event["ev"] != "transition" or value not in (event["dest"], f"{event['machine']}/{event['dest']}"):
                return False
        elif event.get(key) != value:
            return False
    return True


def _first_missing(wanted: list[str], actual: list[str]) -> int | None:
    position = 0
    for index, state in enumerate(wanted):
        try:
            position = actual.index(state, position) + 1
        except ValueError:
            return index
    return None


def _diff(expected: list[str], actual: list[str]) -> str:
    return "\n".join("  " + line for line in difflib.ndiff(expected, actual) if not line.startswith("?"))


def _divergence(expected: list[str], actual: list[str]) -> int:
    for index, (a, b) in enumerate(zip(expected, actual, strict=False)):
        if a != b:
            return index
    return min(len(expected), len(actual))


def _excerpt(events: list[dict[str, Any]], index: int) -> str:
    """The trace around the transition where the state sequence first diverged."""
    transitions = [i for i, e in enumerate(events) if e["ev"] == "transition" and e["dest"]]
    if not transitions:
        return "trace: no state was entered"
    at = transitions[min(index, len(transitions) - 1)]
    shown = [e for e in events[max(0, at - 6) : at + 4] if e["ev"] not in ("tick", "tick_end")]
    return "trace around the first divergence:\n" + "\n".join("  " + json.dumps(e) for e in shown)


def location(scenario: Scenario) -> Location:
    assert scenario.loaded.locations.root is not None
    return scenario.loaded.locations.root
