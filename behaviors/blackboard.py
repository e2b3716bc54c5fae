"""The mission's shared blackboard: py_trees' blackboard with namespaced, typed keys,
per-node access and an activity stream that also reaches the trace.

py_trees keeps one process-wide store, so each ``Blackboard`` lives under a namespace of its own
and two missions in one process never see each other's keys. Users and skills only ever see
relative keys such as ``battery_pct`` or ``robot/pose``.
"""

from __future__ import annotations

import itertools
import re
import unicodedata
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import py_trees

from botstage.behaviors.trace import Trace, jsonable
from botstage.skills.base import MISSING, check_type, type_name

_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
_instances = itertools.count()
READ = py_trees.common.Access.READ
WRITE = py_trees.common.Access.WRITE


class BlackboardError(Exception):
    """Base of every blackboard problem; the message is meant for users."""


class MissingKeyError(BlackboardError, KeyError):
    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class AccessError(BlackboardError, PermissionError):
    pass


class KeyTypeError(BlackboardError, TypeError):
    pass


def normalise_key(key: str) -> str:
    """``/robot/pose`` and ``robot/pose`` name the same key; anything else is an error.

    Each part is an identifier as Python has them (``電池`` too), normalised as Python normalises
    names (NFKC), so a key written in a mission and read by a condition is the same key."""
    if not isinstance(key, str):
        raise BlackboardError(f"a blackboard key must be a string, got {type(key).__name__}")
    rel = key.strip("/")
    if _KEY.match(rel):
        return rel
    rel = unicodedata.normalize("NFKC", rel)
    if not all(part.isidentifier() for part in rel.split("/")):
        raise BlackboardError(
            f"invalid blackboard key {key!r}: use identifiers separated by '/', e.g. 'robot/battery_pct'"
        )
    return rel


@dataclass(frozen=True, slots=True)
class Activity:
    tick: int
    kind: str  # write, read, denied, missing, type_error
    key: str
    client: str
    value: Any = None


class Blackboard:
    def __init__(self, trace: Trace | None = None, *, activity_size: int = 1000, record_reads: bool = False) -> None:
        self.namespace = f"/botstage{next(_instances)}"
        self.trace = trace
        self.record_reads = record_reads
        self.activity: deque[Activity] = deque(maxlen=activity_size)
        self._types: dict[str, Any] = {}
        self._docs: dict[str, str] = {}
        self._clients: list[py_trees.blackboard.Client] = []
        self._admin = py_trees.blackboard.Client(name="mission", namespace=self.namespace)
        self._clients.append(self._admin)
        self._written: set[str] = set()

    # -- declarations and privileged access (runner, events, tests) ------------------------

    def declare(self, key: str, type: Any = Any, default: Any = MISSING, doc: str = "") -> None:
        rel = normalise_key(key)
        self._types[rel] = type
        if doc:
            self._docs[rel] = doc
        if default is not MISSING:
            self.set(rel, default, writer="init")

    def declared_type(self, key: str) -> Any:
        return self._types.get(normalise_key(key), Any)

    @property
    def declared(self) -> Mapping[str, Any]:
        return self._types

    def set(self, key: str, value: Any, writer: str = "mission") -> None:
        rel = normalise_key(key)
        if not self._admin.is_registered(rel):
            self._admin.register_key(rel, access=WRITE)
        self._write(self._admin, rel, value, writer)

    def get(self, key: str, default: Any = MISSING) -> Any:
        rel = normalise_key(key)
        name = self._absolute(rel)
        if name in py_trees.blackboard.Blackboard.storage:
            return py_trees.blackboard.Blackboard.storage[name]
        if default is not MISSING:
            return default
        raise MissingKeyError(f"blackboard key {rel!r} was never written")

    def exists(self, key: str) -> bool:
        return self._absolute(normalise_key(key)) in py_trees.blackboard.Blackboard.storage

    def update(self, values: Mapping[str, Any], writer: str = "mission") -> None:
        for key, value in values.items():
            self.set(key, value, writer)

    def snapshot(self) -> dict[str, Any]:
        """Every key and its value, relative names, sorted."""
        prefix = self.namespace + "/"
        storage = py_trees.blackboard.Blackboard.storage
        return {k[len(prefix) :]: storage[k] for k in sorted(storage) if k.startswith(prefix)}

    @property
    def written_keys(self) -> set[str]:
        return set(self._written)

    # -- per node access ------------------------------------------------------------------

    def client(self, node: str, reads: Iterable[str] = (), writes: Iterable[str] = ()) -> NodeAccess:
        return NodeAccess(self, node, reads, writes)

    def close(self) -> None:
        """Forget this blackboard's keys and clients in py_trees' process-wide store."""
        storage = py_trees.blackboard.Blackboard.storage
        prefix = self.namespace + "/"
        for key in [k for k in storage if k.startswith(prefix)]:
            del storage[key]
        for client in self._clients:
            client.unregister(clear=False)
        self._clients.clear()

    # -- internals ------------------------------------------------------------------------

    def _absolute(self, rel: str) -> str:
        return f"{self.namespace}/{rel}"

    def _new_client(self, node: str) -> py_trees.blackboard.Client:
        client = py_trees.blackboard.Client(name=node, namespace=self.namespace)
        self._clients.append(client)
        return client

    def _record(self, kind: str, key: str, client: str, value: Any = None) -> None:
        tick = self.trace.clock.ticks if self.trace is not None else 0
        self.activity.append(Activity(tick, kind, key, client, value))

    def _write(self, client: py_trees.blackboard.Client, rel: str, value: Any, writer: str) -> None:
        declared = self._types.get(rel, Any)
        if declared is not Any:
            try:
                value = check_type(declared, value)
            except TypeError as exc:
                self._record("type_error", rel, writer, value)
                raise KeyTypeError(f"blackboard key {rel!r} is declared {type_name(declared)}: {exc}") from None
        name = self._absolute(rel)
        storage = py_trees.blackboard.Blackboard.storage
        old = storage.get(name)
        client.set(rel, value)
        self._written.add(rel)
        self._record("write", rel, writer, value)
        if self.trace is not None:
            self.trace.emit("bb_write", rel, jsonable(old), jsonable(value), writer)


class NodeAccess:
    """One node's view of the blackboard: it may read and write only the keys it declared."""

    __slots__ = ("_bb", "_client", "_reads", "_writes", "node")

    def __init__(self, bb: Blackboard, node: str, reads: Iterable[str], writes: Iterable[str]) -> None:
        self._bb = bb
        self.node = node
        self._reads = frozenset(normalise_key(k) for k in reads)
        self._writes = frozenset(normalise_key(k) for k in writes)
        self._client = bb._new_client(node) if (self._reads or self._writes) else None
        for key in self._reads - self._writes:
            self._client.register_key(key, access=READ)  # type: ignore[union-attr]
        for key in self._writes:
            self._client.register_key(key, access=WRITE)  # type: ignore[union-attr]

    @property
    def reads(self) -> frozenset[str]:
        return self._reads

    @property
    def writes(self) -> frozenset[str]:
        return self._writes

    def get(self, key: str) -> Any:
        rel = normalise_key(key)
        if rel not in self._reads and rel not in self._writes:
            self._bb._record("denied", rel, self.node)
            raise AccessError(f"node {self.node!r} may not read {rel!r}: it is not among its inputs")
        try:
            value = self._client.get(rel)  # type: ignore[union-attr]
        except KeyError:
            self._bb._record("missing", rel, self.node)
            raise MissingKeyError(
                f"blackboard key {rel!r} was read by {self.node!r} but nothing has written it"
            ) from None
        if self._bb.record_reads:
            self._bb._record("read", rel, self.node, value)
        return value

    def exists(self, key: str) -> bool:
        rel = normalise_key(key)
        return self._bb._absolute(rel) in py_trees.blackboard.Blackboard.storage

    def set(self, key: str, value: Any) -> None:
        rel = normalise_key(key)
        if rel not in self._writes:
            self._bb._record("denied", rel, self.node)
            raise AccessError(f"node {self.node!r} may not write {rel!r}: it is not among its outputs")
        self._bb._write(self._client, rel, value, self.node)  # type: ignore[arg-type]

    # -- BehaviorTree.CPP's UnsetBlackboard (behaviors/btcpp) removes a key --------------------

    def unset(self, key: str) -> bool:
        """Remove a key this node may write; False if it was not there."""
        rel = normalise_key(key)
        if rel not in self._writes:
            self._bb._record("denied", rel, self.node)
            raise AccessError(f"node {self.node!r} may not unset {rel!r}: it is not among its outputs")
        self._bb._record("unset", rel, self.node)
        return self._client.unset(rel)  # type: ignore[union-attr]
