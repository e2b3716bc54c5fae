"""A ROS 2 node over Zenoh in rmw_zenoh's wire format: what makes a botstage process a node of a ROS 2 graph.

A ``Ros2Node`` owns one Zenoh session (as an rmw_zenoh context does) and declares its node
token; its publishers put CDR with rmw_zenoh's attachment on the topic's data key and declare
``MP`` tokens, its subscriptions declare ``MS`` tokens and decode what arrives. Other ROS 2 nodes
(rmw_zenoh, or any implementation of its format) see them in ``ros2 node list`` and
``ros2 topic list -t`` and exchange messages with them.

The session listens on loopback by default with multicast scouting off: nothing is reachable
beyond this machine unless asked for. Peers find each other by connecting to a listening
endpoint; in ``router`` mode on ``tcp/127.0.0.1:7447`` a node stands in for rmw_zenohd, so ROS 2
nodes started with their default configuration find it and each other through it.

Subscription callbacks run on Zenoh's threads. A sample without a valid attachment or with bad
CDR is dropped and counted (an rmw_zenoh subscriber drops the former too); a callback that raises
is counted and logged. Nothing raises into Zenoh.

Durability ``transient_local`` uses Zenoh's advanced publisher (a cache of ``depth`` samples) and
subscriber (history from late-joining publishers), as rmw_zenoh does. Deadline, lifespan and
liveliness are advertised in the tokens but not enforced.
"""

from __future__ import annotations

import itertools
import json
import logging
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import zenoh
from zenoh import ext as zenoh_ext

from botstage.robots.ros2 import attachment as attachments
from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment, AttachmentError
from botstage.robots.ros2.entity import _Entity
from botstage.robots.ros2.graph import Graph
from botstage.robots.ros2.liveliness import EntityKind, graph_key, node_token
from botstage.robots.ros2.names import check_domain_id, node_fqn
from botstage.robots.ros2.qos import Durability, History, QoS, Reliability

log = logging.getLogger(__name__)

DEFAULT_LISTEN = "tcp/127.0.0.1:0"  # loopback, a port the system picks
ROUTER_LISTEN = "tcp/127.0.0.1:7447"  # where rmw_zenoh's nodes look for rmw_zenohd by default
SPORADIC_HEARTBEAT_S = 0.5  # rmw_zenoh's period for reliable transient-local miss detection

Mode = Literal["peer", "router"]
Clock = Callable[[], int]
Callback = Callable[[Any, Attachment], None]


def session_config(
    listen: Sequence[str] = (DEFAULT_LISTEN,),
    connect: Sequence[str] = (),
    mode: Mode = "peer",
    options: Mapping[str, Any] | None = None,
    *,
    allow_remote: bool = False,
) -> zenoh.Config:
    """A Zenoh configuration: the given endpoints, multicast scouting off, then ``options`` (path -> value).

    Listening beyond loopback is refused (``security.ListenError``) unless ``allow_remote`` asks
    for it and ``options`` demand mutual TLS (robots/ros2/security.py).
    """
    from botstage.robots.ros2.security import check_listen  # certificates' imports only where sessions open

    if mode not in ("peer", "router"):
        raise ValueError(f"Zenoh mode {mode!r}: botstage nodes are 'peer' or 'router'")
    check_listen(listen, options, allow_remote=allow_remote)
    config = zenoh.Config()
    settings: dict[str, Any] = {
        "mode": mode,
        "scouting/multicast/enabled": False,
        "listen/endpoints": list(listen),
        "connect/endpoints": list(connect),
    }
    settings.update(options or {})
    for path, value in settings.items():
        config.insert_json5(path, json.dumps(value))
    return config


@dataclass(frozen=True, slots=True)
class SubscriptionStats:
    """What a subscription received: delivered to the callback, or dropped and why."""

    received: int = 0
    no_attachment: int = 0
    bad_attachment: int = 0
    bad_cdr: int = 0
    callback_errors: int = 0
    wrong_key: int = 0  # put on a wildcard that covers the topic: not a publication of it

    @property
    def dropped(self) -> int:
        """Samples that never reached the callback."""
        return self.no_attachment + self.bad_attachment + self.bad_cdr + self.wrong_key


class Publisher(_Entity):
    """Publishes messages of one type on one topic, each with its attachment (sequence from 1)."""

    kind = EntityKind.PUBLISHER

    def __init__(self, node: Ros2Node, entity_id: int, topic: str, type_name: str, qos: QoS) -> None:
        super().__init__(node, entity_id, topic, type_name, qos)
        self._clock = node.clock
        self._sequence = 0
        self._publisher = self._declare_publisher(node.session)
        self._declared.append(self._publisher)
        self._declare_token()

    def _declare_publisher(self, session: zenoh.Session) -> Any:
        q = self.qos
        reliable = q.reliability is Reliability.RELIABLE
        block = reliable and q.history is History.KEEP_ALL
        options: dict[str, Any] = {
            "reliability": zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT,
            "congestion_control": zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP,
        }
        if q.durability is not Durability.TRANSIENT_LOCAL:
            return session.declare_publisher(self.key, **options)
        detection = zenoh_ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=SPORADIC_HEARTBEAT_S)
        return zenoh_ext.declare_advanced_publisher(
            session,
            self.key,
            cache=zenoh_ext.CacheConfig(q.depth),
            publisher_detection=True,
            sample_miss_detection=detection if reliable else None,
            **options,
        )

    @property
    def sequence(self) -> int:
        """The sequence number of the last message published (0 before the first)."""
        return self._sequence

    def publish(self, message: Any) -> Attachment:
        """Serialise and send ``message``; returns the attachment it went with."""
        payload = types.serialize(message, self.type_name)
        with self._lock:
            if self._closed:
                raise RuntimeError(f"publisher on {self.topic} is closed")
            self._sequence += 1
            sent = Attachment(self._sequence, int(self._clock()), self.gid)
            self._publisher.put(payload, attachment=attachments.encode(sent))
        return sent


class Subscription(_Entity):
    """Receives messages of one type on one topic and hands each to ``callback(message, attachment)``."""

    kind = EntityKind.SUBSCRIPTION

    def __init__(
        self, node: Ros2Node, entity_id: int, topic: str, type_name: str, callback: Callback, qos: QoS
    ) -> None:
        super().__init__(node, entity_id, topic, type_name, qos)
        self._callback = callback
        self._stats_lock = threading.Lock()
        self._stats = SubscriptionStats()
        self._declared.append(self._declare_subscriber(node.session))
        self._declare_token()

    def _declare_subscriber(self, session: zenoh.Session) -> Any:
        q = self.qos
        if q.durability is not Durability.TRANSIENT_LOCAL:
            return session.declare_subscriber(self.key, self._on_sample)
        recovery = None
        if q.reliability is Reliability.RELIABLE:
            recovery = zenoh_ext.RecoveryConfig(periodic_queries=None, heartbeat=True)
        return zenoh_ext.declare_advanced_subscriber(
            session,
            self.key,
            self._on_sample,
            history=zenoh_ext.HistoryConfig(detect_late_publishers=True, max_samples=q.depth),
            recovery=recovery,
            subscriber_detection=True,
        )

    @property
    def stats(self) -> SubscriptionStats:
        """A snapshot of the counts."""
        with self._stats_lock:
            return self._stats

    def _count(self, **deltas: int) -> None:
        with self._stats_lock:
            self._stats = replace(self._stats, **{k: getattr(self._stats, k) + v for k, v in deltas.items()})

    def _on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh's thread: decode, deliver, and never let anything escape."""
        try:
            self._deliver(sample)
        except Exception:  # a bug of ours must not kill Zenoh's thread either
            log.exception("subscription on %s: unexpected error", self.topic)

    def _deliver(self, sample: zenoh.Sample) -> None:
        if self._closed:
            return
        if str(sample.key_expr) != self.key:  # a put on `0/**` would pass an ACL denying `0/cmd_vel/**`
            self._count(wrong_key=1)
            log.debug("%s: dropped a sample put on %s, not on the topic's key", self.topic, sample.key_expr)
            return
        if sample.attachment is None:
            self._count(no_attachment=1)
            log.debug("%s: dropped a sample without an attachment", self.topic)
            return
        try:
            received = attachments.decode(sample.attachment.to_bytes())
        except AttachmentError as error:
            self._count(bad_attachment=1)
            log.debug("%s: dropped a sample: %s", self.topic, error)
            return
        try:
            message = types.deserialize(sample.payload.to_bytes(), self.type_name)
        except types.CdrError as error:
            self._count(bad_cdr=1)
            log.debug("%s: dropped a sample: %s", self.topic, error)
            return
        self._count(received=1)
        try:
            self._callback(message, received)
        except Exception:
            self._count(callback_errors=1)
            log.exception("subscription on %s: the callback raised", self.topic)


class Ros2Node:
    """A ROS 2 node on its own Zenoh session, in rmw_zenoh's wire format."""

    def __init__(
        self,
        name: str,
        namespace: str = "/",
        *,
        domain_id: int = 0,
        listen: Sequence[str] = (DEFAULT_LISTEN,),
        connect: Sequence[str] = (),
        mode: Mode = "peer",
        clock: Clock = time.time_ns,
        enclave: str = "/",
        options: Mapping[str, Any] | None = None,
        allow_remote: bool = False,
    ) -> None:
        """Open the session and declare the node.

        ``clock`` gives the source timestamps of publications, in ns since the epoch as ROS 2
        expects (a simulation passes its own). ``options`` are further Zenoh settings by path;
        ``allow_remote`` lets it listen beyond loopback (with mutual TLS in ``options`` only).
        """
        self.fqn = node_fqn(namespace, name)  # validates both before anything opens
        self.name, self.namespace, self.enclave = name, namespace, enclave
        self.domain_id = check_domain_id(domain_id)
        self.clock = clock
        self.node_id = 0  # one node per session: its entities count from 1
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._entities: list[_Entity] = []
        self.session = zenoh.open(session_config(listen, connect, mode, options, allow_remote=allow_remote))
        self.zid = str(self.session.zid())
        try:
            self.token = node_token(self.domain_id, self.zid, self.node_id, namespace, name, enclave)
            self._node_token = self.session.liveliness().declare_token(self.token)
        except Exception:
            self.session.close()
            raise
        self._closed = False

    def __enter__(self) -> Ros2Node:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"node {self.fqn} is closed")

    def _add(self, make: Callable[[int], _Entity]) -> Any:
        with self._lock:
            self._check_open()
            entity = make(next(self._ids))
            self._entities.append(entity)
            return entity

    def _forget(self, entity: _Entity) -> None:
        with self._lock:
            if entity in self._entities:
                self._entities.remove(entity)

    def publisher(self, topic: str, type_name: str, qos: QoS | None = None) -> Publisher:
        """A publisher of ``type_name`` messages on ``topic`` (relative names are in the node's namespace)."""
        return self._add(lambda i: Publisher(self, i, topic, type_name, qos or QoS()))

    def subscription(self, topic: str, type_name: str, callback: Callback, qos: QoS | None = None) -> Subscription:
        """A subscription handing each ``type_name`` message on ``topic`` to ``callback(message, attachment)``."""
        return self._add(lambda i: Subscription(self, i, topic, type_name, callback, qos or QoS()))

    def service(
        self,
        name: str,
        type_name: str,
        handler: Callable[[Any], Any],
        qos: QoS | None = None,
        *,
        deferred: bool = False,
    ) -> Any:
        """A server of ``type_name`` (``pkg/srv/S``) on ``name``: ``handler(request)`` returns the response.

        The handler runs on the server's own thread (robots.ros2.service); ``deferred=True`` hands
        it a PendingRequest to answer later instead.
        """
        from botstage.robots.ros2.service import ServiceServer

        return self._add(lambda i: ServiceServer(self, i, name, type_name, handler, qos or QoS(), deferred))

    def client(self, name: str, type_name: str, qos: QoS | None = None) -> Any:
        """A client of the ``type_name`` service on ``name`` (robots.ros2.service.ServiceClient)."""
        from botstage.robots.ros2.service import ServiceClient

        return self._add(lambda i: ServiceClient(self, i, name, type_name, qos or QoS()))

    def action_server(self, name: str, type_name: str, **callbacks: Any) -> Any:
        """A server of the ``type_name`` action (``pkg/action/A``) on ``name`` (robots.ros2.action.ActionServer).

        ``callbacks`` and options are ActionServer's (``on_goal``, ``on_cancel``, ``on_accepted``, …).
        """
        from botstage.robots.ros2.action import ActionServer

        self._check_open()
        return ActionServer(self, name, type_name, **callbacks)

    def action_client(self, name: str, type_name: str) -> Any:
        """A client of the ``type_name`` action on ``name`` (robots.ros2.action.ActionClient)."""
        from botstage.robots.ros2.action import ActionClient

        self._check_open()
        return ActionClient(self, name, type_name)

    def graph(self, timeout: float = 2.0) -> Graph:
        """The domain's ROS 2 graph as the live tokens say now (this node's own included).

        ``timeout`` bounds the wait for answers, in seconds; the query ends sooner when every
        peer has answered.
        """
        self._check_open()
        keys = [
            str(reply.ok.key_expr)
            for reply in self.session.liveliness().get(graph_key(self.domain_id), timeout=timeout)
            if reply.ok is not None
        ]
        return Graph.from_tokens(keys)

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Undeclare every entity and the node (the graph forgets them), then close the session."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            entities = list(self._entities)
        try:
            for entity in entities:
                entity.close()
            self._node_token.undeclare()
        finally:
            self.session.close()  # whatever happened above: a session left open keeps the process alive
