"""One event stream for a run: ticks, node statuses, transitions, skills and blackboard writes.

Events are kept as plain records and serialised to JSON lines with a fixed field order and no
wall-clock values, so the same seed and mission give a byte-identical trace.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import IO, Any

from botstage.robots.clock import Clock

Listener = Callable[[dict[str, Any]], None]

# The fields of each event kind, in output order. Events are stored as flat tuples of values
# (tuples of atoms are untracked by Python's cyclic GC, so millions of them stay cheap).
FIELDS: dict[str, tuple[str, ...]] = {
    "tick": (),
    "tick_end": ("status",),
    "status": ("node", "old", "new", "reason"),
    "skill_start": ("node", "skill", "inputs"),
    "skill_outcome": ("node", "skill", "outcome", "reason", "outputs"),
    "skill_cancel": ("node", "skill", "reason"),
    "bb_write": ("key", "old", "new", "writer"),
    "transition": ("machine", "source", "dest", "trigger", "reason"),
    "log": ("node", "level", "message"),
    "error": ("reason",),
}
_SCALARS = (str, int, bool, type(None))


def jsonable(value: Any, _depth: int = 0) -> Any:
    """A JSON-compatible copy of ``value`` that is the same in every run (no ids, no addresses)."""
    if isinstance(value, _SCALARS):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if _depth > 8:
        return "..."
    if isinstance(value, Mapping):
        return {str(k): jsonable(v, _depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v, _depth + 1) for v in value]
    if isinstance(value, set | frozenset):
        return sorted((jsonable(v, _depth + 1) for v in value), key=repr)
    shape = getattr(value, "shape", None)
    if shape is not None and hasattr(value, "dtype"):  # numpy arrays and images
        if getattr(value, "size", 0) <= 16:
            return jsonable(value.tolist(), _depth + 1)
        return f"<array shape={tuple(shape)} dtype={value.dtype}>"
    dump = getattr(value, "model_dump", None)  # pydantic models
    if callable(dump):
        return jsonable(dump(), _depth + 1)
    return f"<{type(value).__name__}>"


ARITY = {kind: len(fields) for kind, fields in FIELDS.items()}


class Trace:
    """Collects events; optionally streams them to a JSONL file as it goes.

    ``emit`` is on the hot path (several events per skill run). Events are appended to one
    flat list of values (tick, t, kind, fields...), which holds no container per event, so
    Python's cyclic GC has nothing new to scan however long the run; they become dicts only
    when read, listened to or written.
    """

    def __init__(
        self, clock: Clock, sink: IO[str] | None = None, *, keep: bool = True, flush_every: int = 4096
    ) -> None:
        self.clock = clock
        self.keep = keep
        self._sink = sink
        self._flush_every = flush_every
        self._flat: list[Any] = []
        self._unwritten: list[Any] = []
        self._unwritten_count = 0
        self._dicts: list[dict[str, Any]] = []
        self._decoded = 0  # position in _flat up to which _dicts is built
        self._listeners: list[Listener] = []
        self._tick = -1
        self._t = 0.0
        self.count = 0

    def subscribe(self, listener: Listener) -> None:
        self._listeners.append(listener)

    def emit(self, ev: str, *values: Any) -> None:
        """Record an event of a kind in ``FIELDS``, its values given in that order."""
        if len(values) != ARITY[ev]:
            raise ValueError(f"trace event {ev!r} takes {ARITY[ev]} values ({', '.join(FIELDS[ev])})")
        clock = self.clock
        tick = clock.ticks
        if tick != self._tick:  # one timestamp per tick: deterministic and cheap
            self._tick = tick
            self._t = round(clock.now(), 6)
        self.count += 1
        if self.keep:
            self._flat += (tick, self._t, ev, *values)
        if self._sink is not None:
            self._unwritten += (tick, self._t, ev, *values)
            self._unwritten_count += 1
            if self._unwritten_count >= self._flush_every:
                self.flush()
        if self._listeners:
            record = {"tick": tick, "t": self._t, "ev": ev}
            record.update(zip(FIELDS[ev], values, strict=False))
            for listener in self._listeners:
                listener(record)

    @property
    def events(self) -> list[dict[str, Any]]:
        """Every kept event as a dict ``{tick, t, ev, ...fields}`` (treat them as read-only)."""
        if self._decoded < len(self._flat):
            self._decoded = _decode(self._flat, self._decoded, self._dicts.append)
        return self._dicts

    def of(self, *kinds: str) -> list[dict[str, Any]]:
        return [e for e in self.events if e["ev"] in kinds]

    def flush(self) -> None:
        if self._sink is None or not self._unwritten:
            return
        lines: list[str] = []
        _decode(self._unwritten, 0, lambda record: lines.append(dumps(record) + "\n"))
        self._sink.write("".join(lines))
        self._sink.flush()
        self._unwritten.clear()
        self._unwritten_count = 0

    def to_jsonl(self) -> str:
        return "".join(dumps(e) + "\n" for e in self.events)

    def write(self, path: str | Path) -> None:
        Path(path).write_text(self.to_jsonl(), encoding="utf-8")


def _decode(flat: list[Any], position: int, out: Callable[[dict[str, Any]], None]) -> int:
    end = len(flat)
    while position < end:
        tick, t, ev = flat[position], flat[position + 1], flat[position + 2]
        names = FIELDS[ev]
        record = {"tick": tick, "t": t, "ev": ev}
        record.update(zip(names, flat[position + 3 : position + 3 + len(names)], strict=True))
        out(record)
        position += 3 + len(names)
    return position


def dumps(event: Mapping[str, Any]) -> str:
    return json.dumps(event, separators=(",", ":"), ensure_ascii=False, default=jsonable, allow_nan=False)


def read_jsonl(path: str | Path) -> list[dict[str, Any]]:
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def by_kind(events: Iterable[Mapping[str, Any]], *kinds: str) -> list[Mapping[str, Any]]:
    return [e for e in events if e["ev"] in kinds]
