"""The mission's side of a remote skill: a skill class with the real one's contract.

``remote_of(real, link)`` is to distribution what ``botstage.missions.mocks.mock_of`` is to scenarios: the
registry resolves the name to it, and trees, machines, checks and the trace see the same ports,
parameters and outcomes. Its run sends one request per tick over ``link`` and replays what the
host says the skill did (log lines, blackboard writes) where the local skill would have done it;
cancelling it (closing the generator) cancels the remote call and waits for its cleanup.
"""

from __future__ import annotations

import contextlib
import logging
import os
from typing import Any, Protocol

from botstage.robots.remote import values
from botstage.robots.remote.devices import RemoteLost
from botstage.skills.base import FAILURE, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.expression import ExpressionError, compile_expression
from botstage.skills.remote.protocol import Call, State, Step, TickReply, TickRequest


class SkillLink(Protocol):
    """Carries ticks to the process that runs a skill; raises ``RemoteLost`` when it is gone."""

    remote: str  # the process's name, for reasons

    def tick(self, request: TickRequest) -> TickReply: ...


def node_keys(real: type[Skill], inputs: dict[str, Any]) -> tuple[frozenset[str], frozenset[str]]:
    """The keys a node of ``real`` reads and writes itself (through ``ctx.blackboard``)."""
    reads: set[str] = set()
    writes: set[str] = set()
    for port_name, value in inputs.items():
        port = real.inputs.get(port_name)
        if port is None or not isinstance(value, str):
            continue
        if port.expression:
            with contextlib.suppress(ExpressionError):
                reads |= compile_expression(value).keys
        elif port.names_key == "read":
            reads.add(value)
        elif port.names_key == "write":
            writes.add(value)
    return frozenset(reads), frozenset(writes)


def _snapshot(ctx: SkillContext, keys: frozenset[str]) -> dict[str, Any]:
    board = ctx.blackboard
    return {key: board.get(key) for key in sorted(keys) if board.exists(key)}


def _replay(ctx: SkillContext, reply: TickReply) -> None:
    for kind, key, value in reply.events:
        if kind == "set":
            ctx.blackboard.set(key, value)
        elif kind == "log":
            ctx.logger.log(logging.getLevelName(str(key).upper()) if isinstance(key, str) else logging.INFO, str(value))


def remote_of(real: type[Skill], link: SkillLink) -> type[Skill]:
    """A skill with ``real``'s contract whose runs happen where ``link`` leads."""

    def run(self: Skill, ctx: SkillContext, **inputs: Any) -> SkillRun:
        reads, writes = node_keys(real, inputs)
        keys = reads | writes
        call_id = os.urandom(16).hex()  # unique as a uuid4's hex, without building a UUID per call
        clock = ctx.clock

        def request(step: Step, call: Call | None = None, reason: str = "") -> TickRequest:
            now, ticks, board = clock.now(), clock.ticks, _snapshot(ctx, keys)
            return TickRequest(call_id, step, now, ticks, clock.period, clock.simulated, call, board, reason)

        call = Call(real.name, ctx.node, inputs, self.params.model_dump(mode="json"), ctx.rng.getstate(), reads, writes)
        running = True
        try:
            reply = link.tick(request(Step.START, call))
            while True:
                _replay(ctx, reply)
                if reply.state is State.RUNNING:
                    yield
                    reply = link.tick(request(Step.STEP))
                    continue
                running = False
                if reply.state is State.ENDED:
                    if reply.rng_state is not None:
                        ctx.rng.setstate(reply.rng_state)
                    return Outcome(reply.outcome, reply.reason, reply.outputs)
                return Outcome(FAILURE, f"remote {link.remote!r} lost the call: {reply.reason}")
        except RemoteLost as lost:
            running = False
            return Outcome(FAILURE, str(lost))
        except values.ValueCodecError as error:
            return Outcome(FAILURE, f"cannot run {real.name!r} remotely: {error}")
        finally:
            if running:  # cancelled while the remote runs it: close it there and wait for its cleanup
                with contextlib.suppress(RemoteLost):
                    reply = link.tick(request(Step.CANCEL, reason="cancelled by the mission"))
                    _replay(ctx, reply)
                    if reply.rng_state is not None:
                        ctx.rng.setstate(reply.rng_state)

    return type(
        f"Remote_{real.__name__}",
        (Skill,),
        {
            "name": real.name,
            "description": real.description,
            "kind": real.kind,
            "inputs": real.inputs,
            "outputs": real.outputs,
            "outcomes": tuple(sorted(real.all_outcomes - set(real.success_outcomes) - {FAILURE})),
            "success_outcomes": real.success_outcomes,
            "Params": real.Params,
            "run": run,
            "remote": link.remote,
            "__module__": __name__,
            "__doc__": f"{real.name}, run by the remote process {link.remote!r}.",
        },
    )
