"""Run a checked mission on the engine and leave its run folder.

The folder holds ``trace.jsonl`` (streamed while the mission runs), ``summary.json``,
``report.html`` and ``transcript.jsonl`` when anyone spoke, and the run's artefacts. The work is
done by a ``RunSession`` (``missions/session/``): phases, observers, services; ``run`` is its
front door, with the same arguments as ever.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from botstage.behaviors.engine import Engine
from botstage.behaviors.kinds import NodeKinds
from botstage.missions.loader import Loaded
from botstage.missions.session import (
    WALL_CLOCK_FIELDS,
    MissionInvalid,
    Progress,
    ProgressCallback,
    ProgressObserver,
    RunError,
    RunResult,
    RunSession,
    StopRun,
    build,
    run_folder,
    running_skills,
)
from botstage.robots.backend_registry import DEFAULT, BackendRegistry
from botstage.skills.registry import Registry

__all__ = [
    "WALL_CLOCK_FIELDS",
    "MissionInvalid",
    "Progress",
    "ProgressCallback",
    "RunError",
    "RunResult",
    "StopRun",
    "build",
    "run",
    "run_folder",
    "running_skills",
]


def run(
    path: str | Path,
    *,
    backend: str = DEFAULT,
    seed: int | None = None,
    until: float | None = None,
    realtime: bool = False,
    out: Path | None = None,
    progress: ProgressCallback | None = None,
    progress_interval_s: float = 0.1,
    registry: Registry | None = None,
    kinds: NodeKinds | None = None,
    blackboard: dict[str, Any] | None = None,
    before_tick: Callable[[Engine], None] | None = None,
    port: str | None = None,
    backend_options: Mapping[str, Any] | None = None,
    observers: Sequence[object] = (),
    backends: BackendRegistry | None = None,
    loaded: Loaded | None = None,
    record: Callable[[Path], Path] | None = None,
) -> RunResult:
    """Check and run a mission.

    Scenario tests pass a ``registry`` with mocks (``kinds``: node kinds beyond the installed ones),
    ``blackboard`` overrides of initial values and
    a ``before_tick`` hook (scripted events, `never` conditions); a hook may raise ``StopRun``.
    ``backend`` names an installed backend (``BackendRegistry``); wall-clock ones (``emulator``,
    ``hardware``) run in real time. Its options come from the robot profile's ``backends:``,
    then ``port`` (a shortcut for the hardware backend's ``port``), then ``backend_options``.
    ``loaded`` and ``record``: a mission in memory and how its run folder keeps it (``RunSession``).
    ``observers`` watch the run (``missions/session/observer.py``); ``progress`` is the live
    display's callback, given a snapshot maker every ``progress_interval_s``.
    """
    watching = list(observers)
    if progress is not None:
        watching.append(ProgressObserver(progress, progress_interval_s))
    session = RunSession(
        path,
        backend=backend,
        seed=seed,
        until=until,
        realtime=realtime,
        out=out,
        registry=registry,
        kinds=kinds,
        blackboard=blackboard,
        before_tick=before_tick,
        backend_options=backend_options,
        port=port,
        observers=watching,
        backends=backends,
        loaded=loaded,
        record=record,
    )
    return session.run()
