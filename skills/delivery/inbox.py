"""The order inbox: orders that arrive while a mission runs, as files in its run folder.

``botstage order TABLE ITEM`` (or any program) drops one JSON file per order into
``<run folder>/inbox/``: it writes ``.<name>.tmp`` and renames it to ``<name>.json``, so a reader
never sees half an order (a rename is atomic within a file system). Names start with the
arrival time in nanoseconds, so sorting them gives arrival order.

The mission side (``OrderInbox.take``) reads the ``*.json`` files in name order, validates each,
and moves it to ``taken/`` or, when it is not a valid order, to ``rejected/`` with the reason
beside it: nothing is lost and nothing is read twice. On opening, the inbox writes
``accepts.json`` (the tables it serves), so a sender can refuse an unknown table before writing.

Only local files: no socket, nothing beyond the machine.
"""

from __future__ import annotations

import json
import os
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ACCEPTS = "accepts.json"
MAX_ITEM = 80


class OrderError(ValueError):
    """An order that cannot be served, with the reason."""


@dataclass(frozen=True, slots=True)
class Order:
    table: str
    item: str
    source: str = "mission"  # where it came from: the mission file, or the inbox file's name

    def as_dict(self) -> dict[str, Any]:
        return {"table": self.table, "item": self.item, "source": self.source}


def parse_order(value: Any, tables: list[str] | None, source: str = "mission") -> Order:
    """An order from a mapping ``{table, item}`` (or a ``[table, item]`` pair); ``OrderError`` if bad."""
    if isinstance(value, list | tuple) and len(value) == 2:
        value = {"table": value[0], "item": value[1]}
    if not isinstance(value, dict):
        raise OrderError(f"an order is {{table: ..., item: ...}} or [table, item], got {value!r}")
    extra = sorted(set(value) - {"table", "item", "source", "id"})
    if extra:
        raise OrderError(f"an order has only table and item, not {', '.join(map(str, extra))}")
    table, item = value.get("table"), value.get("item")
    if not isinstance(table, str) or not table.strip():
        raise OrderError(f"an order needs a table name, got {table!r}")
    if not isinstance(item, str) or not item.strip():
        raise OrderError(f"an order needs an item, got {item!r}")
    item = " ".join(item.split())
    if len(item) > MAX_ITEM or not item.isprintable():
        raise OrderError(f"an item is at most {MAX_ITEM} printable characters, got {item[:MAX_ITEM]!r}...")
    table = table.strip()
    if tables is not None and table not in tables:
        raise OrderError(f"unknown table {table!r} (tables: {', '.join(tables) or 'none'})")
    return Order(table, item, str(value.get("source", source)))


class OrderInbox:
    """One run's inbox folder; nothing touches the disk until ``open``."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.opened = False
        self.tables: list[str] | None = None  # None: any table
        self.taken = 0
        self.rejected: list[dict[str, str]] = []

    def open(self, tables: list[str] | None) -> None:
        """Create the folders and say which tables are served, None for any (blocking: from ``ctx.submit``)."""
        for sub in ("", "taken", "rejected"):
            (self.folder / sub).mkdir(parents=True, exist_ok=True)
        self.tables = None if tables is None else list(tables)
        write_atomically(self.folder / ACCEPTS, json.dumps({"tables": self.tables, "pid": os.getpid()}))
        self.opened = True

    def take(self) -> list[Order]:
        """The orders that arrived since the last call, in arrival order (blocking: file I/O)."""
        if not self.opened:
            raise RuntimeError("the order inbox is not open")
        orders = []
        for path in sorted(self.folder.glob("*.json")):
            if path.name == ACCEPTS:
                continue
            try:
                value = json.loads(path.read_text(encoding="utf-8"))
                order = parse_order(value, self.tables, source=path.name)
            except (OSError, UnicodeDecodeError, json.JSONDecodeError, OrderError) as exc:
                reason = f"{type(exc).__name__}: {exc}" if not isinstance(exc, OrderError) else str(exc)
                path.replace(self.folder / "rejected" / path.name)
                write_atomically(self.folder / "rejected" / (path.name + ".reason"), reason + "\n")
                self.rejected.append({"file": path.name, "reason": reason})
                continue
            path.replace(self.folder / "taken" / path.name)
            self.taken += 1
            orders.append(order)
        return orders


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to a hidden temporary file beside ``path``, flush it to disk, rename it."""
    temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    with temporary.open("w", encoding="utf-8") as handle:
        handle.write(text)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(temporary, path)
