"""One tick of a remote skill: what the mission sends and what the host answers.

The fields are those of ``botstage_msgs/srv/SkillTick`` (robots/ros2/msg), kept here as plain
dataclasses so the host and the proxy are tested without a network. Time is a float64 of the
mission's clock, not a ROS Time: rounding it to nanoseconds would hand the skill a different
``now()`` than a local run and the runs would drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from robots.remote import values
from skills.remote import rng


class Step(IntEnum):
    """What a request asks of the host."""

    START = 0  # begin the call (its first step): inputs, parameters and the node's keys travel
    STEP = 1  # advance it one tick
    CANCEL = 2  # close it now (its ``finally`` runs); the reply carries its last log lines


class State(IntEnum):
    """Where the call is after the request."""

    RUNNING = 0
    ENDED = 1  # the reply holds the outcome
    CANCELLED = 2
    UNKNOWN = 3  # the host has no such call (it restarted, or the call ended long ago)


@dataclass(frozen=True)
class Call:
    """What a START carries besides the tick: the run of one node."""

    skill: str
    node: str
    inputs: dict[str, Any]
    params: dict[str, Any]
    rng_state: tuple[Any, ...] | None = None  # the node's random.Random state, which persists across calls
    reads: frozenset[str] = frozenset()
    writes: frozenset[str] = frozenset()

    def to_json(self) -> str:
        return values.dumps(
            {
                "inputs": self.inputs,
                "params": self.params,
                "reads": sorted(self.reads),
                "writes": sorted(self.writes),
            },
            "the call",
        )

    @classmethod
    def from_json(cls, skill: str, node: str, text: str, rng_state: tuple[Any, ...] | None = None) -> Call:
        data = values.loads(text, "the call")
        try:
            return cls(
                skill,
                node,
                dict(data["inputs"]),
                dict(data["params"]),
                rng_state,
                frozenset(data["reads"]),
                frozenset(data["writes"]),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise values.ValueCodecError(f"the call: missing or malformed field {error}") from None


def _packed(state: tuple[Any, ...] | None) -> np.ndarray:
    """The state as a ``uint8[]`` field holds it (rosbags takes numpy arrays); empty for none."""
    return np.frombuffer(b"" if state is None else rng.pack(state), np.uint8)


def _unpacked(data: Any) -> tuple[Any, ...] | None:
    """The state from a message's ``uint8[]`` (a numpy array) or bytes; None when empty."""
    packed = bytes(data)
    if not packed:
        return None
    try:
        return rng.unpack(packed)
    except ValueError as error:
        raise values.ValueCodecError(f"the random state: {error}") from None


@dataclass(frozen=True)
class TickRequest:
    call_id: str  # unique per call (a goal id): ticks of one node's run share it
    step: Step
    time: float  # the mission clock's now() for this tick
    ticks: int  # the mission clock's ticks completed
    period: float
    simulated: bool
    call: Call | None = None  # with START only
    blackboard: dict[str, Any] = field(default_factory=dict)  # the node's readable keys that exist
    reason: str = ""  # with CANCEL: why (the trace already says it; the host logs it)


@dataclass(frozen=True)
class TickReply:
    state: State
    outcome: str = ""
    reason: str = ""
    outputs: dict[str, Any] = field(default_factory=dict)
    # ("log", level, message) and ("set", key, value), in the order the skill made them
    events: tuple[tuple[str, str, Any], ...] = ()
    rng_state: tuple[Any, ...] | None = None  # when the call ended having drawn from the node's generator


def request_fields(request: TickRequest) -> dict[str, Any]:
    """The request as the fields of ``SkillTick``'s request (plain values and JSON text)."""
    call = request.call
    return {
        "call_id": request.call_id,
        "step": int(request.step),
        "time": request.time,
        "ticks": request.ticks,
        "period": request.period,
        "simulated": request.simulated,
        "skill": call.skill if call else "",
        "node": call.node if call else "",
        "call_json": call.to_json() if call else "",
        "rng": _packed(call.rng_state if call else None),
        "blackboard_json": values.dumps(request.blackboard, "the blackboard"),
        "reason": request.reason,
    }


def request_of(fields: Any) -> TickRequest:
    """A request from ``SkillTick``'s request fields (a message or a mapping); ValueError if malformed."""
    get = fields.get if isinstance(fields, dict) else lambda name: getattr(fields, name)
    try:
        step = Step(int(get("step")))
    except ValueError:
        raise values.ValueCodecError(f"step {get('step')!r} is not one of {[s.name for s in Step]}") from None
    call_json = str(get("call_json"))
    call = Call.from_json(str(get("skill")), str(get("node")), call_json, _unpacked(get("rng"))) if call_json else None
    board = values.loads(str(get("blackboard_json")), "the blackboard") if get("blackboard_json") else {}
    if not isinstance(board, dict):
        raise values.ValueCodecError("the blackboard: not a mapping of keys to values")
    return TickRequest(
        str(get("call_id")),
        step,
        float(get("time")),
        int(get("ticks")),
        float(get("period")),
        bool(get("simulated")),
        call,
        board,
        str(get("reason")),
    )


def reply_fields(reply: TickReply) -> dict[str, Any]:
    """The reply as the fields of ``SkillTick``'s response."""
    return {
        "state": int(reply.state),
        "outcome": reply.outcome,
        "reason": reply.reason,
        "outputs_json": values.dumps(reply.outputs, "the outputs") if reply.outputs else "",
        "events_json": values.dumps(list(reply.events), "the events") if reply.events else "",
        "rng": _packed(reply.rng_state),
    }


def reply_of(fields: Any) -> TickReply:
    """A reply from ``SkillTick``'s response fields; ValueError if malformed."""
    get = fields.get if isinstance(fields, dict) else lambda name: getattr(fields, name)
    try:
        state = State(int(get("state")))
    except ValueError:
        raise values.ValueCodecError(f"state {get('state')!r} is not one of {[s.name for s in State]}") from None
    outputs = values.loads(get("outputs_json"), "the outputs") if get("outputs_json") else {}
    events = values.loads(get("events_json"), "the events") if get("events_json") else []
    drawn = _unpacked(get("rng"))
    if not isinstance(outputs, dict) or not isinstance(events, list):
        raise values.ValueCodecError("a reply's outputs must be a mapping and its events a list")
    return TickReply(state, str(get("outcome")), str(get("reason")), outputs, tuple(tuple(e) for e in events), drawn)


class DirectLink:
    """A link to a host in this process, through the same fields as the wire: for tests and benches."""

    def __init__(self, host: Any, remote: str = "local") -> None:
        self.host, self.remote = host, remote

    def tick(self, request: TickRequest) -> TickReply:
        return reply_of(reply_fields(self.host.handle(request_of(request_fields(request)))))
