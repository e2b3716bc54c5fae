"""summary.json: the run's facts, its states and skill outcomes counted from the trace as it streams.

The ``SummaryObserver`` starts the summary when the run has finished (the core fields in their
fixed order); the backend, the services and other observers add their blocks after it, the
report lists the artefacts, and the ``SummaryFileObserver``, last, writes the file.
"""

from __future__ import annotations

import json
import time
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from botstage.behaviors.trace import jsonable

if TYPE_CHECKING:
    from botstage.missions.session.result import RunResult
    from botstage.missions.session.session import RunSession

FILE = "summary.json"
CORE = ("mission", "robot", "backend", "seed", "outcome", "reason", "sim_time_s", "wall_time_s", "ticks")


class TraceCounts:
    """States entered and skill outcomes, from trace events (streamed, or read back from a file)."""

    def __init__(self) -> None:
        self.entered: list[tuple[str, str]] = []  # (machine, state)
        self.outcomes: dict[str, Counter[str]] = defaultdict(Counter)

    def add(self, event: Mapping[str, Any]) -> None:
        kind = event["ev"]
        if kind == "transition" and event["dest"]:
            self.entered.append((event["machine"], event["dest"]))
        elif kind == "skill_outcome":
            self.outcomes[event["skill"]][event["outcome"]] += 1
        elif kind == "skill_cancel":
            self.outcomes[event["skill"]]["cancelled"] += 1

    def states_visited(self, root_machine: str) -> list[str]:
        """Entered states, the root machine's by name, nested ones as ``machine/state``."""
        return [dest if machine == root_machine else f"{machine}/{dest}" for machine, dest in self.entered]

    def skill_outcomes(self) -> dict[str, dict[str, int]]:
        return {skill: dict(sorted(c.items())) for skill, c in sorted(self.outcomes.items())}


def artefacts(folder: Path, also: Iterable[str] = ()) -> list[str]:
    """The run folder's files (but summary.json), and ``also`` (files about to be written)."""
    found = {str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and p.name != FILE}
    return sorted(found | set(also))


def core(folder: Path, counts: TraceCounts, fields: Mapping[str, Any]) -> dict[str, Any]:
    return {
        **{k: fields[k] for k in CORE},
        "mission_file": fields["mission_file"],  # what `botstage scenario from-trace` replays against
        "until": fields["until"],
        "states_visited": counts.states_visited(fields["mission"]),
        "skill_outcomes": counts.skill_outcomes(),
        "counters": fields["counters"],
        "artefacts": artefacts(folder),
    }


class SummaryObserver:
    """Counts the trace as it streams; when the run has finished, starts its summary."""

    name = "summary"

    def __init__(self) -> None:
        self.counts = TraceCounts()

    def event(self, record: dict[str, Any]) -> None:
        self.counts.add(record)

    def finished(self, session: RunSession, result: RunResult) -> None:
        mission = session.mission
        clock = session.clock
        summary = core(
            session.folder,
            self.counts,
            {
                "mission": mission.name,
                "robot": mission.robot,
                "backend": session.backend_name,
                "seed": session.seed,
                "outcome": result.outcome,
                "reason": result.reason,
                "sim_time_s": round(clock.now(), 6),
                "wall_time_s": round(time.perf_counter() - session.started_at, 3),
                "ticks": clock.ticks,
                "counters": session.counters,
                "mission_file": str(session.mission_file.resolve()),
                "until": session.until,
            },
        )
        if session.overrides:
            summary["blackboard_overrides"] = jsonable(session.overrides)  # what a replay must set again
        result.summary.update(summary)


class SummaryFileObserver:
    """Writes summary.json, after everything else has added to the summary."""

    name = "summary_file"

    def finished(self, session: RunSession, result: RunResult) -> None:
        text = json.dumps(result.summary, indent=2) + "\n"
        (session.folder / FILE).write_text(text, encoding="utf-8")
