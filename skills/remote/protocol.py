"""One tick of a remote skill: what the mission sends and what the host answers.

The fields are those of ``botstage_msgs/srv/SkillTick`` (robots/ros2/msg), kept here as plain
dataclasses so the host and the proxy are tested without a network. Time is a float64 of the
mission's clock, not a ROS Time: rounding it to nanoseconds would hand the skill a different
``now()`` than a local run and the runs would drift apart.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from botstage.robots.remote import values
from botstage.skills.remote import rng


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
    # the node's random.Random state, which persists across calls; as the wire's packed bytes on a
    # host (rng.LazyRandom unpacks them only if the skill draws)
    rng_state: tuple[Any, ...] | bytes | None = None
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
    def from_json(cls, skill: str, node: str, text: str, rng_state: tuple[Any, ...] | bytes | None = None) -> Call:
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


_NO_STATE = np.frombuffer(b"", np.uint8)


def _packed(state: tuple[Any, ...] | bytes | None) -> np.ndarray:
    """The state as a ``uint8[]`` field holds it (rosbags takes numpy arrays); empty for none."""
    if state is None:
        return _NO_STATE
    return np.frombuffer(state if isinstance(state, bytes) else rng.pack(state), np.uint8)


def _state(data: Any, read: Callable[[bytes], Any]) -> Any:
    """``read`` of the packed state in a message's ``uint8[]`` (a numpy array) or bytes; None when empty."""
    if not len(data):  # no state travelled (a host's reply when the skill did not draw): the common case
        return None
    try:
        return read(bytes(data))
    except ValueError as error:
        raise values.ValueCodecError(f"the random state: {error}") from None


def _checked(data: Any) -> bytes | None:
    """The packed state, its shape checked (a host unpacks it only if the skill draws)."""
    return _state(data, rng.check)


def _unpacked(data: Any) -> tuple[Any, ...] | None:
    """The state, unpacked."""
    return _state(data, rng.unpack)


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
    # whether the host's process has after-tick work (set by that process; True when unknown)
    pending_after_tick: bool = True


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
        "blackboard_json": values.dumps(request.blackboard, "the blackboard") if request.blackboard else "",
        "reason": request.reason,
    }


class _Mapped:
    """A mapping's items as attributes (None when missing): the decoders read messages and mappings alike."""

    __slots__ = ("_data",)

    def __init__(self, data: dict[str, Any]) -> None:
        self._data = data

    def __getattr__(self, name: str) -> Any:
        return self._data.get(name)


_STEPS = {int(step): step for step in Step}
_STATES = {int(state): state for state in State}


def request_of(fields: Any) -> TickRequest:
    """A request from ``SkillTick``'s request fields (a message or a mapping); ValueError if malformed."""
    f = _Mapped(fields) if isinstance(fields, dict) else fields  # a message's fields are read directly
    step = _STEPS.get(int(f.step))
    if step is None:
        raise values.ValueCodecError(f"step {f.step!r} is not one of {[s.name for s in Step]}")
    call_json = str(f.call_json)
    call = Call.from_json(str(f.skill), str(f.node), call_json, _checked(f.rng)) if call_json else None
    board = values.loads(str(f.blackboard_json), "the blackboard") if f.blackboard_json else {}
    if not isinstance(board, dict):
        raise values.ValueCodecError("the blackboard: not a mapping of keys to values")
    return TickRequest(
        str(f.call_id),
        step,
        float(f.time),
        int(f.ticks),
        float(f.period),
        bool(f.simulated),
        call,
        board,
        str(f.reason),
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
        "pending_after_tick": reply.pending_after_tick,
    }


def reply_of(fields: Any) -> TickReply:
    """A reply from ``SkillTick``'s response fields (a message or a mapping); ValueError if malformed."""
    f = _Mapped(fields) if isinstance(fields, dict) else fields
    state = _STATES.get(int(f.state))
    if state is None:
        raise values.ValueCodecError(f"state {f.state!r} is not one of {[s.name for s in State]}")
    outputs = values.loads(f.outputs_json, "the outputs") if f.outputs_json else {}
    events = values.loads(f.events_json, "the events") if f.events_json else []
    drawn = _unpacked(f.rng)
    if not isinstance(outputs, dict) or not isinstance(events, list):
        raise values.ValueCodecError("a reply's outputs must be a mapping and its events a list")
    pending = True if f.pending_after_tick is None else bool(f.pending_after_tick)
    return TickReply(
        state, str(f.outcome), str(f.reason), outputs, tuple(map(tuple, events)) if events else (), drawn, pending
    )


class DirectLink:
    """A link to a host in this process, through the same fields as the wire: for tests and benches."""

    def __init__(self, host: Any, remote: str = "local") -> None:
        self.host, self.remote = host, remote

    def tick(self, request: TickRequest) -> TickReply:
        return reply_of(reply_fields(self.host.handle(request_of(request_fields(request)))))
