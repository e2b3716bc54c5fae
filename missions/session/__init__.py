"""A run of a mission as a session: phases, observers of the run, and the services it opens."""

from botstage.missions.session.errors import MissionInvalid, RunError, StopRun
from botstage.missions.session.observer import RunObserver
from botstage.missions.session.plugins import PluginRegistry, observer_registry, service_registry
from botstage.missions.session.progress import Progress, ProgressCallback, ProgressObserver, running_skills
from botstage.missions.session.result import WALL_CLOCK_FIELDS, RunResult
from botstage.missions.session.service import RunService
from botstage.missions.session.session import RunSession, build, run_folder

__all__ = [
    "WALL_CLOCK_FIELDS",
    "MissionInvalid",
    "PluginRegistry",
    "Progress",
    "ProgressCallback",
    "ProgressObserver",
    "RunError",
    "RunObserver",
    "RunResult",
    "RunService",
    "RunSession",
    "StopRun",
    "build",
    "observer_registry",
    "run_folder",
    "running_skills",
    "service_registry",
]
