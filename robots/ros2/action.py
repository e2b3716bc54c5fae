"""ROS 2 actions over Zenoh, laid out as rcl_action lays them out on services and topics.

An action ``/a`` of type ``pkg/action/A`` is, under ``/a/_action/``:

- ``send_goal`` (service ``pkg/action/A_SendGoal``): goal id (a UUID the client picks) and goal
  -> accepted and the acceptance stamp;
- ``cancel_goal`` (service ``action_msgs/srv/CancelGoal``): a goal id and a stamp -> a return code
  and the goals now cancelling (all of them for a zero id and stamp, as rcl_action reads it);
- ``get_result`` (service ``pkg/action/A_GetResult``): goal id -> status and result, answered
  when the goal ends (rmw_zenoh's calls never time out: the query stays open until then);
- ``feedback`` (topic ``pkg/action/A_FeedbackMessage``): goal id and feedback;
- ``status`` (topic ``action_msgs/msg/GoalStatusArray``, reliable, transient local, depth 1):
  every goal the server knows with its status, published on each change.

QoS are rcl_action's defaults. ROS 2 tools (``ros2 action list -t``, ``ros2 action send_goal``)
and any rcl_action client or server work with these.

ActionServer imposes no threading: its callbacks (accept a goal, accept a cancel) run on the
services' threads and must be quick; the goal's work runs wherever its owner likes, which reports
with ``publish_feedback`` and ends the goal with ``succeed``, ``abort`` or ``canceled`` from any
thread. Ended goals keep their result for ``result_timeout`` seconds (rcl_action's 15 minutes)
and at most ``max_results`` of them.

ActionClient sends a goal and, once it is accepted, asks for its result at once (as ``ros2 action
send_goal`` does); a GoalHandle gives the result as a future, the feedback to a callback, and
cancels. The client watches the liveliness tokens of the ``get_result`` servers: when the server
that accepted a goal leaves the graph (its node closed, its process died: Zenoh drops a dead
peer's tokens as soon as its connection breaks), every unfinished goal it held fails at once with
ActionServerLost. A ``get_result`` query that ends without a reply while its server is still in
the graph is sent again after a short grace; the grace only lets a departure arrive first.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import numpy

from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.names import fully_qualified_name
from botstage.robots.ros2.qos import Durability, QoS
from botstage.robots.ros2.service import (
    Call,
    PendingRequest,
    ServiceClient,
    ServiceError,
    ServiceUnavailable,
    _settle,
)

if TYPE_CHECKING:
    from botstage.robots.ros2.node import Publisher, Ros2Node, Subscription

log = logging.getLogger(__name__)

CANCEL_GOAL = "action_msgs/srv/CancelGoal"
GOAL_STATUS_ARRAY = "action_msgs/msg/GoalStatusArray"
STATUS_QOS = QoS(durability=Durability.TRANSIENT_LOCAL, depth=1)  # rcl_action_qos_profile_status_default
RESULT_TIMEOUT_S = 900.0  # rcl_action's default result_timeout: 15 minutes
MAX_RESULTS = 1000
RESULT_RETRY_S = 0.5  # before asking again for a result whose query ended unanswered
NS_PER_S = 1_000_000_000


class GoalStatus(IntEnum):
    """action_msgs/msg/GoalStatus."""

    UNKNOWN = 0
    ACCEPTED = 1
    EXECUTING = 2
    CANCELING = 3
    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6

    @property
    def terminal(self) -> bool:
        return self >= GoalStatus.SUCCEEDED


class CancelCode(IntEnum):
    """action_msgs/srv/CancelGoal's return codes."""

    NONE = 0
    REJECTED = 1
    UNKNOWN_GOAL_ID = 2
    GOAL_TERMINATED = 3


class GoalRejected(RuntimeError):
    """The server did not accept the goal."""


class ActionServerLost(ServiceError):
    """The server that held the goal left the ROS 2 graph before the goal ended (from its liveliness tokens)."""

    def __init__(self, message: str, zid: str) -> None:
        super().__init__(message)
        self.zid = zid


@dataclass(frozen=True, slots=True)
class GoalResult:
    """How a goal ended: SUCCEEDED, ABORTED or CANCELED, and the result the server gave."""

    status: GoalStatus
    result: Any


def action_endpoints(action: str) -> dict[str, str]:
    """The services and topics of the action ``action`` (fully qualified), as rcl_action names them."""
    parts = ("send_goal", "cancel_goal", "get_result", "feedback", "status")
    return {part: f"{action}/_action/{part}" for part in parts}


def goal_uuid(goal_id: bytes) -> Any:
    """A unique_identifier_msgs/UUID of 16 bytes."""
    if len(goal_id) != 16:
        raise ValueError(f"a goal id is 16 bytes, got {len(goal_id)}")
    return types.message_class(types.UUID)(uuid=numpy.frombuffer(goal_id, dtype=numpy.uint8).copy())


def time_message(ns: int) -> Any:
    """A builtin_interfaces/Time of ``ns`` nanoseconds since the epoch."""
    seconds, nanoseconds = divmod(int(ns), NS_PER_S)
    return types.message_class(types.TIME)(sec=seconds, nanosec=nanoseconds)


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def _goal_id(message: Any) -> bytes:
    return bytes(numpy.asarray(message.uuid, dtype=numpy.uint8).tobytes())


@dataclass
class _Goal:
    goal_id: bytes
    goal: Any
    stamp_ns: int
    status: GoalStatus = GoalStatus.EXECUTING
    result: Any = None
    ended_at: float = 0.0  # monotonic
    waiting: list[PendingRequest] | None = None


class ActionServer:
    """Serves one action: goals are accepted by ``on_goal``, cancelled by ``on_cancel``, ended by their owner.

    ``on_goal(goal_id, goal) -> bool`` accepts (default: every goal); an accepted goal is EXECUTING
    at once and ``on_accepted(goal_id, goal)`` is called after the client has its answer: start the
    work there, and return (it runs on the send_goal service's thread, which takes the next goal
    only after it). ``on_cancel(goal_id) -> bool`` accepts a cancel request (default: accept, unlike
    rclpy: a botstage skill can always be cancelled); an accepted one makes the goal CANCELING,
    and its owner stops the work and calls ``canceled``. A callback that raises rejects, and is
    logged.
    """

    def __init__(
        self,
        node: Ros2Node,
        name: str,
        type_name: str,
        *,
        on_goal: Callable[[bytes, Any], bool] | None = None,
        on_cancel: Callable[[bytes], bool] | None = None,
        on_accepted: Callable[[bytes, Any], None] | None = None,
        result_timeout: float = RESULT_TIMEOUT_S,
        max_results: int = MAX_RESULTS,
    ) -> None:
        self.action = types.action_type(type_name)
        self.name = fully_qualified_name(name, node.namespace, node.name)
        self._clock = node.clock
        self._on_goal, self._on_cancel, self._on_accepted = on_goal, on_cancel, on_accepted
        self._result_timeout, self._max_results = result_timeout, max_results
        self._goals: dict[bytes, _Goal] = {}
        self._lock = threading.Lock()
        self._status_lock = threading.Lock()
        at = action_endpoints(self.name)
        self._entities: list[Any] = []
        try:  # rcl_action's order: the three services, then the two topics
            self._add(node.service(at["send_goal"], self.action.send_goal.name, self._send_goal, deferred=True))
            self._add(node.service(at["cancel_goal"], CANCEL_GOAL, self._cancel_goal))
            self._add(node.service(at["get_result"], self.action.get_result.name, self._get_result, deferred=True))
            self._feedback: Publisher = self._add(node.publisher(at["feedback"], self.action.feedback_message))
            self._status: Publisher = self._add(node.publisher(at["status"], GOAL_STATUS_ARRAY, STATUS_QOS))
        except Exception:
            self.close()
            raise

    def _add(self, entity: Any) -> Any:
        self._entities.append(entity)
        return entity

    # -- the services (their threads) ----------------------------------------------------------

    def _send_goal(self, pending: PendingRequest) -> None:
        goal_id, goal = _goal_id(pending.request.goal_id), pending.request.goal
        accepted = self._decide(lambda: self._on_goal is None or bool(self._on_goal(goal_id, goal)), "on_goal")
        stamp_ns = int(self._clock())
        with self._lock:
            if goal_id in self._goals:
                accepted = False  # a goal id is used once (rcl_action rejects a duplicate)
            if accepted:
                self._goals[goal_id] = _Goal(goal_id, goal, stamp_ns)
        Response = types.message_class(self.action.send_goal.response)
        pending.reply(Response(accepted=accepted, stamp=time_message(stamp_ns)))
        if accepted:
            self._publish_status()
            if self._on_accepted is not None:
                try:
                    self._on_accepted(goal_id, goal)
                except Exception:
                    log.exception("action %s: on_accepted raised; the goal is aborted", self.name)
                    self.abort(goal_id)

    def _decide(self, decide: Callable[[], bool], what: str) -> bool:
        try:
            return decide()
        except Exception:
            log.exception("action %s: %s raised; rejected", self.name, what)
            return False

    def _cancel_goal(self, request: Any) -> Any:
        goal_id, stamp_ns = _goal_id(request.goal_info.goal_id), _ns(request.goal_info.stamp)
        with self._lock:
            active = [g for g in self._goals.values() if not g.status.terminal]
            if goal_id == bytes(16):
                chosen = [g for g in active if stamp_ns == 0 or g.stamp_ns <= stamp_ns]
            else:
                chosen = [g for g in active if g.goal_id == goal_id or (stamp_ns and g.stamp_ns <= stamp_ns)]
            named = self._goals.get(goal_id)
        canceling = []
        for goal in chosen:
            if goal.status is GoalStatus.CANCELING or self._decide(
                lambda g=goal: self._on_cancel is None or bool(self._on_cancel(g.goal_id)), "on_cancel"
            ):
                with self._lock:
                    if not goal.status.terminal:
                        goal.status = GoalStatus.CANCELING
                        canceling.append(goal)
        if canceling:
            code = CancelCode.NONE
        elif goal_id != bytes(16) and named is None:
            code = CancelCode.UNKNOWN_GOAL_ID
        elif named is not None and named.status.terminal:
            code = CancelCode.GOAL_TERMINATED
        else:
            code = CancelCode.REJECTED
        if canceling:
            self._publish_status()
        GoalInfo = types.message_class("action_msgs/msg/GoalInfo")
        infos = [GoalInfo(goal_id=goal_uuid(g.goal_id), stamp=time_message(g.stamp_ns)) for g in canceling]
        return types.message_class(f"{CANCEL_GOAL}_Response")(return_code=int(code), goals_canceling=infos)

    def _get_result(self, pending: PendingRequest) -> None:
        goal_id = _goal_id(pending.request.goal_id)
        self._expire()
        with self._lock:
            goal = self._goals.get(goal_id)
            if goal is not None and not goal.status.terminal:
                goal.waiting = (goal.waiting or []) + [pending]
                return
        self._answer(pending, goal)

    def _answer(self, pending: PendingRequest, goal: _Goal | None) -> None:
        Response = types.message_class(self.action.get_result.response)
        if goal is None:  # unknown, or its result expired: rcl_action answers STATUS_UNKNOWN
            pending.reply(Response(status=int(GoalStatus.UNKNOWN), result=types.default_message(self.action.result)))
        else:
            pending.reply(Response(status=int(goal.status), result=goal.result))

    # -- what the goal's owner calls (any thread) ------------------------------------------------

    def publish_feedback(self, goal_id: bytes, feedback: Any) -> None:
        """Publish ``feedback`` (of the action's feedback type) for an active goal."""
        self._active(goal_id)
        FeedbackMessage = types.message_class(self.action.feedback_message)
        self._feedback.publish(FeedbackMessage(goal_id=goal_uuid(goal_id), feedback=feedback))

    def succeed(self, goal_id: bytes, result: Any = None) -> None:
        """End the goal SUCCEEDED with ``result`` (default: an empty result)."""
        self._end(goal_id, GoalStatus.SUCCEEDED, result)

    def abort(self, goal_id: bytes, result: Any = None) -> None:
        """End the goal ABORTED (the server could not reach it) with ``result``."""
        self._end(goal_id, GoalStatus.ABORTED, result)

    def canceled(self, goal_id: bytes, result: Any = None) -> None:
        """End a goal whose cancel was accepted (CANCELING) as CANCELED with ``result``."""
        self._end(goal_id, GoalStatus.CANCELED, result)

    def status(self, goal_id: bytes) -> GoalStatus:
        """The goal's status (UNKNOWN when the server does not know it, or no longer)."""
        with self._lock:
            goal = self._goals.get(goal_id)
            return goal.status if goal is not None else GoalStatus.UNKNOWN

    def _active(self, goal_id: bytes) -> _Goal:
        goal = self._goals.get(goal_id)
        if goal is None:
            raise KeyError(f"action {self.name}: no goal {uuid.UUID(bytes=goal_id)}")
        if goal.status.terminal:
            raise ValueError(f"action {self.name}: goal {uuid.UUID(bytes=goal_id)} already ended {goal.status.name}")
        return goal

    def _end(self, goal_id: bytes, status: GoalStatus, result: Any) -> None:
        if result is None:
            result = types.default_message(self.action.result)
        types.serialize(result, self.action.result)  # a result of the wrong type fails here, the goal still open
        with self._lock:
            goal = self._active(goal_id)
            if status is GoalStatus.CANCELED and goal.status is not GoalStatus.CANCELING:
                raise ValueError(
                    f"action {self.name}: goal {uuid.UUID(bytes=goal_id)} is {goal.status.name}: "
                    "only a goal whose cancel was accepted ends CANCELED (abort it instead)"
                )
            goal.status, goal.result, goal.ended_at = status, result, time.monotonic()
            waiting, goal.waiting = goal.waiting or [], None
        for pending in waiting:
            self._answer(pending, goal)
        self._publish_status()

    # -- status ---------------------------------------------------------------------------------

    def _expire(self) -> None:
        """Forget ended goals past the result timeout, and the oldest beyond ``max_results``."""
        now = time.monotonic()
        with self._lock:
            ended = sorted((g for g in self._goals.values() if g.status.terminal), key=lambda g: g.ended_at)
            excess = max(0, len(ended) - self._max_results)
            for index, goal in enumerate(ended):
                if index < excess or now - goal.ended_at > self._result_timeout:
                    del self._goals[goal.goal_id]

    def _publish_status(self) -> None:
        self._expire()
        GoalStatusMessage = types.message_class("action_msgs/msg/GoalStatus")
        GoalInfo = types.message_class("action_msgs/msg/GoalInfo")
        with self._status_lock:  # one snapshot published at a time: the last one sent is the newest
            with self._lock:
                goals = [(g.goal_id, g.stamp_ns, g.status) for g in self._goals.values()]
            statuses = [
                GoalStatusMessage(goal_info=GoalInfo(goal_id=goal_uuid(i), stamp=time_message(s)), status=int(st))
                for i, s, st in goals
            ]
            if not self._status.closed:
                self._status.publish(types.message_class(GOAL_STATUS_ARRAY)(status_list=statuses))

    def close(self) -> None:
        """Leave the graph; results still awaited are never sent (their clients see the server go)."""
        for entity in self._entities:
            entity.close()
        with self._lock:
            waiting = [p for g in self._goals.values() for p in (g.waiting or [])]
            for goal in self._goals.values():
                goal.waiting = None
        for pending in waiting:
            pending.drop()


class GoalHandle:
    """A goal sent to an action server: whether it was accepted, its status, feedback, result and cancel."""

    def __init__(self, client: ActionClient, goal_id: bytes, on_feedback: Callable[[Any], None] | None) -> None:
        self.goal_id = goal_id
        self.accepted = False
        self.stamp_ns = 0
        self.server: str | None = None  # the Zenoh session id of the server that accepted it
        self.status = GoalStatus.UNKNOWN
        self.result_future: Future = Future()
        self._client = client
        self._on_feedback = on_feedback

    @property
    def done(self) -> bool:
        return self.result_future.done()

    def result(self, timeout: float | None = None) -> GoalResult:
        """How the goal ended; GoalRejected, ActionServerLost, ServiceError, or TimeoutError after ``timeout`` s."""
        return self.result_future.result(timeout)

    def cancel(self, timeout: float | None = None) -> Any:
        """Ask the server to cancel the goal; its action_msgs/srv/CancelGoal response."""
        return self.cancel_async().result(timeout)

    def cancel_async(self) -> Call:
        GoalInfo = types.message_class("action_msgs/msg/GoalInfo")
        Request = types.message_class(f"{CANCEL_GOAL}_Request")
        info = GoalInfo(goal_id=goal_uuid(self.goal_id), stamp=time_message(0))
        return self._client._cancel.call_async(Request(goal_info=info))

    def _feedback(self, feedback: Any) -> None:
        if self._on_feedback is not None:
            self._on_feedback(feedback)

    def __repr__(self) -> str:
        state = "accepted" if self.accepted else "not accepted"
        return f"GoalHandle({uuid.UUID(bytes=self.goal_id)}, {state}, {self.status.name})"


class ActionClient:
    """Sends goals to one action and follows them, failing them when their server leaves the graph."""

    def __init__(self, node: Ros2Node, name: str, type_name: str) -> None:
        self.action = types.action_type(type_name)
        self.name = fully_qualified_name(name, node.namespace, node.name)
        self._goals: dict[bytes, GoalHandle] = {}
        self._lock = threading.Lock()
        self._closed = False
        at = action_endpoints(self.name)
        self._entities: list[Any] = []
        try:
            self._send: ServiceClient = self._add(node.client(at["send_goal"], self.action.send_goal.name))
            self._cancel: ServiceClient = self._add(node.client(at["cancel_goal"], CANCEL_GOAL))
            self._result: ServiceClient = self._add(node.client(at["get_result"], self.action.get_result.name))
            self._feedback_subscription: Subscription = self._add(
                node.subscription(at["feedback"], self.action.feedback_message, self._on_feedback)
            )
            self._status_subscription: Subscription = self._add(
                node.subscription(at["status"], GOAL_STATUS_ARRAY, self._on_status, STATUS_QOS)
            )
        except Exception:
            self.close()
            raise
        self.servers = self._result.servers  # the get_result servers: where results come from
        self.servers.listen(self._on_server_change)

    def _add(self, entity: Any) -> Any:
        self._entities.append(entity)
        return entity

    def wait_for_server(self, timeout: float | None = None) -> bool:
        """Whether the action's three services are in the graph, waiting up to ``timeout`` s for them."""
        deadline = None if timeout is None else time.monotonic() + timeout
        for client in (self._send, self._cancel, self._result):
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not client.wait_for_service(left):
                return False
        return True

    def send_goal(
        self, goal: Any, on_feedback: Callable[[Any], None] | None = None, timeout: float | None = None
    ) -> GoalHandle:
        """Send ``goal`` and wait up to ``timeout`` s for the server's answer: the handle (see ``accepted``)."""
        return self.send_goal_async(goal, on_feedback).result(timeout)

    def send_goal_async(self, goal: Any, on_feedback: Callable[[Any], None] | None = None) -> Future:
        """Send ``goal``; a future of its GoalHandle. ``on_feedback(feedback)`` runs on Zenoh's thread: be quick."""
        types.serialize(goal, self.action.goal)  # a goal of the wrong type fails here
        handle = GoalHandle(self, uuid.uuid4().bytes, on_feedback)
        with self._lock:
            if self._closed:
                raise RuntimeError(f"action client of {self.name} is closed")
            self._goals[handle.goal_id] = handle  # before sending: feedback may come before the answer
        Request = types.message_class(self.action.send_goal.request)
        call = self._send.call_async(Request(goal_id=goal_uuid(handle.goal_id), goal=goal))
        answered: Future = Future()
        call.add_done_callback(lambda c: self._answered(handle, c, answered))
        return answered

    def _answered(self, handle: GoalHandle, call: Future, answered: Future) -> None:
        """The send_goal response (on Zenoh's thread): follow an accepted goal, forget a rejected one."""
        assert isinstance(call, Call)
        failure = ServiceError(f"action {self.name}: sending the goal was cancelled") if call.cancelled() else None
        failure = failure or call.exception()
        if failure is not None:
            self._forget(handle, failure)
            _settle(answered, error=failure)
            return
        response = call.result()
        handle.accepted, handle.stamp_ns, handle.server = bool(response.accepted), _ns(response.stamp), call.replier
        if not handle.accepted:
            handle.status = GoalStatus.UNKNOWN
            self._forget(handle, GoalRejected(f"action {self.name}: the server rejected the goal"))
        else:
            if handle.status is GoalStatus.UNKNOWN:
                handle.status = GoalStatus.ACCEPTED
            if handle.server is not None and self.servers.left(handle.server):
                self._lost(handle)
            else:
                self._ask_result(handle)
        _settle(answered, handle)

    def _ask_result(self, handle: GoalHandle) -> None:
        if handle.done or self._closed:
            return
        Request = types.message_class(self.action.get_result.request)
        self._result.call_async(Request(goal_id=goal_uuid(handle.goal_id))).add_done_callback(
            lambda call: self._got_result(handle, call)
        )

    def _got_result(self, handle: GoalHandle, call: Future) -> None:
        if handle.done or call.cancelled():
            return
        error = call.exception()
        if isinstance(error, ServiceUnavailable) and not self._closed:
            # The query ended unanswered: the server is leaving (its departure fails the goal) or
            # dropped the request (ask again). Wait a little for a departure before deciding.
            timer = threading.Timer(RESULT_RETRY_S, self._retry_result, args=(handle,))
            timer.daemon = True
            timer.start()
            return
        if error is not None:
            self._forget(handle, error)
            return
        response = call.result()
        status = GoalStatus(response.status)
        handle.status = status
        if not status.terminal:
            unknown = f"action {self.name}: the server does not know the goal (status {status.name})"
            self._forget(handle, ServiceError(unknown))
            return
        self._forget(handle, None, GoalResult(status, response.result))

    def _retry_result(self, handle: GoalHandle) -> None:
        if handle.server is not None and self.servers.left(handle.server):
            self._lost(handle)
        else:
            self._ask_result(handle)

    def _forget(self, handle: GoalHandle, error: BaseException | None, result: GoalResult | None = None) -> None:
        with self._lock:
            self._goals.pop(handle.goal_id, None)
        _settle(handle.result_future, result, error)

    def _lost(self, handle: GoalHandle) -> None:
        zid = handle.server or "?"
        self._forget(
            handle,
            ActionServerLost(f"action {self.name}: its server (Zenoh session {zid}) left the ROS 2 graph", zid),
        )

    def _on_server_change(self, zid: str, alive: bool) -> None:
        """A get_result server appeared or left (Zenoh's thread): fail the goals of one that left."""
        if alive:
            return
        with self._lock:
            held = [h for h in self._goals.values() if h.accepted and h.server == zid]
        for handle in held:
            self._lost(handle)

    def _on_feedback(self, message: Any, _: Attachment) -> None:
        handle = self._goals.get(_goal_id(message.goal_id))
        if handle is not None:
            handle._feedback(message.feedback)

    def _on_status(self, message: Any, _: Attachment) -> None:
        for status in message.status_list:
            handle = self._goals.get(_goal_id(status.goal_info.goal_id))
            if handle is not None:
                handle.status = GoalStatus(status.status)

    def goals(self) -> list[GoalHandle]:
        """The goals sent and not finished yet."""
        with self._lock:
            return list(self._goals.values())

    def close(self) -> None:
        """Leave the graph; goals not finished fail."""
        with self._lock:
            self._closed = True
            handles = list(self._goals.values())
        for entity in self._entities:
            entity.close()
        for handle in handles:
            self._forget(handle, ServiceError(f"action client of {self.name} closed"))
