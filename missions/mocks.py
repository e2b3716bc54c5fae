"""Scripted mocks of skills for scenario tests: a call script, and a skill class with the real
skill's contract that plays it.

A call says how one run of the mocked skill goes: its outcome, reason and outputs after a
duration, or an error it raises, or that it runs until the engine cancels it; and the blackboard
writes it makes on the way (through the key ports the node binds, as the real skill would).
Recorded runs become such scripts (``missions/replay.py``), so a mock must be able to do all
that a real call did.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from botstage.skills.base import Outcome, Skill, SkillContext, SkillRun

# Durations and write times are compared to the microsecond, as the trace records times: a call
# recorded as lasting 0.714286 s replays for exactly as many ticks, whatever the tick rate.
DIGITS = 6
_EPSILON = 1e-9


class Write(BaseModel):
    """Blackboard writes a call makes ``after`` seconds into its run."""

    model_config = ConfigDict(extra="forbid")
    after: float = Field(default=0.0, ge=0, description="seconds after the call started")
    set: dict[str, Any] = Field(min_length=1, description="keys and the values written to them, in order")


class Call(BaseModel):
    """One scripted call of a mocked skill."""

    model_config = ConfigDict(extra="forbid")
    outcome: str | None = Field(default=None, description="default: the skill's success outcome")
    reason: str = ""
    outputs: dict[str, Any] = Field(default_factory=dict)
    duration: float = Field(default=0.0, ge=0, description="sim seconds RUNNING before the outcome")
    raises: str | None = Field(default=None, description="raise an error with this message instead")
    until_cancelled: bool = Field(
        default=False, description="stay RUNNING until the engine cancels the call (no outcome of its own)"
    )
    writes: list[Write] = Field(
        default_factory=list, description="blackboard writes on the way, through the node's key ports"
    )
    times: int = Field(default=1, ge=1, description="this call, this many times in a row")

    @model_validator(mode="after")
    def _consistent(self) -> Call:
        if self.until_cancelled:
            ending = [k for k in ("outcome", "reason", "outputs", "duration", "raises") if k in self.model_fields_set]
            if ending:
                raise ValueError(
                    f"a call that runs until cancelled has no {', '.join(ending)}: the engine ends it, not the mock"
                )
        else:
            late = [w.after for w in self.writes if round(w.after - self.duration, DIGITS) > 0]
            if late:
                raise ValueError(f"a write after {late[0]:g} s never happens: the call ends after {self.duration:g} s")
        return self


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


Script = list[Call] | Rule


def calls_of(script: Script) -> list[Call]:
    """The calls a script names (none for a probability rule)."""
    if isinstance(script, list):
        return script
    if script.always is not None:
        return [script.always]
    return list(script.cycle or [])


def _stamp(t: float) -> float:
    return round(t, DIGITS)


def play(call: Call, ctx: SkillContext, success: str) -> SkillRun:
    """One scripted call: its writes when they fall due, then its outcome (or RUNNING until cancelled).

    Writes due at the tick the call is cancelled are made as it is cancelled: the real call may
    have made them in its ``finally``, when the node was no longer ticked.
    """
    start = _stamp(ctx.clock.now())
    pending = deque(sorted(call.writes, key=lambda w: w.after))

    def elapsed() -> float:
        return round(_stamp(ctx.clock.now()) - start, DIGITS)

    def write_due() -> None:
        while pending and pending[0].after <= elapsed() + _EPSILON:
            for key, value in pending.popleft().set.items():
                ctx.blackboard.set(key, value)

    ended = False
    try:
        write_due()
        while call.until_cancelled or elapsed() < call.duration - _EPSILON:
            yield
            write_due()
        ended = True
    finally:
        if not ended:
            write_due()
    if call.raises is not None:
        raise RuntimeError(call.raises)
    return Outcome(call.outcome or success, call.reason, call.outputs)


def mock_of(real: type[Skill], script: Script) -> type[Skill]:
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
        return (yield from play(next_call(ctx), ctx, real.success_outcomes[0]))

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
