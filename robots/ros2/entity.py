"""What a node's publishers, subscriptions, services and clients share: a topic or service name, a
type, a liveliness token, and undeclaring once. Apart from the node so that the service and
action modules, which the node creates on demand, need not import the node back."""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any

import zenoh

from botstage.robots.ros2 import attachment as attachments
from botstage.robots.ros2 import types
from botstage.robots.ros2.liveliness import EntityKind, entity_token
from botstage.robots.ros2.names import data_key, fully_qualified_name
from botstage.robots.ros2.qos import QoS

if TYPE_CHECKING:
    from botstage.robots.ros2.node import Ros2Node

log = logging.getLogger(__name__)


class _Entity:
    """What publishers and subscriptions share: a topic, a type, a token, and undeclaring once."""

    kind: EntityKind

    def __init__(self, node: Ros2Node, entity_id: int, topic: str, type_name: str, qos: QoS) -> None:
        self.topic = fully_qualified_name(topic, node.namespace, node.name)
        self.type_name = type_name
        self.qos = qos.resolved()
        dds_type, type_hash = types.dds_type_name(type_name), types.type_hash(type_name)
        self.key = data_key(node.domain_id, self.topic, dds_type, type_hash)
        self.token = entity_token(
            node.domain_id,
            node.zid,
            node.node_id,
            entity_id,
            self.kind,
            node.namespace,
            node.name,
            self.topic,
            dds_type,
            type_hash,
            self.qos,
            node.enclave,
        )
        self.gid = attachments.entity_gid(self.token)
        self._node = node
        self._declared: list[Any] = []
        self._closed = False
        # held while a Zenoh entity is used and while it is undeclared: Zenoh refuses to undeclare
        # a publisher in the middle of a put on another thread ("Already borrowed")
        self._lock = threading.Lock()

    def _declare_token(self) -> None:
        """Declared last, as rmw_zenoh does: whoever sees the token can already reach the entity."""
        self._declared.insert(0, self._node.session.liveliness().declare_token(self.token))

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Undeclare the token (the graph forgets the entity), then the Zenoh entity."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            for declared in self._declared:
                try:
                    declared.undeclare()
                except zenoh.ZError as error:  # the session closed under us: nothing left to undeclare
                    log.debug("undeclaring %s on %s: %s", self.kind.name.lower(), self.topic, error)
        self._node._forget(self)
