"""A plain blackboard for running a skill outside the engine (the skill's BlackboardView): the
benchmarks' and the tests' harnesses drive skills with it, without a tree around them."""

from __future__ import annotations

from typing import Any


class DictBoard:
    def __init__(self) -> None:
        self.values: dict[str, Any] = {}

    def get(self, key: str) -> Any:
        return self.values[key]

    def set(self, key: str, value: Any) -> None:
        self.values[key] = value

    def exists(self, key: str) -> bool:
        return key in self.values
