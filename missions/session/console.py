"""``--observe console``: the run's states and skill outcomes printed as they happen (stderr)."""

from __future__ import annotations

import sys
from typing import IO, Any


class ConsoleLog:
    """state changes and skill outcomes, printed to stderr as they happen"""

    name = "console"

    def __init__(self, stream: IO[str] | None = None) -> None:
        self.stream = stream

    def event(self, record: dict[str, Any]) -> None:
        kind = record["ev"]
        if kind == "transition" and record["dest"]:
            line = f"{record['machine']}: {record['source'] or '-'} -> {record['dest']} ({record['trigger']})"
        elif kind == "skill_outcome":
            reason = f": {record['reason']}" if record["reason"] else ""
            line = f"{record['node']}: {record['outcome']}{reason}"
        elif kind == "error":
            line = f"error: {record['reason']}"
        else:
            return
        stream = self.stream or sys.stderr
        stream.write(f"{record['t']:9.1f} s  {line}\n")
        stream.flush()
