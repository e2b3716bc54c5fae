"""ROS 2 services over Zenoh, as rmw_zenoh does them: a queryable per server, a query per call.

A server declares a queryable (``complete``) on the service's data key
``<domain>/<service>/<pkg::srv::dds_::S_>/<RIHS01 of the service>`` and an ``SS`` token; a
client declares an ``SC`` token and calls with ``get`` on that key: the CDR request as payload,
rmw_zenoh's attachment (the client's sequence number from 1, source time, the client's GID),
target ``ALL_COMPLETE``, consolidation ``NONE`` and no practical timeout (rmw_zenoh uses the
largest one: actions wait long for results). The server replies on its key with the CDR response
and an attachment carrying the request's sequence number and the client's GID, which is how the
client matches a reply to its call (rcl matches by sequence number too).

What rmw_zenoh leaves to the layers above, decided here:

- A server's handler runs on the server's own thread, one request at a time in arrival order (a
  ROS executor's default), never on Zenoh's threads. That thread waits in Zenoh's channel of
  queries (``recv``, the GIL released), so a request reaches the handler with one thread woken,
  as a raw queryable's does: a hand-off from a callback thread cost as much again as the rest of
  a call. Requests that arrive while the handler runs wait in that channel; when the thread is
  free it takes them all and, with keep-last, drops all but the newest QoS-depth ones with an
  error reply saying the queue is full (the same requests rmw_zenoh's queue would drop, told
  when the running request is done rather than as they arrive). Zenoh itself holds at most
  ``INTAKE_CAPACITY`` queries for a busy server and ends the oldest beyond that unanswered.
- A handler that raises, or a request that cannot be decoded, gets a Zenoh *error reply* with the
  reason: a botstage client raises ServiceError with it, an rmw_zenoh client logs it ("z_reply_is_ok
  returned False") and keeps waiting, as it would for a server that never answers. Nothing else
  is affected; the server counts it.
- A deferred server hands its handler a PendingRequest to answer later, from any thread (an action
  server answers ``get_result`` when the goal ends).
- A call with no server ends at once: Zenoh ends a query no queryable matches, and the client
  raises ServiceUnavailable instead of waiting for its timeout. A call whose server answers
  nothing (its query ended without a reply) raises ServiceUnavailable too.
- ``wait_for_service`` watches the liveliness tokens of servers of the same name, type and hash,
  the graph rmw_zenoh's ``rmw_service_server_is_available`` reads.

A future's done-callbacks run on the thread that completes it: Zenoh's, for replies. Keep them
quick; ``call`` and ``Future.result`` block the caller instead.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, InvalidStateError
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import zenoh

from botstage.robots.ros2 import attachment as attachments
from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment, AttachmentError
from botstage.robots.ros2.entity import _Entity
from botstage.robots.ros2.liveliness import ADMIN_SPACE, EntityKind, TokenError, parse_token
from botstage.robots.ros2.names import mangle
from botstage.robots.ros2.qos import History, QoS

if TYPE_CHECKING:
    from botstage.robots.ros2.node import Ros2Node

log = logging.getLogger(__name__)

QUERY_TIMEOUT_S = 1e9  # rmw_zenoh asks for the largest timeout: a call waits until it is answered or given up
INTAKE_CAPACITY = 4096  # queries Zenoh keeps for a busy server (a ring: never blocks Zenoh's threads)
Handler = Callable[[Any], Any]


class ServiceError(RuntimeError):
    """A call that got no response: the server replied an error, or the client gave up."""


class ServiceUnavailable(ServiceError):
    """No server answered: none was there, or the one there ended the call without a reply."""


class ServiceTimeout(ServiceError, TimeoutError):
    """No response within the caller's timeout."""


class ServiceCancelled(ServiceError):
    """The caller's cancellation token ended the wait (or the client closed)."""


_UNMATCHED = object()  # a reply for another call: keep waiting
_ZENOH_TIMEOUT = b"Timeout"  # the error Zenoh replies itself when a query's time is up


def is_zenoh_timeout(reply: zenoh.Reply) -> bool:
    """Whether ``reply`` is Zenoh's own "the query timed out", not a server's answer.

    The caller's session sends it with no replier; under load the server's session can send it
    first, naming itself as the replier. Either way it has no attachment and says "Timeout" (a
    botstage server's errors always give a reason, and rmw_zenoh's servers send none).
    """
    if reply.err is None:
        return False
    return reply.replier_id is None or reply.err.payload.to_bytes() == _ZENOH_TIMEOUT


def _settle(future: Future, result: Any = None, error: BaseException | None = None) -> bool:
    """Complete ``future`` unless it already is (cancelled by its caller, or answered twice)."""
    try:
        if error is not None:
            future.set_exception(error)
        else:
            future.set_result(result)
    except InvalidStateError:
        return False
    return True


@dataclass(frozen=True, slots=True)
class ServerStats:
    """What a server received: handled, refused and why, and handler failures."""

    received: int = 0
    bad_requests: int = 0  # no attachment, a bad one, or bytes that are not the request type
    dropped: int = 0  # pushed out of a full keep-last queue
    handler_errors: int = 0


class PendingRequest:
    """One request a server has taken: answer it once, now or later, from any thread."""

    def __init__(self, server: ServiceServer, query: zenoh.Query, request: Any, client: Attachment) -> None:
        self.request = request
        self.client = client  # the client's sequence number, source time and GID
        self._server = server
        self._query: zenoh.Query | None = query
        self._lock = threading.Lock()

    @property
    def answered(self) -> bool:
        return self._query is None

    def _take(self) -> zenoh.Query | None:
        with self._lock:
            query, self._query = self._query, None
        self._server._unanswered.discard(self)
        return query

    def reply(self, response: Any) -> bool:
        """Send ``response`` (of the service's response type); False if already answered or the server closed."""
        payload = types.serialize(response, self._server.service.response)  # a bad response raises here, unsent
        query = self._take()
        if query is None:
            return False
        try:
            if self._server.closed:
                return False
            answer = attachments.pack(self.client.sequence, int(self._server.clock()), self.client.gid)
            query.reply(self._server.key, payload, attachment=answer)
            return True
        finally:
            query.drop()

    def fail(self, reason: str) -> bool:
        """Answer with a Zenoh error reply carrying ``reason``; False if already answered."""
        query = self._take()
        if query is None:
            return False
        try:
            query.reply_err(reason.encode("utf-8"))
            return True
        finally:
            query.drop()

    def drop(self) -> None:
        """End the call without a reply (the client sees its query end)."""
        query = self._take()
        if query is not None:
            query.drop()


class ServiceServer(_Entity):
    """Answers calls of one service: ``handler(request) -> response`` on the server's own thread.

    With ``deferred=True`` the handler gets a PendingRequest instead and answers it when it can
    (its return value is ignored); a request it leaves unanswered stays pending until the server
    closes.
    """

    kind = EntityKind.SERVICE

    def __init__(
        self, node: Ros2Node, entity_id: int, name: str, type_name: str, handler: Handler, qos: QoS, deferred: bool
    ) -> None:
        self.service = types.service_type(type_name)
        super().__init__(node, entity_id, name, type_name, qos)
        self.clock = node.clock
        self._handler, self._deferred = handler, deferred
        self._unanswered: set[PendingRequest] = set()  # a deferred handler's, kept until answered or closed
        self._stats_lock = threading.Lock()
        self._received = self._bad_requests = self._dropped_count = self._handler_errors = 0
        self._depth = None if self.qos.history is History.KEEP_ALL else self.qos.depth
        capacity = max(INTAKE_CAPACITY, self._depth or 0)
        queryable = node.session.declare_queryable(self.key, zenoh.handlers.RingChannel(capacity), complete=True)
        self._queries = queryable.handler  # taken now: undeclared, the queryable no longer gives it
        self._declared.append(queryable)
        self._thread = threading.Thread(target=self._serve, name=f"service {self.topic}", daemon=True)
        self._thread.start()
        self._declare_token()

    @property
    def stats(self) -> ServerStats:
        with self._stats_lock:
            return ServerStats(self._received, self._bad_requests, self._dropped_count, self._handler_errors)

    def _serve(self) -> None:
        """The server's thread: wait for queries, take all that wait, answer them in arrival order.

        Ends when the server closes (Zenoh closes the channel, and the queries in it end
        unanswered); requests taken but not yet handled then end without a reply too.
        """
        queries, depth = self._queries, self._depth
        waiting: deque[PendingRequest] = deque()
        while not self._closed:
            try:
                if not waiting:
                    self._admit(queries.recv(), waiting)
                while (query := queries.try_recv()) is not None:
                    self._admit(query, waiting)
            except zenoh.ZError:  # the channel closed with the server
                break
            if depth is not None:
                while len(waiting) > depth:
                    self._dropped(waiting.popleft())
            if self._closed:
                break
            if waiting:  # empty when what came was a bad request
                self._handle(waiting.popleft())
        for pending in waiting:
            pending.drop()

    def _admit(self, query: zenoh.Query, waiting: deque[PendingRequest]) -> None:
        """Decode ``query`` and queue it (a bad one gets its error reply); never raises."""
        try:
            pending = self._take(query)
        except Exception:
            log.exception("service %s: unexpected error", self.topic)
            query.drop()
            return
        if pending is not None:
            with self._stats_lock:  # plain counters: a new ServerStats per request cost more than the rest
                self._received += 1
            waiting.append(pending)

    def _take(self, query: zenoh.Query) -> PendingRequest | None:
        if self._closed:
            query.drop()
            return None
        if str(query.key_expr) != self.key:  # a query on `0/**` would pass an ACL denying this service's key
            log.debug("service %s: dropped a query on %s, not on the service's key", self.topic, query.key_expr)
            query.drop()
            return None
        problem = None
        try:
            attachment = query.attachment
            if attachment is None:
                raise AttachmentError("the request has no attachment")
            client = attachments.decode(attachment.to_bytes())
            body = query.payload
            payload = body.to_bytes() if body is not None else b""
            request = types.deserialize(payload, self.service.request)
        except (AttachmentError, types.CdrError) as error:
            problem = f"service {self.topic}: bad request: {error}"
        if problem is not None:
            with self._stats_lock:
                self._bad_requests += 1
            log.debug("%s", problem)
            query.reply_err(problem.encode("utf-8"))
            query.drop()
            return None
        return PendingRequest(self, query, request, client)

    def _dropped(self, pending: PendingRequest) -> None:
        with self._stats_lock:
            self._dropped_count += 1
        pending.fail(f"service {self.topic}: request dropped, the server's queue of {self.qos.depth} is full")

    def _handle(self, pending: PendingRequest) -> None:
        """The server's thread: run the handler; a raise becomes an error reply with its reason."""
        try:
            if self._deferred:
                self._unanswered.add(pending)
                self._handler(pending)
                return
            response = self._handler(pending.request)
            if not pending.reply(response):
                log.debug("service %s: the response to #%d was not sent", self.topic, pending.client.sequence)
        except Exception as error:
            with self._stats_lock:
                self._handler_errors += 1
            log.exception("service %s: the handler raised", self.topic)
            pending.fail(f"service {self.topic}: the handler raised {type(error).__name__}: {error}")

    def close(self) -> None:
        """Leave the graph, stop taking requests, and end the queued ones without a reply.

        Waits for a handler that is running to return, unless called from it.
        """
        super().close()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join()
        for pending in list(self._unanswered):
            pending.drop()


class Call(Future):
    """One call: a future of its response, with its sequence number and, once answered, who answered.

    ``replier`` is the Zenoh session id of the server that replied (an action client watches that
    server's liveliness while it waits for a goal's result). Cancelling the future abandons the call.
    """

    def __init__(self, sequence: int) -> None:
        super().__init__()
        self.sequence = sequence
        self.replier: str | None = None
        self.replied = False
        self._query_cancel = zenoh.CancellationToken()


class ServiceClient(_Entity):
    """Calls one service: ``call(request, timeout)`` or ``call_async(request)``."""

    kind = EntityKind.CLIENT

    def __init__(self, node: Ros2Node, entity_id: int, name: str, type_name: str, qos: QoS) -> None:
        self.service = types.service_type(type_name)
        super().__init__(node, entity_id, name, type_name, qos)
        self._session, self._clock = node.session, node.clock
        self._sequence = 0
        self._calls: dict[int, Call] = {}
        self._calls_lock = threading.Lock()
        self._waiting: set[zenoh.CancellationToken] = set()  # synchronous calls in flight
        self.unmatched_replies = 0  # replies for no call of ours (another client's GID, an unknown sequence)
        dds_type, type_hash = types.dds_type_name(type_name), types.type_hash(type_name)
        self.servers = ServerWatch(node.session, node.domain_id, self.topic, dds_type, type_hash)
        self._declared.append(self.servers)
        self._declare_token()

    def wait_for_service(self, timeout: float | None = None) -> bool:
        """Whether a server of this service is in the graph, waiting up to ``timeout`` s for one."""
        return self.servers.wait(timeout)

    def call(self, request: Any, timeout: float | None = None, cancel: zenoh.CancellationToken | None = None) -> Any:
        """The response to ``request``; ServiceTimeout after ``timeout`` s, ServiceError and subclasses otherwise.

        The reply wakes this thread straight from Zenoh's channel (no callback thread in between:
        a tenth of a millisecond per call on loopback). ``cancel``, cancelled from another
        thread, ends the wait with ServiceCancelled.
        """
        payload = types.serialize(request, self.service.request)
        token = cancel or zenoh.CancellationToken()
        with self._lock:
            if self._closed:
                raise RuntimeError(f"client of {self.topic} is closed")
            self._sequence += 1
            sequence = self._sequence
            sent = attachments.pack(sequence, int(self._clock()), self.gid)
            self._waiting.add(token)
        began = time.monotonic()
        try:
            replies = self._session.get(
                self.key,
                payload=payload,
                attachment=sent,
                target=zenoh.QueryTarget.ALL_COMPLETE,
                consolidation=zenoh.ConsolidationMode.NONE,
                timeout=QUERY_TIMEOUT_S if timeout is None else timeout,
                cancellation_token=token,
            )
            replied = timed_out = False
            for reply in replies:
                sample = reply.ok
                if sample is None and is_zenoh_timeout(reply):
                    timed_out = True
                    continue
                replied = True
                answer = self._answer(reply, sample, sequence)
                if answer is not _UNMATCHED:
                    return answer
        except zenoh.ZError as error:
            raise ServiceError(f"service {self.topic}: cannot send the request: {error}") from None
        finally:
            with self._lock:
                self._waiting.discard(token)
        if token.is_cancelled:
            raise ServiceCancelled(f"service {self.topic}: the call was cancelled")
        if timeout is not None and (timed_out or time.monotonic() - began >= timeout):
            raise ServiceTimeout(f"service {self.topic}: no response within {timeout} s")
        raise ServiceUnavailable(
            f"service {self.topic} ({self.service.name}): no server answered"
            if not replied
            else f"service {self.topic}: the reply could not be used"
        )

    def _answer(self, reply: zenoh.Reply, sample: zenoh.Sample | None, sequence: int) -> Any:
        """The response in a reply (``sample`` is its ``ok``) to call ``sequence``; ``_UNMATCHED`` for a reply
        to drop; raises ServiceError."""
        if sample is None:
            error = reply.err
            reason = error.payload.to_bytes().decode("utf-8", "replace") if error is not None else ""
            raise ServiceError(reason or f"service {self.topic}: the server replied an error")
        try:
            attachment = sample.attachment
            if attachment is None:
                raise AttachmentError("a reply without an attachment")
            answered, _, gid = attachments.unpack(attachment.to_bytes())
        except AttachmentError as error:
            log.debug("client of %s: dropped a reply: %s", self.topic, error)
            return _UNMATCHED
        if gid != self.gid or answered != sequence:
            with self._calls_lock:
                self.unmatched_replies += 1
            return _UNMATCHED
        try:
            return types.deserialize(sample.payload.to_bytes(), self.service.response)
        except types.CdrError as error:
            raise ServiceError(f"service {self.topic}: bad response: {error}") from None

    def call_async(self, request: Any) -> Call:
        """Send ``request`` now; the future holds the response or the ServiceError. Cancelling it abandons the call."""
        payload = types.serialize(request, self.service.request)
        with self._lock:
            if self._closed:
                raise RuntimeError(f"client of {self.topic} is closed")
            self._sequence += 1
            call = Call(self._sequence)
            sent = attachments.pack(call.sequence, int(self._clock()), self.gid)
        with self._calls_lock:
            self._calls[call.sequence] = call
        call.add_done_callback(self._done)
        try:
            self._session.get(
                self.key,
                zenoh.handlers.Callback(lambda r: self._on_reply(call, r), lambda: self._on_end(call), indirect=False),
                payload=payload,
                attachment=sent,
                target=zenoh.QueryTarget.ALL_COMPLETE,
                consolidation=zenoh.ConsolidationMode.NONE,
                timeout=QUERY_TIMEOUT_S,
                cancellation_token=call._query_cancel,
            )
        except zenoh.ZError as error:
            _settle(call, error=ServiceError(f"service {self.topic}: cannot send the request: {error}"))
        return call

    def _done(self, call: Future) -> None:
        assert isinstance(call, Call)
        with self._calls_lock:
            self._calls.pop(call.sequence, None)
        if call.cancelled():  # it may block on a running reply callback: not on the caller's thread
            threading.Thread(target=call._query_cancel.cancel, daemon=True).start()

    def _on_reply(self, call: Call, reply: zenoh.Reply) -> None:
        """Zenoh's thread: match the reply to its call by the sequence number in its attachment."""
        try:
            self._match(call, reply)
        except Exception:
            log.exception("client of %s: unexpected error", self.topic)

    def _match(self, sent: Call, reply: zenoh.Reply) -> None:
        replier = reply.replier_id
        if reply.err is not None:  # no attachment: it answers the call whose query it came on
            sent.replied, sent.replier = True, str(replier.zid) if replier is not None else None
            reason = reply.err.payload.to_bytes().decode("utf-8", "replace")
            _settle(sent, error=ServiceError(reason or f"service {self.topic}: the server replied an error"))
            return
        sample = reply.ok
        try:
            if sample is None or sample.attachment is None:
                raise AttachmentError("a reply without an attachment")
            answer = attachments.decode(sample.attachment.to_bytes())
        except AttachmentError as error:
            log.debug("client of %s: dropped a reply: %s", self.topic, error)
            return
        with self._calls_lock:
            call = self._calls.get(answer.sequence) if answer.gid == self.gid else None
            if call is None:
                self.unmatched_replies += 1
                return
        call.replied, call.replier = True, str(replier.zid) if replier is not None else None
        try:
            response = types.deserialize(sample.payload.to_bytes(), self.service.response)
        except types.CdrError as error:
            _settle(call, error=ServiceError(f"service {self.topic}: bad response: {error}"))
            return
        _settle(call, response)

    def _on_end(self, call: Call) -> None:
        """Zenoh's thread: the query is over; a call still unanswered got nothing."""
        _settle(
            call,
            error=ServiceUnavailable(
                f"service {self.topic} ({self.service.name}): no server answered"
                if not call.replied
                else f"service {self.topic}: the reply could not be used"
            ),
        )

    def close(self) -> None:
        """Leave the graph and fail the calls in flight."""
        super().close()
        with self._calls_lock:
            calls = list(self._calls.values())
        for call in calls:
            _settle(call, error=ServiceError(f"client of {self.topic} closed"))
        with self._lock:
            waiting = list(self._waiting)
        for token in waiting:
            token.cancel()


def server_token_pattern(domain_id: int, service: str, dds_type: str, type_hash: str) -> str:
    """The key expression every server token (``SS``) of one service name, type and hash matches."""
    node = f"{ADMIN_SPACE}/{domain_id}/*/*/*/{EntityKind.SERVICE.value}/*/*/*"
    return f"{node}/{mangle(service)}/{dds_type}/{type_hash}/*"


class ServerWatch:
    """The live servers of one service, by Zenoh session id, from their liveliness tokens.

    ``on_change(zid, alive)`` is called on Zenoh's thread when a session's first server of the
    service appears or its last one leaves (a closed node, a dead process); keep it quick.
    """

    def __init__(
        self,
        session: zenoh.Session,
        domain_id: int,
        service: str,
        dds_type: str,
        type_hash: str,
        on_change: Callable[[str, bool], None] | None = None,
    ) -> None:
        self.service = service
        self._tokens: dict[str, set[str]] = {}
        self._gone: set[str] = set()
        self._changed = threading.Condition()
        self._listeners: list[Callable[[str, bool], None]] = [on_change] if on_change is not None else []
        pattern = server_token_pattern(domain_id, service, dds_type, type_hash)
        self._subscriber = session.liveliness().declare_subscriber(pattern, self._on_token, history=True)

    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        try:
            zid = parse_token(key).zid
        except TokenError:
            return
        alive = sample.kind == zenoh.SampleKind.PUT
        with self._changed:
            before = bool(self._tokens.get(zid))
            tokens = self._tokens.setdefault(zid, set())
            (tokens.add if alive else tokens.discard)(key)
            now = bool(tokens)
            if not now:
                del self._tokens[zid]
                self._gone.add(zid)
            else:
                self._gone.discard(zid)
            self._changed.notify_all()
        if before != now:
            for listener in list(self._listeners):
                try:
                    listener(zid, now)
                except Exception:
                    log.exception("server watch of %s: a change callback raised", self.service)

    def listen(self, on_change: Callable[[str, bool], None]) -> None:
        """Also call ``on_change(zid, alive)`` on each change (on Zenoh's thread)."""
        self._listeners.append(on_change)

    def serving(self) -> bool:
        """Whether any session serves the service now (``zids`` without building the set)."""
        return bool(self._tokens)

    def zids(self) -> frozenset[str]:
        """The sessions that serve the service now."""
        with self._changed:
            return frozenset(self._tokens)

    def left(self, zid: str) -> bool:
        """Whether ``zid`` served the service and no longer does."""
        with self._changed:
            return zid in self._gone

    def wait(self, timeout: float | None = None) -> bool:
        """Whether a server is there, waiting up to ``timeout`` s (None: for ever) for one."""
        with self._changed:
            return self._changed.wait_for(lambda: bool(self._tokens), timeout)

    def undeclare(self) -> None:
        self._subscriber.undeclare()
