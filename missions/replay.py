"""Record and replay: a scenario that replays a recorded run (``botstage scenario from-trace``).

Every call of a skill that met the world (drove, listened, looked, uploaded) becomes a mock call
that does what the recorded call did: the same outcome, reason and outputs after the same time,
the same blackboard writes at the same moments, or, for a call the run cancelled, RUNNING until
the engine cancels it again. Skills whose work is blackboard bookkeeping (``BOOKKEEPING``) run
for real: given the same blackboard and clock they do the same, and a replay then still tests
the mission's own logic (a changed condition, a counter written elsewhere) rather than replaying
its past. The replay expects the run's outcome, its states in order, its calls per skill and its
counters.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from botstage.behaviors.blackboard import BlackboardError, normalise_key
from botstage.missions.steering import ESTOP, TELEOP_ENDED, TeleopStretch, read_teleop_note
from botstage.skills.base import MISSING, Skill, check_type
from botstage.skills.registry import Registry

# Built-in skills that only read and write the blackboard and read the clock: they run for real in
# a replay, unless the recorded run was a scenario that mocked them.
BOOKKEEPING = frozenset({"check", "count", "log", "set", "wait", "wait_for"})
# Writers of blackboard writes that come from outside the mission (a scenario's events): replayed as events.
OPERATOR = "monitor"  # the node (and writer) of an operator's actions in the trace
EXTERNAL_WRITERS = frozenset({"scenario", "mission", OPERATOR})
# How a run that the operator stopped is replayed: up to the tick it was stopped at.
INTERRUPTED = "interrupted"


@dataclass
class _Open:
    """A mocked call still running at this point of the trace."""

    skill: type[Skill]
    t: float
    own_keys: frozenset[str]  # the keys its key ports name: what it may write itself
    script: dict[str, Any]  # its entry in the skill's script, filled when it ends
    writes: list[tuple[int, float, str, Any]] = field(default_factory=list)


@dataclass
class _Recording:
    calls: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    starts: dict[str, int] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    entered: list[tuple[str, str]] = field(default_factory=list)
    written: set[str] = field(default_factory=set)  # every key the run wrote, whoever wrote it
    teleop: TeleopStretch | None = None  # a stretch of driving by hand under way


class RunSummary(BaseModel):
    """What a replay takes from the run's summary.json (the rest is ignored)."""

    model_config = ConfigDict(extra="ignore")
    mission: str = ""
    mission_file: str | None = None
    seed: int | None = None
    until: float | None = None
    outcome: str | None = None
    ticks: int | None = None
    sim_time_s: float | None = None
    blackboard_overrides: dict[str, Any] = Field(default_factory=dict)
    counters: dict[str, Any] = Field(default_factory=dict)
    scenario: dict[str, Any] = Field(default_factory=dict)  # a scenario's run: {file, mocked}

    @property
    def mocked(self) -> set[str]:
        names = self.scenario.get("mocked", [])
        return {n for n in names if isinstance(n, str)} if isinstance(names, list) else set()


def read_summary(trace: Path) -> RunSummary:
    """The summary.json beside a trace (an empty one if there is none)."""
    path = trace.parent / "summary.json"
    if not path.exists():
        return RunSummary()
    try:
        return RunSummary.model_validate(json.loads(path.read_text(encoding="utf-8")))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a run's summary ({exc})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "the file"
        raise ValueError(f"{path}: not a run's summary ({where}: {first['msg']})") from None


def from_trace(
    trace: Path, output: Path, mission: Path | None = None, registry: Registry | None = None
) -> dict[str, Any]:
    """Write a scenario replaying a recorded run to ``output`` and return it.

    ``summary.json`` beside the trace names the mission, seed, time limit, blackboard overrides
    and, for a scenario's run, which skills it mocked. Raises ``ValueError`` for a trace that
    cannot be replayed (and ``OSError`` when files cannot be read or written).
    """
    summary = read_summary(trace)
    if summary.outcome == "stopped_by_test":
        raise ValueError(
            f"{trace} was stopped by a scenario's never-condition: "
            "replay that scenario itself rather than a recording of it"
        )
    if mission is None:
        if summary.mission_file is None:
            raise ValueError(f"no summary.json with the mission beside {trace}: name the mission with --mission")
        mission = Path(summary.mission_file)
    registry = registry or Registry.default()
    real = {name for name in BOOKKEEPING - summary.mocked if name in registry}
    interrupted = summary.outcome == INTERRUPTED
    name, key_types = _mission(mission, registry)
    recording = _read(trace, registry, real, key_types, summary.ticks if interrupted else None)
    spec = _spec(summary, recording, summary.mission or name, interrupted)
    spec = {"mission": _relative(mission, output).as_posix(), "description": f"replay of {trace}", **spec}
    output.write_text(yaml.safe_dump(spec, sort_keys=False, width=100, allow_unicode=True), encoding="utf-8")
    return spec


def _spec(summary: RunSummary, recording: _Recording, root: str, interrupted: bool) -> dict[str, Any]:
    """The scenario's settings, mocks, events and expectations (a stopped run ends where it stopped)."""
    spec: dict[str, Any] = {}
    if summary.seed is not None:
        spec["seed"] = summary.seed
    until = summary.sim_time_s if interrupted else summary.until
    if until:
        spec["until"] = until
    if summary.blackboard_overrides:
        spec["blackboard"] = summary.blackboard_overrides
    spec["mocks"] = {skill: _compact(script) for skill, script in recording.calls.items()}
    if recording.events:
        spec["events"] = recording.events
    expect: dict[str, Any] = {}
    if summary.outcome is not None:
        expect["outcome"] = "time_limit" if interrupted else summary.outcome
    expect["states"] = [dest if machine == root else f"{machine}/{dest}" for machine, dest in recording.entered]
    expect["calls"] = [{"skill": skill, "times": n} for skill, n in sorted(recording.starts.items())]
    # counters the blackboard held (the outbox's figures fill the others, and uploads are mocked)
    counters = {k: v for k, v in summary.counters.items() if k in recording.written}
    if counters and not interrupted:
        expect["counters"] = counters
    spec["expect"] = expect
    return spec


def _read(
    trace: Path, registry: Registry, real: set[str], key_types: dict[str, Any], last_tick: int | None
) -> _Recording:
    """The mocked calls, outside writes, skill starts and states entered, from the trace's lines."""
    recording = _Recording()
    running: dict[str, _Open] = {}
    with trace.open(encoding="utf-8") as lines:
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                event = json.loads(line)
                kind = event["ev"]
                if last_tick is not None and event["tick"] >= last_tick:
                    break
                _take(event, kind, recording, running, registry, real, key_types)
            except (json.JSONDecodeError, KeyError, TypeError, AttributeError) as exc:
                raise ValueError(f"{trace}:{number}: not a trace event ({type(exc).__name__}: {exc})") from None
    for call in running.values():  # still running when the trace ends: it ran until cancelled
        _cancelled(call, key_types)
    return recording


def _take(
    event: dict[str, Any],
    kind: str,
    recording: _Recording,
    running: dict[str, _Open],
    registry: Registry,
    real: set[str],
    key_types: dict[str, Any],
) -> None:
    if kind == "skill_start":
        name = event["skill"]
        recording.starts[name] = recording.starts.get(name, 0) + 1
        if name in real:
            return
        if name not in registry:
            raise ValueError(f"the run called skill {name!r}, which is not installed here")
        skill = registry.get(name)
        script: dict[str, Any] = {}
        recording.calls.setdefault(name, []).append(script)
        running[event["node"]] = _Open(skill, event["t"], _own_keys(skill, event["inputs"]), script)
    elif kind == "bb_write":
        recording.written.add(event["key"])
        call = running.get(event["writer"])
        if call is not None:
            call.writes.append((event["tick"], event["t"], event["key"], event["new"]))
        elif event["writer"] in EXTERNAL_WRITERS:
            recording.events.append(
                {"t": event["t"], "set": {event["key"]: _restored(key_types, event["key"], event["new"])}}
            )
    elif kind == "skill_outcome" and event["node"] in running:
        _ended(running.pop(event["node"]), event, key_types)
    elif kind == "skill_cancel" and event["node"] in running:
        _cancelled(running.pop(event["node"]), key_types)
    elif kind == "transition" and event["dest"]:
        recording.entered.append((event["machine"], event["dest"]))
    elif kind == "log" and event["node"] == OPERATOR:
        _steered(event, recording)


def _steered(event: dict[str, Any], recording: _Recording) -> None:
    """The operator's e-stop and driving by hand (``missions/steering.py``) as scenario events."""
    message, t = event["message"], event["t"]
    command = read_teleop_note(message)
    if message == ESTOP:
        recording.events.append({"t": t, "estop": True})
    elif command is not None and recording.teleop is None:
        recording.teleop = TeleopStretch.begin(t, *command)
    elif command is not None and recording.teleop is not None:
        recording.teleop.change(t, *command)
    elif message == TELEOP_ENDED and recording.teleop is not None:
        stretch, recording.teleop = recording.teleop, None
        stretch.end(t)
        if stretch.commands:
            drives = [{"v": v, "w": w, "seconds": seconds} for v, w, seconds in stretch.commands]
            recording.events.append({"t": stretch.start, "teleop": drives})


def _ended(call: _Open, event: dict[str, Any], key_types: dict[str, Any]) -> None:
    """A call that returned: its own writes (its outputs' writes come again from its outputs)."""
    own = [w for w in call.writes if w[2] in call.own_keys or w[0] != event["tick"]]
    script = call.script
    script["outcome"] = event["outcome"]
    if event["reason"]:
        script["reason"] = event["reason"]
    if event["outputs"]:
        ports = call.skill.outputs
        script["outputs"] = {
            port: _restored({port: ports[port].type} if port in ports else {}, port, value)
            for port, value in event["outputs"].items()
        }
    duration = round(event["t"] - call.t, 6)
    if duration:
        script["duration"] = duration
    _add_writes(script, call, own, key_types)


def _cancelled(call: _Open, key_types: dict[str, Any]) -> None:
    call.script["until_cancelled"] = True
    _add_writes(call.script, call, call.writes, key_types)


def _add_writes(
    script: dict[str, Any], call: _Open, writes: list[tuple[int, float, str, Any]], key_types: dict[str, Any]
) -> None:
    """Writes at the same moment share one entry, in order (a key written twice starts a new one)."""
    entries: list[dict[str, Any]] = []
    for _tick, t, key, value in writes:
        after = round(t - call.t, 6)
        last = entries[-1] if entries else None
        if last is None or last.get("after", 0.0) != after or key in last["set"]:
            last = {"after": after, "set": {}} if after else {"set": {}}
            entries.append(last)
        last["set"][key] = _restored(key_types, key, value)
    if entries:
        script["writes"] = entries


def _own_keys(skill: type[Skill], inputs: dict[str, Any]) -> frozenset[str]:
    keys = set()
    for name, port in skill.inputs.items():
        value = inputs.get(name, port.default)
        if port.names_key == "write" and value is not MISSING and isinstance(value, str):
            try:
                keys.add(normalise_key(value))
            except BlackboardError:
                continue
    return frozenset(keys)


def _restored(types: dict[str, Any], name: str, value: Any) -> Any:
    """A value as the trace wrote it (JSON), read back as its declared type where JSON lost it
    (a float that was not finite, written as 'inf' or 'nan')."""
    tp = types.get(name)
    if tp is None or not isinstance(value, str):
        return value
    try:
        check_type(tp, value)
        return value
    except TypeError:
        pass
    try:
        restored = TypeAdapter(tp).validate_python(value)
    except ValidationError:
        return value
    return restored if isinstance(restored, float) else value


def _mission(mission: Path, registry: Registry) -> tuple[str, dict[str, Any]]:
    """The mission's name and declared key types (none if it cannot be checked now)."""
    from botstage.missions.check import check

    if not mission.is_file():
        return mission.stem, {}
    checked = check(mission, registry)
    name = checked.mission.name if checked.mission is not None else mission.stem
    return name, checked.key_types


def _compact(script: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Consecutive identical calls as one with ``times``."""
    compact: list[dict[str, Any]] = []
    for call in script:
        if compact and {k: v for k, v in compact[-1].items() if k != "times"} == call:
            compact[-1]["times"] = compact[-1].get("times", 1) + 1
        else:
            compact.append(call)
    return compact


def _relative(mission: Path, output: Path) -> Path:
    try:
        return Path(os.path.relpath(mission.resolve(), output.resolve().parent))
    except ValueError:  # another drive
        return mission.resolve()
