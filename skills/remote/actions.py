"""Each skill a process serves, also as a ROS 2 action any ROS 2 client can list and call.

``/<process>/skills/<skill>`` of type ``botstage_msgs/action/SkillCall``: a goal names the skill,
its inputs and parameters as JSON; the process runs it on its own wall clock at ``rate_hz`` (there
is no mission to tick it), publishes feedback each tick (ticks run, the last thing the skill
logged), and ends the goal with the outcome, reason and outputs: SUCCEEDED for the skill's
success outcomes, ABORTED for the others, CANCELED after a cancel (the skill's ``finally`` ran).
A call from a ROS 2 tool has no blackboard: the keys the skill writes are kept for that call
only, and a key it reads has no value. A mission does not use these: it drives its remote skills
tick by tick over ``/<process>/skill_tick`` so a distributed run stays deterministic.
"""

from __future__ import annotations

import json
import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from botstage.robots.clock import WallClock
from botstage.robots.ros2 import types
from botstage.robots.ros2.node import Ros2Node
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import Call, State, Step, TickReply, TickRequest
from botstage.skills.remote.proxy import node_keys

log = logging.getLogger(__name__)

ACTION_TYPE = "botstage_msgs/action/SkillCall"
RATE_HZ = 10.0


def action_name(process: str, skill: str) -> str:
    return f"/{process}/skills/{skill}"


def _object(text: str, what: str) -> dict[str, Any]:
    if not text.strip():
        return {}
    value = json.loads(text)
    if not isinstance(value, dict):
        raise ValueError(f"{what} must be a JSON object, got {type(value).__name__}")
    return value


@dataclass
class _Goal:
    goal_id: bytes
    call: Call
    ticks: int = 0
    started: bool = False
    cancel: bool = False
    detail: str = ""
    clock_origin: float = 0.0
    events: list[Any] = field(default_factory=list)


class SkillActions:
    """The action servers of one process's skills and the thread that runs their goals."""

    def __init__(self, node: Ros2Node, host: SkillHost, skills: list[str], rate_hz: float = RATE_HZ) -> None:
        self.host, self.process = host, node.name
        self._goals: dict[bytes, _Goal] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._clock = WallClock(rate_hz, sleep=self._stop.wait)
        self._result = types.message_class(f"{ACTION_TYPE}_Result")
        self._feedback = types.message_class(f"{ACTION_TYPE}_Feedback")
        self.servers = {
            skill: node.action_server(
                action_name(node.name, skill),
                ACTION_TYPE,
                on_goal=lambda goal_id, goal, skill=skill: self._accept(skill, goal_id, goal),
                on_cancel=self._cancel,
            )
            for skill in skills
        }
        self._thread = threading.Thread(target=self._run, name="botstage-skill-actions", daemon=True)
        self._thread.start()

    def _accept(self, skill: str, goal_id: bytes, goal: Any) -> bool:
        if goal.skill and goal.skill != skill:
            log.warning("goal for %r sent to the %r action: rejected", goal.skill, skill)
            return False
        try:
            inputs = _object(goal.inputs_json, "inputs_json")
            params = _object(goal.params_json, "params_json")
            real = self.host.registry.get(skill)
            real.validate_params(params)
        except Exception as error:  # bad JSON, bad parameters: rejected, and said in the log
            log.warning("goal for %r rejected: %s", skill, error)
            return False
        reads, writes = node_keys(real, inputs)
        node = f"{action_name(self.process, skill)}/{goal_id.hex()[:8]}"
        call = Call(skill, node, inputs, params, None, reads, writes)
        with self._lock:
            self._goals[goal_id] = _Goal(goal_id, call, clock_origin=self._clock.now())
        return True

    def _cancel(self, goal_id: bytes) -> bool:
        with self._lock:
            goal = self._goals.get(goal_id)
            if goal is None:
                return False
            goal.cancel = True
            return True

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                goals = list(self._goals.values())
            for goal in goals:
                try:
                    self._tick(goal)
                except Exception:  # one goal's trouble never stops the others
                    log.exception("skill action goal %s", goal.goal_id.hex())
                    self._end(goal, TickReply(State.ENDED, "failure", "the skill's action server failed"))
            self._clock.next_tick()
        with self._lock:
            goals = list(self._goals.values())
        for goal in goals:
            goal.cancel = True
            self._tick(goal)

    def _tick(self, goal: _Goal) -> None:
        server = self.servers[goal.call.skill]
        step = Step.CANCEL if goal.cancel else (Step.STEP if goal.started else Step.START)
        if goal.cancel and not goal.started:
            self._end(goal, TickReply(State.CANCELLED, reason="cancelled before it started"))
            return
        now = self._clock.now() - goal.clock_origin
        request = TickRequest(
            goal.goal_id.hex(),
            step,
            now,
            goal.ticks,
            self._clock.period,
            False,
            goal.call if step is Step.START else None,
            {},
            "cancelled by its caller",
        )
        reply = self.host.handle(request)
        goal.started = True
        for kind, _key, value in reply.events:
            if kind == "log":
                goal.detail = str(value)[:200]
        if reply.state is State.RUNNING:
            goal.ticks += 1
            server.publish_feedback(goal.goal_id, self._feedback(ticks=goal.ticks, detail=goal.detail))
            return
        self._end(goal, reply)

    def _end(self, goal: _Goal, reply: TickReply) -> None:
        with self._lock:
            if self._goals.pop(goal.goal_id, None) is None:
                return
        server = self.servers[goal.call.skill]
        outputs = json.dumps(reply.outputs, default=str, ensure_ascii=False) if reply.outputs else ""
        outcome = reply.outcome or ("cancelled" if reply.state is not State.ENDED else "failure")
        result = self._result(outcome=outcome, reason=reply.reason, outputs_json=outputs, ticks=goal.ticks)
        if goal.cancel:
            try:
                server.canceled(goal.goal_id, result)
            except Exception:  # ended by this process closing, not by a cancel request
                server.abort(goal.goal_id, result)
        elif reply.state is State.ENDED and outcome in self.host.registry.get(goal.call.skill).success_outcomes:
            server.succeed(goal.goal_id, result)
        else:
            server.abort(goal.goal_id, result)

    def close(self) -> None:
        """Cancel what runs (each skill's cleanup runs), then leave the graph."""
        self._stop.set()
        self._thread.join()
        for server in self.servers.values():
            server.close()
