"""The built-in observers every run has: the backend's results, the clock's overruns, the
transcript and the report (the summary's are in ``summary.py``), and a scenario's tick hook.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from botstage.missions.session.summary import artefacts
from botstage.missions.transcript import Transcriber, write_transcript

if TYPE_CHECKING:
    from botstage.behaviors.engine import Engine
    from botstage.missions.session.result import RunResult
    from botstage.missions.session.session import RunSession


class BackendObserver:
    """The backend's files (a simulation's trajectory.csv) and its block, under its name."""

    name = "backend"

    def finished(self, session: RunSession, result: RunResult) -> None:
        backend = session.backend
        if backend is None:
            return
        backend.write_results(session.folder)
        result.summary[session.backend_name] = backend.summary()


class ClockObserver:
    """How often a wall-clock run's ticks ended late, and the worst lateness."""

    name = "clock"

    def finished(self, session: RunSession, result: RunResult) -> None:
        overruns = getattr(session.clock, "overruns", None)
        if overruns is not None:
            result.summary["overruns"] = {"count": overruns.count, "worst_s": round(overruns.worst_s, 4)}


class TranscriptObserver:
    """transcript.jsonl: who said what, collected from the trace as the run goes."""

    name = "transcript"

    def __init__(self) -> None:
        self.transcriber = Transcriber()

    def event(self, record: dict[str, Any]) -> None:
        self.transcriber.add(record)

    def finished(self, session: RunSession, result: RunResult) -> None:
        write_transcript(session.folder, self.transcriber.lines())


class ReportObserver:
    """report.html, from the finished summary (artefacts listed, report.html among them)."""

    name = "report"

    def finished(self, session: RunSession, result: RunResult) -> None:
        from botstage.missions.report import write_report  # matplotlib and friends load only when reporting

        summary = result.summary
        summary["artefacts"] = artefacts(session.folder, also=["report.html"])
        if session.observer_errors:
            summary["observer_errors"] = list(session.observer_errors)
        write_report(session.folder, session.checked, summary)


class EventRecorder:
    """Keeps every trace event of a run in memory as it happens (what a scenario judges, and
    what coverage counts), so nothing reads the trace file back."""

    name = "recorder"

    def __init__(self) -> None:
        self.events: list[dict[str, Any]] = []

    def event(self, record: dict[str, Any]) -> None:
        self.events.append(record)


class BeforeTickHook:
    """A scenario's ``before_tick(engine)``: scripted events and `never` conditions (may raise StopRun)."""

    name = "before_tick"

    def __init__(self, hook: Callable[[Engine], None]) -> None:
        self.hook = hook

    def before_tick(self, session: RunSession) -> None:
        assert session.engine is not None
        self.hook(session.engine)
