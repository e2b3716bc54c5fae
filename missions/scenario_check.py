"""A scenario checked against its mission: every key, state, counter and skill it names must be one
the mission has, so that no event, mock write or expectation silently does nothing and no check
silently passes (``never: ["lops >= 1"]`` with a misspelt key would never hold).

The mission's keys are those ``missions/check.py`` finds: declared (``keys:``), initialised
(``blackboard:``) and read or written by what the mission runs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from botstage.behaviors.blackboard import BlackboardError, normalise_key
from botstage.behaviors.render import Item
from botstage.behaviors.trace import FIELDS
from botstage.missions.check import check, check_write, describe_part
from botstage.missions.mocks import calls_of
from botstage.robots.suggest import did_you_mean
from botstage.skills.base import type_name
from botstage.skills.expression import ExpressionError, compile_expression
from botstage.skills.registry import Registry

if TYPE_CHECKING:
    from botstage.missions.mocks import Script
    from botstage.missions.scenario import ScenarioSpec

At = Callable[..., None]  # at(where, message, hint="")
Where = tuple[str | int, ...]

# what a `within` matcher may name: an event's fields, and `state` (entering it)
MATCHER_FIELDS = frozenset({"tick", "t", "ev", "state", *(f for fields in FIELDS.values() for f in fields)})


@dataclass
class MissionFacts:
    """What a valid mission has, as a scenario names it."""

    keys: set[str] = field(default_factory=set)
    key_types: dict[str, Any] = field(default_factory=dict)
    counters: list[str] = field(default_factory=list)
    states: list[str] = field(default_factory=list)  # as `states:` names them (summary.json's states_visited)
    state_names: set[str] = field(default_factory=set)  # what a `within` matcher's `state:` takes
    valid: bool = False


def mission_facts(mission: Path, registry: Registry) -> MissionFacts:
    checked = check(mission, registry)
    facts = MissionFacts(key_types=dict(checked.key_types))
    if checked.mission is None or not checked.ok:
        return facts  # the run reports the mission's own problems; names are checked against a valid one
    initialised = set()
    for key in checked.mission.blackboard:
        try:
            initialised.add(normalise_key(key))
        except BlackboardError:
            continue
    facts.keys = checked.keys_used | set(checked.key_types) | initialised
    facts.counters = list(checked.mission.counters)
    for machine, state in _states(describe_part(checked)):
        dest = state[len(machine) + 1 :]
        facts.states.append(dest if machine == checked.mission.name else state)
        facts.state_names |= {dest, state}
    facts.valid = True
    return facts


def _states(item: Item, machine: str = "") -> Iterator[tuple[str, str]]:
    """(top machine path, state path) of every state under ``item``, and of every machine outcome
    (a machine's run ends by entering one: `stopped` is among the states a run visits)."""
    if item.kind == "machine" and item.machine:
        machine = item.machine
    if item.kind in ("state", "outcome") and machine:
        yield machine, item.path
    for child in item.children:
        yield from _states(child, machine)


def check_against_mission(spec: ScenarioSpec, facts: MissionFacts, registry: Registry, at: At) -> None:
    """Every name the scenario uses, checked against the mission; each problem located."""
    writes: list[tuple[Where, str, Any]] = [(("blackboard", k), k, v) for k, v in spec.blackboard.items()]
    for index, event in enumerate(spec.events):
        writes += [(("events", index, "set", k), k, v) for k, v in event.set.items()]
    for name, script in spec.mocks.items():
        if name in registry:
            writes += list(_mock_writes(name, script, registry, at))
    for where, key, value in writes:
        _check_write(where, key, value, facts, at)
    expect = spec.expect
    for index, condition in enumerate(expect.never):
        _check_condition(("expect", "never", index), condition, facts, at)
    for key in expect.blackboard:
        _check_key(("expect", "blackboard", key), key, facts, at)
    if facts.valid:
        for key in expect.counters:
            if key not in facts.counters:
                at(
                    ("expect", "counters", key),
                    f"{key!r} is not a counter of the mission",
                    did_you_mean(key, facts.counters) or "its counters: " + (", ".join(facts.counters) or "none"),
                )
        for field_name in ("states", "states_in_order"):
            for index, state in enumerate(getattr(expect, field_name) or []):
                _check_state(("expect", field_name, index), state, facts.states, at)
    for index, span in enumerate(expect.within):
        for end, matcher in (("from", span.from_), ("to", span.to)):
            _check_matcher(("expect", "within", index, end), matcher, facts, registry, at)


def _mock_writes(name: str, script: Script, registry: Registry, at: At) -> Iterator[tuple[Where, str, Any]]:
    """The writes a mock's calls make; a skill without key ports of its own writes nothing."""
    real = registry.get(name)
    own = [port for port, spec in real.inputs.items() if spec.names_key == "write"]
    base: Where = ("mocks", name)
    for index, call in enumerate(calls_of(script)):
        where = base + ((index,) if isinstance(script, list) else ("cycle", index) if script.cycle else ("always",))
        for number, write in enumerate(call.writes):
            if not own:
                outputs = ", ".join(real.outputs)
                at(
                    where + ("writes", number),
                    f"skill {name!r} writes no blackboard key itself: it has no key port",
                    f"script its outputs instead ({outputs})" if outputs else "",
                )
                break
            for key, value in write.set.items():
                yield where + ("writes", number, "set", key), key, value


def _check_write(where: Where, key: str, value: Any, facts: MissionFacts, at: At) -> None:
    rel, declared, problem = check_write(key, value, facts.key_types)
    if rel is None:
        at(where, problem)
    elif facts.valid and rel not in facts.keys:
        at(where, f"the mission never reads or writes {rel!r}", did_you_mean(rel, facts.keys))
    elif problem:
        at(where, f"{rel!r} is declared {type_name(declared)}: {problem}")


def _check_key(where: Where, key: str, facts: MissionFacts, at: At) -> None:
    try:
        rel = normalise_key(key)
    except BlackboardError as exc:
        at(where, str(exc))
        return
    if facts.valid and rel not in facts.keys:
        at(where, f"the mission never declares, initialises or writes {rel!r}", did_you_mean(rel, facts.keys))


def _check_condition(where: Where, condition: str, facts: MissionFacts, at: At) -> None:
    try:
        expression = compile_expression(condition)
    except ExpressionError as exc:
        at(where, str(exc))
        return
    if not facts.valid:
        return
    for key in sorted(expression.keys - facts.keys):
        at(
            where,
            f"unknown blackboard key {key!r} in {condition.strip()!r}: "
            "the mission never declares, initialises or writes it",
            did_you_mean(key, facts.keys),
        )


def _check_state(where: Where, state: Any, known: Iterable[str], at: At) -> None:
    known = list(known)
    if state not in known:
        at(where, f"the mission has no state {state!r}", did_you_mean(str(state), known) or _listed(known))


def _check_matcher(where: Where, matcher: dict[str, Any], facts: MissionFacts, registry: Registry, at: At) -> None:
    if not matcher:
        at(where, "an empty matcher matches every event", "name the event, e.g. {state: NAME}")
    for name, value in matcher.items():
        here = where + (name,)
        if name not in MATCHER_FIELDS:
            at(here, f"events have no field {name!r}", did_you_mean(name, MATCHER_FIELDS))
        elif name == "ev" and value not in FIELDS:
            at(here, f"there is no event {value!r}", did_you_mean(str(value), FIELDS) or _listed(FIELDS))
        elif name == "skill" and value not in registry:
            at(here, f"unknown skill {value!r}", did_you_mean(str(value), registry))
        elif name == "key":
            _check_key(here, str(value), facts, at)
        elif name == "state" and facts.valid:
            _check_state(here, value, sorted(facts.state_names), at)


def _listed(names: Iterable[str]) -> str:
    shown = sorted(names)
    return "known: " + ", ".join(shown[:12]) + (", ..." if len(shown) > 12 else "") if shown else ""
