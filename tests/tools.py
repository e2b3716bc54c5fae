"""System tools some tests need: skipped with a reason outside CI, required under CI=true."""

from __future__ import annotations

import os
import shutil
from typing import Any

import pytest


def require(tool: str, package: str) -> str:
    path = shutil.which(tool)
    if path is None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{tool} is not installed; CI must install the Debian package {package}")
        pytest.skip(f"{tool} is not installed (Debian package {package}; CI installs it)")
    return path


class DictBoard:
    """A plain blackboard for running a skill outside the engine (the skill's BlackboardView)."""

    def __init__(self) -> None:
        self.values: dict[str, Any] = {}

    def get(self, key: str) -> Any:
        return self.values[key]

    def set(self, key: str, value: Any) -> None:
        self.values[key] = value

    def exists(self, key: str) -> bool:
        return key in self.values
