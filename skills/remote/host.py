"""The serving side of remote skills: runs each call of the real skill as the mission asks.

Steps run one at a time, in the order requests take the host's lock, on the thread that brings
each request (a service's or an action server's worker): no thread hand-off per tick, and two
calls never race over a device. The run's logger sends to the reply the lines its step logs on
that thread (``SkillLogger.adopt``), as the engine's thread does locally. A call's clock reads
the time of the request that drives it; on a simulated clock the host waits for the work a step
submitted before it answers, as the engine does after each tick, so the skill sees that work
done at the same tick as in a local run.

A call ends when its skill ends or is cancelled; a host keeps at most ``max_calls`` at once and
cancels them all when it closes (their ``finally`` blocks stop what they started).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from pydantic import BaseModel

from botstage.robots.remote import values
from botstage.skills.base import FAILURE, Outcome, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution, describe_exception
from botstage.skills.registry import Registry, UnknownSkillError
from botstage.skills.remote.protocol import Call, State, Step, TickReply, TickRequest
from botstage.skills.remote.rng import LazyRandom
from botstage.skills.workers import Workers

log = logging.getLogger(__name__)

MAX_CALLS = 64
MAX_PARAMS = 1024  # validated parameter sets kept (per node, skill and values); forgotten all at once past it


class DrivenClock:
    """A clock that reads what the latest request says: the mission's time, not this machine's."""

    def __init__(self, request: TickRequest) -> None:
        self.follow(request)

    def follow(self, request: TickRequest) -> None:
        self._now, self.ticks = request.time, request.ticks
        self._period, self._simulated = request.period, request.simulated

    @property
    def period(self) -> float:
        return self._period

    @property
    def simulated(self) -> bool:
        return self._simulated

    def now(self) -> float:
        return self._now

    def next_tick(self) -> None:
        raise RuntimeError("a remote skill's clock moves with the mission's ticks, not by itself")


class KeyView:
    """The blackboard as a remote skill sees it: the node's keys as the request sent them.

    Writes are kept in the request's copy (a read after a write sees it, as locally) and recorded
    for the reply; keys outside the node's declared reads and writes are refused like locally.
    """

    def __init__(self, node: str, reads: frozenset[str], writes: frozenset[str], record: Callable[..., None]) -> None:
        self._node, self._reads, self._writes, self._record = node, reads, writes, record
        self.values: dict[str, Any] = {}

    def get(self, key: str) -> Any:
        if key not in self._reads and key not in self._writes:
            raise KeyError(f"node {self._node!r} did not declare that it reads {key!r}")
        try:
            return self.values[key]
        except KeyError:
            raise KeyError(f"no value for {key!r} yet: nothing has written it") from None

    def set(self, key: str, value: Any) -> None:
        if key not in self._writes:
            raise KeyError(f"node {self._node!r} did not declare that it writes {key!r}")
        self.values[key] = value
        self._record("set", key, value)

    def exists(self, key: str) -> bool:
        return key in self.values


class _Run:
    """One call: its execution, its clock, its keys, and what it said since the last reply."""

    def __init__(self, host: SkillHost, request: TickRequest, call: Call) -> None:
        skill = host.registry.get(call.skill)(host.params(call))
        # the node's generator where the mission left it, loaded only if the skill draws from it
        self.rng = LazyRandom(call.rng_state)
        self.events: list[tuple[str, str, Any]] = []
        self.clock = DrivenClock(request)
        self.view = KeyView(call.node, call.reads, call.writes, self._record)
        self.logger = SkillLogger(call.node, sink=self._log)
        ctx = SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=self.logger,
            blackboard=self.view,
            workers=host.workers,
            interfaces=host.interfaces,
            rng=self.rng,
            node=call.node,
        )
        self.execution = SkillExecution(skill, ctx)
        self.inputs = call.inputs

    def _record(self, kind: str, key: str, value: Any) -> None:
        self.events.append((kind, key, value))

    def _log(self, node: str, level: str, message: str) -> None:
        self.events.append(("log", level, message))

    def drawn(self) -> tuple[Any, ...] | None:
        """The generator's state if the call drew from it (the mission's node takes it back)."""
        rng = self.rng
        if not rng.used:  # the common case, for free: the state is what the mission sent
            return None
        initial = rng.initial()
        state = rng.getstate()
        return state if initial is not None and state != initial else None

    def take_events(self) -> tuple[tuple[str, str, Any], ...]:
        events, self.events = tuple(self.events), []
        return events


class SkillHost:
    """Runs calls of the skills it serves, one step per request, one step at a time."""

    def __init__(
        self,
        registry: Registry,
        interfaces: Mapping[str, Any],
        skills: Iterable[str] | None = None,
        *,
        workers: Workers | None = None,
        max_calls: int = MAX_CALLS,
    ) -> None:
        self.registry = registry
        self.interfaces = interfaces
        self.serves = frozenset(skills) if skills is not None else frozenset(registry)
        for name in self.serves:
            registry.get(name)  # an unknown skill is an error now, not at the first call
        self.workers = workers or Workers(name="botstage-remote-worker")
        self.max_calls = max_calls
        self._runs: dict[str, _Run] = {}
        self._params: dict[tuple[str, str, str], BaseModel] = {}
        self._lock = threading.Lock()
        self._closed = False

    def params(self, call: Call) -> BaseModel:
        """The call's validated parameters, one object per node, skill and values (as a local node has).

        Validating them costs more than the rest of starting a call, and a node calls with the
        same ones each time; a local node's skill keeps one parameters object for all its runs,
        and so does the host per node. Raises what validation raises.
        """
        given = call.params
        key = (call.node, call.skill, values.dumps(given, "the parameters") if given else "")  # exact: tagged JSON
        params = self._params.get(key)
        if params is None:
            params = self.registry.get(call.skill).validate_params(given)
            if len(self._params) >= MAX_PARAMS:
                self._params.clear()
            self._params[key] = params
        return params

    @property
    def calls(self) -> int:
        """Calls running now."""
        return len(self._runs)

    def handle(self, request: TickRequest, timeout: float | None = None) -> TickReply:
        """Run one request on this thread once the step before it is done; TimeoutError after ``timeout`` s."""
        if not self._lock.acquire(timeout=-1 if timeout is None else timeout):
            raise TimeoutError(f"the skill host was busy for {timeout} s")
        try:
            if self._closed:
                return TickReply(State.UNKNOWN, reason="the skill host is closed")
            return self._step_safely(request)
        finally:
            self._lock.release()

    def close(self) -> None:
        """Cancel every call (their cleanup runs) once the step in progress is done."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            for call_id in list(self._runs):
                self._cancel(call_id, "the skill host closed")
        self.workers.shutdown(wait_for_work=False)

    # -- under the lock ---------------------------------------------------------------------

    def _step_safely(self, request: TickRequest) -> TickReply:
        try:
            return self._step(request)
        except Exception as error:  # a bug of ours: the call fails with it, the host goes on
            log.exception("skill host: request %s failed", request.call_id)
            self._runs.pop(request.call_id, None)
            return TickReply(State.ENDED, FAILURE, f"the remote host failed: {describe_exception(error)}")

    def _step(self, request: TickRequest) -> TickReply:
        if request.step is Step.START:
            return self._start(request)
        run = self._runs.get(request.call_id)
        if run is None:
            return TickReply(State.UNKNOWN, reason=f"no call {request.call_id} here (the host restarted?)")
        run.clock.follow(request)
        run.view.values = dict(request.blackboard)
        run.logger.adopt()
        if request.step is Step.CANCEL:
            problem = self._cancel(request.call_id, request.reason)
            return TickReply(State.CANCELLED, reason=problem or "", events=run.take_events(), rng_state=run.drawn())
        return self._reply(request, run, run.execution.step())

    def _start(self, request: TickRequest) -> TickReply:
        call = request.call
        if call is None:
            return TickReply(State.ENDED, FAILURE, "a START without its call")
        if call.skill not in self.serves:
            return TickReply(State.ENDED, FAILURE, f"this host does not serve {call.skill!r}")
        if request.call_id in self._runs:  # a retried START: the first one stands
            self._cancel(request.call_id, "started again")
        if len(self._runs) >= self.max_calls:
            return TickReply(State.ENDED, FAILURE, f"the remote host runs {self.max_calls} calls already")
        try:
            run = _Run(self, request, call)
        except (UnknownSkillError, ValueError, TypeError) as error:  # bad parameters: pydantic says which
            return TickReply(State.ENDED, FAILURE, f"cannot start {call.skill!r}: {error}")
        run.view.values = dict(request.blackboard)
        self._runs[request.call_id] = run
        return self._reply(request, run, run.execution.start(run.inputs))

    def _reply(self, request: TickRequest, run: _Run, outcome: Outcome | None) -> TickReply:
        if request.simulated:
            self.workers.drain()  # what the engine does after a tick: see the module's docstring
        if outcome is None:
            return TickReply(State.RUNNING, events=run.take_events())
        del self._runs[request.call_id]
        outputs = dict(outcome.outputs)
        return TickReply(State.ENDED, outcome.name, outcome.reason, outputs, run.take_events(), run.drawn())

    def _cancel(self, call_id: str, reason: str) -> str | None:
        run = self._runs.pop(call_id, None)
        if run is None:
            return None
        log.debug("cancelling %s (%s)", call_id, reason)
        return run.execution.cancel()
