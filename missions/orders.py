"""`botstage order TABLE ITEM`: hand an order to a running mission through its run folder's inbox.

A mission that takes orders (the ``take_order`` skill) opens ``<run folder>/inbox/`` and writes
``accepts.json`` there with the tables it serves; a run is running while its folder has no
``summary.json`` (the runner writes it last). The order is checked against the tables before
anything is written, then dropped in atomically (``skills/delivery/inbox.py``): a bad order is an
error here, never a file the mission has to throw away.
"""

from __future__ import annotations

import json
import os
import time
import uuid
from pathlib import Path

from botstage.skills.delivery.inbox import ACCEPTS, OrderError, parse_order, write_atomically


def running_inboxes(runs: Path) -> list[Path]:
    """The open inboxes of runs under ``runs`` that have not finished, newest first."""
    found = [
        accepts.parent
        for accepts in runs.glob(f"*/inbox/{ACCEPTS}")
        if not (accepts.parent.parent / "summary.json").exists()
    ]
    return sorted(found, key=lambda inbox: (inbox / ACCEPTS).stat().st_mtime, reverse=True)


def find_inbox(run: Path | None, runs: Path = Path("runs")) -> Path:
    """The inbox of the given run folder, else of the newest running mission under ``runs``."""
    if run is not None:
        inbox = run / "inbox"
        if (run / "summary.json").exists():
            raise OrderError(f"the run in {run} has finished (it has a summary.json): it takes no more orders")
        if not (inbox / ACCEPTS).exists():
            raise OrderError(f"{run} has no open order inbox (is its mission taking orders yet?)")
        return inbox
    inboxes = running_inboxes(runs)
    if not inboxes:
        raise OrderError(f"no running mission takes orders under {runs}/ (start one, or give its folder with --run)")
    return inboxes[0]


def served_tables(inbox: Path) -> list[str] | None:
    """The tables the inbox's mission serves (None: any)."""
    try:
        accepts = json.loads((inbox / ACCEPTS).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise OrderError(f"cannot read {inbox / ACCEPTS}: {exc}") from None
    tables = accepts.get("tables") if isinstance(accepts, dict) else None
    return None if tables is None else [str(table) for table in tables]


def post_order(inbox: Path, table: str, item: str) -> Path:
    """Check the order against the inbox's tables and drop it in; the file it became."""
    order = parse_order({"table": table, "item": item}, served_tables(inbox), source="cli")
    # the arrival time first, so the mission reads orders in the order they came
    path = inbox / f"{time.time_ns():020d}-{os.getpid()}-{uuid.uuid4().hex[:8]}.json"
    write_atomically(path, json.dumps({"table": order.table, "item": order.item}))
    return path
