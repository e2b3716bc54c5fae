"""For testing a skill on its own, without a tree around it (a plugin author's unit tests, and
botstage's own tests and benchmarks): a plain dict as the skill's blackboard view."""

from __future__ import annotations

from typing import Any


class DictBoard:
    """The ``ctx.blackboard`` a skill sees, as a dict (``values``) a test can read and preset."""

    def __init__(self) -> None:
        self.values: dict[str, Any] = {}

    def get(self, key: str) -> Any:
        return self.values[key]

    def set(self, key: str, value: Any) -> None:
        self.values[key] = value

    def exists(self, key: str) -> bool:
        return key in self.values
