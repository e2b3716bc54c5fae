"""A snapshot of the ROS 2 graph: the live liveliness tokens of one domain, read as ROS 2 tools read them.

``ros2 node list`` is the nodes; ``ros2 topic list -t`` is the topics of publishers and
subscriptions with their types; ``ros2 service list -t`` the same for servers and clients.
Keys that are not valid tokens are kept aside with the reason, never silently lost.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from botstage.robots.ros2.liveliness import EntityKind, GraphEntity, TokenError, parse_token
from botstage.robots.ros2.types import ros_type_name

_TOPIC_KINDS = (EntityKind.PUBLISHER, EntityKind.SUBSCRIPTION)
_SERVICE_KINDS = (EntityKind.SERVICE, EntityKind.CLIENT)


def _type_name(dds_type: str) -> str:
    """The ROS name of a type, or the DDS name as it is when it is not a ROS type (as rmw_zenoh shows it)."""
    try:
        return ros_type_name(dds_type)
    except ValueError:
        return dds_type


@dataclass(frozen=True)
class Graph:
    """The entities of a domain's live tokens, and the keys that were not tokens (key, reason)."""

    entities: tuple[GraphEntity, ...] = ()
    rejected: tuple[tuple[str, str], ...] = field(default=())

    @classmethod
    def from_tokens(cls, keys: Iterable[str]) -> Graph:
        """The graph these liveliness keys describe (duplicates count once)."""
        entities: dict[str, GraphEntity] = {}
        rejected: list[tuple[str, str]] = []
        for key in keys:
            try:
                entities.setdefault(key, parse_token(key))
            except TokenError as error:
                rejected.append((key, str(error)))
        return cls(tuple(entities[k] for k in sorted(entities)), tuple(rejected))

    def node_names(self) -> list[str]:
        """The fully-qualified names of the nodes, sorted (as ``ros2 node list``)."""
        return sorted({e.node_fqn for e in self.entities if e.kind is EntityKind.NODE})

    def _names_and_types(self, kinds: tuple[EntityKind, ...]) -> dict[str, list[str]]:
        found: dict[str, set[str]] = {}
        for entity in self.entities:
            if entity.kind in kinds and entity.topic and entity.dds_type:
                found.setdefault(entity.topic, set()).add(_type_name(entity.dds_type))
        return {name: sorted(types) for name, types in sorted(found.items())}

    def topic_names_and_types(self) -> dict[str, list[str]]:
        """Each topic with a publisher or a subscription, and its types (as ``ros2 topic list -t``)."""
        return self._names_and_types(_TOPIC_KINDS)

    def service_names_and_types(self) -> dict[str, list[str]]:
        """Each service with a server or a client, and its types (as ``ros2 service list -t``)."""
        return self._names_and_types(_SERVICE_KINDS)

    def endpoints(self, topic: str, kind: EntityKind) -> list[GraphEntity]:
        """The publishers (or subscriptions, servers, clients) of one topic or service."""
        return [e for e in self.entities if e.kind is kind and e.topic == topic]
