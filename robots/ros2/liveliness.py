"""rmw_zenoh's liveliness tokens: how a node, publisher, subscription, server or client says it exists.

A token is a key expression under the hermetic ``@ros2_lv`` chunk::

    @ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP|MS|SS|SC>/<enclave>/<namespace>/<node>
        [/<topic>/<dds type>/<type hash>/<qos>]

names mangled (``/`` -> ``%``), the last four chunks only for entities with a topic or service.
ROS 2's graph (``ros2 node list``, ``ros2 topic list -t``) is the set of live tokens. Parsing
follows rmw_zenoh's ``Entity::make``: it accepts the tokens of any implementation that rmw_zenoh
accepts (ids need not be numbers, extra trailing chunks are ignored) and rejects the rest with a
TokenError saying why, so one odd peer never hides the rest of the graph.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from botstage.robots.ros2 import qos as qos_strings
from botstage.robots.ros2.names import (
    check_domain_id,
    demangle,
    mangle,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
)
from botstage.robots.ros2.qos import QoS

ADMIN_SPACE = "@ros2_lv"
NODE_CHUNKS = 9
ENTITY_CHUNKS = 13


class EntityKind(Enum):
    """What a token stands for, by its two-letter code."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE = "SS"
    CLIENT = "SC"


class TokenError(ValueError):
    """A key under ``@ros2_lv`` that is not a liveliness token rmw_zenoh would accept."""


@dataclass(frozen=True, slots=True)
class GraphEntity:
    """One live entity of the ROS 2 graph, as a token describes it (names demangled)."""

    domain_id: int
    zid: str
    node_id: str
    entity_id: str
    kind: EntityKind
    enclave: str
    namespace: str
    node_name: str
    topic: str | None = None  # fully-qualified topic or service name
    dds_type: str | None = None
    type_hash: str | None = None
    qos: QoS | None = None

    @property
    def node_fqn(self) -> str:
        """The node's fully-qualified name (``/talker``, ``/robot1/talker``)."""
        return f"/{self.node_name}" if self.namespace == "/" else f"{self.namespace.rstrip('/')}/{self.node_name}"


def graph_key(domain_id: int) -> str:
    """The key expression every token of a domain matches (for ``liveliness().get`` and subscribers)."""
    return f"{ADMIN_SPACE}/{check_domain_id(domain_id)}/**"


def _id_chunk(what: str, value: int | str) -> str:
    text = str(value)
    if not text or "/" in text or any(c in text for c in "*$?#"):
        raise ValueError(f"{what} {value!r} cannot be one key expression chunk")
    return text


def node_token(domain_id: int, zid: str, node_id: int | str, namespace: str, node_name: str, enclave: str = "/") -> str:
    """The token of a node (the node id stands in the entity id's place too, as rmw_zenoh does)."""
    return _token(domain_id, zid, node_id, node_id, EntityKind.NODE, enclave, namespace, node_name)


def entity_token(
    domain_id: int,
    zid: str,
    node_id: int | str,
    entity_id: int | str,
    kind: EntityKind,
    namespace: str,
    node_name: str,
    topic: str,
    dds_type: str,
    type_hash: str,
    qos: QoS,
    enclave: str = "/",
) -> str:
    """The token of a publisher, subscription, service server or client of a node."""
    if kind is EntityKind.NODE:
        raise ValueError("a node's token has no topic: use node_token")
    validate_full_topic_name(topic)
    tail = [mangle(topic), _id_chunk("DDS type name", dds_type), _id_chunk("type hash", type_hash)]
    tail.append(qos_strings.encode(qos))
    return _token(domain_id, zid, node_id, entity_id, kind, enclave, namespace, node_name, tail)


def _token(
    domain_id: int,
    zid: str,
    node_id: int | str,
    entity_id: int | str,
    kind: EntityKind,
    enclave: str,
    namespace: str,
    node_name: str,
    tail: list[str] | None = None,
) -> str:
    check_domain_id(domain_id)
    validate_namespace(namespace)
    validate_node_name(node_name)
    if not enclave.startswith("/"):
        raise ValueError(f"enclave {enclave!r}: must be absolute ('/' by default)")
    chunks = [ADMIN_SPACE, str(domain_id), _id_chunk("zenoh id", zid), _id_chunk("node id", node_id)]
    chunks += [_id_chunk("entity id", entity_id), kind.value, mangle(enclave), mangle(namespace), node_name]
    return "/".join(chunks + (tail or []))


def parse_token(key: str) -> GraphEntity:
    """The entity a liveliness token describes, or a TokenError with the reason it is not one."""
    chunks = str(key).split("/")
    if chunks[0] != ADMIN_SPACE:
        raise TokenError(f"{key!r}: not under {ADMIN_SPACE}")
    if len(chunks) < NODE_CHUNKS:
        raise TokenError(f"{key!r}: {len(chunks)} chunks, a token has at least {NODE_CHUNKS}")
    if "" in chunks:
        raise TokenError(f"{key!r}: empty chunk at position {chunks.index('')}")
    domain, zid, node_id, entity_id, code, enclave, namespace, node_name = chunks[1:NODE_CHUNKS]
    if not (domain.isascii() and domain.isdigit()):
        raise TokenError(f"{key!r}: domain id {domain!r} is not a number")
    try:
        kind = EntityKind(code)
    except ValueError:
        raise TokenError(f"{key!r}: unknown entity kind {code!r} (one of NN, MP, MS, SS, SC)") from None
    node = dict(
        domain_id=int(domain),
        zid=zid,
        node_id=node_id,
        entity_id=entity_id,
        kind=kind,
        enclave=demangle(enclave),
        namespace=demangle(namespace),
        node_name=demangle(node_name),
    )
    if kind is EntityKind.NODE:
        return GraphEntity(**node)
    if len(chunks) < ENTITY_CHUNKS:
        raise TokenError(f"{key!r}: a {kind.name.lower()} token has {ENTITY_CHUNKS} chunks, this one {len(chunks)}")
    topic, dds_type, type_hash, qos_text = chunks[NODE_CHUNKS:ENTITY_CHUNKS]
    try:
        qos = qos_strings.decode(qos_text)
    except ValueError as error:
        raise TokenError(f"{key!r}: {error}") from None
    return GraphEntity(**node, topic=demangle(topic), dds_type=demangle(dds_type), type_hash=type_hash, qos=qos)
