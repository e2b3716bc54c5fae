"""Scenario tests: run a mission with mocked skills, scripted events and expectations.

A scenario file (YAML, usually `missions/scenarios/<mission>/<name>.yaml`)::

    mission: ../../hello.yaml          # relative to the scenario file
    seed: 7
    until: 60
    mocks:
      wait:                            # a script of calls, in order; the last one repeats
        - {outcome: success, duration: 2}
        - {outcome: failure, reason: "motor stalled"}
      log: {always: {outcome: success}}
      check: {cycle: [{outcome: success}, {outcome: failure}]}
      detect: {probability: {success: 0.7, no_crowd: 0.3}}   # seeded: same every run
    mock_all: false                    # true: every skill not listed succeeds at once
    blackboard: {battery_pct: 15}      # overrides of the mission's initial values
    events:
      - {t: 12, set: {estop: true}}
      - {t: 40, gallery: down}       # the run's own gallery goes down (and `up` brings it back)
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
declare is a located validation error, so trees and machines cannot tell the difference.
"""

from __future__ import annotations

import difflib
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from behaviors.blackboard import BlackboardError
from behaviors.engine import Engine
from behaviors.suggest import did_you_mean
from missions.gallery.service import set_gallery
from missions.loader import Loaded, Location, Problem, load
from missions.runner import MissionInvalid, RunError, StopRun, run
from missions.session.observers import EventRecorder
from skills.base import Outcome, Skill, SkillContext, SkillRun, type_name
from skills.expression import EvaluationError, ExpressionError, compile_expression
from skills.registry import Registry


class Call(BaseModel):
    """One scripted call of a mocked skill."""

    model_config = ConfigDict(extra="forbid")
    outcome: str | None = Field(default=None, description="default: the skill's success outcome")
    reason: str = ""
    outputs: dict[str, Any] = Field(default_factory=dict)
    duration: float = Field(default=0.0, ge=0, description="sim seconds RUNNING before the outcome")
    raises: str | None = Field(default=None, description="raise an error with this message instead")
    times: int = Field(default=1, ge=1, description="this call, this many times in a row")


class Rule(BaseModel):
    model_config = ConfigDict(extra="forbid")
    always: Call | None = None
    cycle: list[Call] | None = None
    probability: dict[str, float] | None = None

    @model_validator(mode="after")
    def _one(self) -> Rule:
        given = [k for k in ("always", "cycle", "probability") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("a rule is exactly one of always, cycle, probability")
        if self.cycle is not None and not self.cycle:
            raise ValueError("cycle needs at least one call")
        weights = self.probability
        if weights is not None and (not weights or any(p < 0 for p in weights.values()) or not sum(weights.values())):
            raise ValueError("probability maps outcomes to non-negative weights, not all zero")
        return self


class Event(BaseModel):
    model_config = ConfigDict(extra="forbid")
    t: float = Field(ge=0, description="sim seconds")
    set: dict[str, Any] = Field(default_factory=dict)
    gallery: Literal["down", "up"] | None = Field(
        default=None, description="take the run's own gallery down, or bring it back on the same port"
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


# -- mocks --------------------------------------------------------------------------------


def mock_of(real: type[Skill], script: list[Call] | Rule) -> type[Skill]:
    """A skill with ``real``'s contract whose runs follow ``script``.

    Calls are counted per mock class, across every node that uses the skill, in tick order:
    deterministic. A new class is made for every scenario run, so counts start at zero.
    """
    calls = {"n": 0}
    if isinstance(script, list):
        script = [call for call in script for _ in range(call.times)]
    elif script.cycle is not None:
        script = Rule(cycle=[call for call in script.cycle for _ in range(call.times)])

    def next_call(ctx: SkillContext) -> Call:
        n = calls["n"]
        calls["n"] += 1
        if isinstance(script, list):
            return script[min(n, len(script) - 1)]
        if script.always is not None:
            return script.always
        if script.cycle is not None:
            return script.cycle[n % len(script.cycle)]
        assert script.probability is not None
        pick, total = ctx.rng.random() * sum(script.probability.values()), 0.0
        for outcome, weight in script.probability.items():
            total += weight
            if pick < total:
                return Call(outcome=outcome)
        return Call(outcome=next(iter(script.probability)))

    def run(self: Skill, ctx: SkillContext, **inputs: Any) -> SkillRun:
        call = next_call(ctx)
        deadline = ctx.clock.now() + call.duration - 1e-9
        while ctx.clock.now() < deadline:
            yield
        if call.raises is not None:
            raise RuntimeError(call.raises)
        return Outcome(call.outcome or real.success_outcomes[0], call.reason, call.outputs)

    return type(
        f"Mock_{real.__name__}",
        (Skill,),
        {
            "name": real.name,
            "description": f"mock of {real.name}",
            "kind": real.kind,
            "inputs": real.inputs,
            "outputs": real.outputs,
            "outcomes": tuple(sorted(real.all_outcomes - {"success", "failure"})),
            "success_outcomes": real.success_outcomes,
            "Params": real.Params,
            "run": run,
            "__module__": __name__,
        },
    )


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
        calls = script if isinstance(script, list) else [script.always] if script.always else script.cycle or []
        base: tuple[str | int, ...] = ("mocks", name)
        for index, call in enumerate(calls):
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
    if mission.exists():
        _check_keys(spec, mission, registry, at)
    for index, call in enumerate(spec.expect.calls):
        if call.skill not in registry:
            at(("expect", "calls", index, "skill"), f"unknown skill {call.skill!r}", did_you_mean(call.skill, registry))
        else:
            for port in call.inputs:
                if port not in registry.get(call.skill).inputs:
                    at(("expect", "calls", index, "inputs", port), f"skill {call.skill!r} has no input {port!r}")
    for index, condition in enumerate(spec.expect.never):
        try:
            compile_expression(condition)
        except ExpressionError as exc:
            at(("expect", "never", index), str(exc))
    return Scenario(path, spec, _unique(problems), loaded)


def _check_keys(spec: ScenarioSpec, mission: Path, registry: Registry, at: Any) -> None:
    """Scenario keys must be keys the mission uses, of their declared types."""
    from missions.check import check, check_write

    checked = check(mission, registry)
    if checked.mission is None:
        return
    known = checked.keys_used | set(checked.key_types) | {k.strip("/") for k in checked.mission.blackboard}
    writes = [(("blackboard", key), key, value) for key, value in spec.blackboard.items()]
    for index, event in enumerate(spec.events):
        writes += [(("events", index, "set", key), key, value) for key, value in event.set.items()]
    for where, key, value in writes:
        rel, declared, problem = check_write(key, value, checked.key_types)
        if rel is None:
            at(where, problem)
        elif rel not in known:
            at(where, f"the mission never reads or writes {rel!r}", did_you_mean(rel, known))
        elif problem:
            at(where, f"{rel!r} is declared {type_name(declared)}: {problem}")


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


def run_scenario(scenario: Scenario, out: Path, registry: Registry | None = None) -> Result:
    if scenario.problems or scenario.spec is None:
        return Result(scenario, False, [str(p) for p in scenario.problems])
    spec = scenario.spec
    base = registry or Registry.default()
    mocked = Registry()
    for name in base:
        real = base.get(name)
        if name in spec.mocks:
            mocked.register(mock_of(real, spec.mocks[name]))
        elif spec.mock_all:
            mocked.register(mock_of(real, Rule(always=Call())))
        else:
            mocked.register(real)
    never = [compile_expression(c) for c in spec.expect.never]
    pending = sorted(spec.events, key=lambda e: e.t)

    def before_tick(engine: Engine) -> None:
        now = engine.clock.now()
        while pending and pending[0].t <= now + 1e-9:
            event = pending.pop(0)
            for key, value in event.set.items():
                engine.blackboard.set(key, value, writer="scenario")
            if event.gallery is not None:
                set_gallery(engine.interfaces["uploads"], up=event.gallery == "up")
        for condition in never:
            try:
                held = condition.test(engine.blackboard.get)
            except (BlackboardError, EvaluationError):
                continue  # a key not written yet: the condition cannot hold
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
            before_tick=before_tick,
            observers=[recorder],
        )
    except MissionInvalid as exc:
        return Result(scenario, False, ["the mission is invalid:", *(str(p) for p in exc.problems)])
    except RunError as exc:
        return Result(scenario, False, [f"the mission cannot run: {exc}"])
    events = recorder.events
    failures = list(_judge(spec.expect, result.summary, result.blackboard, result.reason, events))
    return Result(scenario, not failures, failures, result.folder, events)


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


# -- record and replay ----------------------------------------------------------------------

LONG_RUN_S = 1e6  # a call that was still running when the run ended keeps running in the replay


def from_trace(trace: Path, output: Path, mission: Path | None = None) -> dict[str, Any]:
    """A scenario replaying a recorded run: its mocks return the recorded skill outcomes, in the
    recorded order and after the recorded durations; it expects the recorded outcome, state
    sequence and number of calls per skill. ``summary.json`` beside the trace names the mission."""
    summary_path = trace.parent / "summary.json"
    summary = json.loads(summary_path.read_text(encoding="utf-8")) if summary_path.exists() else {}
    if summary.get("outcome") == "stopped_by_test":
        raise ValueError(
            f"{trace} was stopped by a scenario's never-condition: "
            "replay that scenario itself rather than a recording of it"
        )
    if mission is None:
        if "mission_file" not in summary:
            raise ValueError(f"no summary.json with the mission beside {trace}: name the mission with --mission")
        mission = Path(summary["mission_file"])
    calls: dict[str, list[dict[str, Any]]] = {}
    running: dict[str, dict[str, Any]] = {}
    events: list[dict[str, Any]] = []
    with trace.open(encoding="utf-8") as lines:
        for line in lines:
            event = json.loads(line)
            kind = event["ev"]
            if kind == "skill_start":
                call: dict[str, Any] = {"outcome": "success", "duration": LONG_RUN_S, "_t": event["t"]}
                calls.setdefault(event["skill"], []).append(call)
                running[event["node"]] = call
            elif kind in ("skill_outcome", "skill_cancel") and event["node"] in running:
                call = running.pop(event["node"])
                if kind == "skill_outcome":
                    call.update(outcome=event["outcome"], duration=round(event["t"] - call["_t"], 6))
                    if event["reason"]:
                        call["reason"] = event["reason"]
                    if event["outputs"]:
                        call["outputs"] = event["outputs"]
            elif kind == "bb_write" and event["writer"] == "scenario":
                events.append({"t": event["t"], "set": {event["key"]: event["new"]}})
    for skill, script in calls.items():
        compact: list[dict[str, Any]] = []
        for call in script:
            call.pop("_t")
            if call["duration"] == 0:
                del call["duration"]
            if compact and {k: v for k, v in compact[-1].items() if k != "times"} == call:
                compact[-1]["times"] = compact[-1].get("times", 1) + 1
            else:
                compact.append(call)
        calls[skill] = compact
    try:
        relative = Path(os.path.relpath(mission.resolve(), output.resolve().parent))
    except ValueError:  # another drive
        relative = mission.resolve()
    spec: dict[str, Any] = {"mission": relative.as_posix(), "description": f"replay of {trace}"}
    if "seed" in summary:
        spec["seed"] = summary["seed"]
    if summary.get("until"):
        spec["until"] = summary["until"]
    if summary.get("blackboard_overrides"):
        spec["blackboard"] = summary["blackboard_overrides"]
    spec["mocks"] = calls
    if events:
        spec["events"] = events
    expect: dict[str, Any] = {}
    if "outcome" in summary:
        expect["outcome"] = summary["outcome"]
    expect["states"] = summary.get("states_visited", [])
    expect["calls"] = [
        {"skill": skill, "times": sum(c.get("times", 1) for c in script)} for skill, script in sorted(calls.items())
    ]
    spec["expect"] = expect
    output.write_text(yaml.safe_dump(spec, sort_keys=False, width=100), encoding="utf-8")
    return spec
