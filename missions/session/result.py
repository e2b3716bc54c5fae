"""What a run hands back: its outcome, its folder, its summary and the final blackboard; and the
exit status `botstage run` gives for it, so that scripts and CI can tell how a mission ended."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

WALL_CLOCK_FIELDS = ("wall_time_s", "overruns")  # summary fields that differ between identical runs

# `botstage run`'s exit statuses (docs/reference/exit-status.md says the same)
EXIT_OK = 0  # the mission succeeded, or ran until its time limit
EXIT_NOT_RUN = 1  # nothing ran: the mission is invalid, or a file could not be read or written
EXIT_USAGE = 2  # a bad option or argument (typer's usage errors too)
EXIT_FAILURE = 3  # the mission ended in failure: `failure`, or a machine outcome that is not its success
EXIT_RUN_ERROR = 4  # the run stopped on an error of its own (outcome `error`)
EXIT_INTERRUPTED = 130  # Ctrl-C or SIGTERM (outcome `interrupted`), as a shell reports SIGINT


@dataclass
class RunResult:
    outcome: str
    reason: str
    folder: Path
    summary: dict[str, Any]
    blackboard: dict[str, Any] = field(default_factory=dict)
    # how what the mission runs ended: True success, False failure, None not ended (time limit, stop)
    succeeded: bool | None = None

    @property
    def exit_status(self) -> int:
        return exit_status(self.outcome, self.succeeded)


def exit_status(outcome: str, succeeded: bool | None) -> int:
    """0 for success or the time limit; a distinct status for failure, an error, an interruption."""
    if outcome == "interrupted":
        return EXIT_INTERRUPTED
    if outcome == "error":
        return EXIT_RUN_ERROR
    if succeeded is True or (succeeded is None and outcome == "time_limit"):
        return EXIT_OK
    return EXIT_FAILURE
