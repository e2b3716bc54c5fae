"""What a run hands back: its outcome, its folder, its summary and the final blackboard."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

WALL_CLOCK_FIELDS = ("wall_time_s", "overruns")  # summary fields that differ between identical runs


@dataclass
class RunResult:
    outcome: str
    reason: str
    folder: Path
    summary: dict[str, Any]
    blackboard: dict[str, Any] = field(default_factory=dict)
