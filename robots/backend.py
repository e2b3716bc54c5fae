"""The one shape every robot backend has: the simulator, the emulated board, real hardware, plugins.

A run (or teleop) never asks which backend it has: it opens one by name through the registry
(``robots/backend_registry.py``) with an ``OpenRequest``, takes its ``devices``, steps it after
every tick, and closes it, which stops the robot whatever happened. A third-party package adds a
backend with a ``BackendKind`` subclass under the entry-point group ``botstage.backends``::

    [project.entry-points."botstage.backends"]
    gazebo = "my_package.backend:GazeboKind"
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict

if TYPE_CHECKING:  # kept light: listing the backends (the CLI's --help) loads no maps, numpy or profiles
    from botstage.robots.clock import Clock
    from botstage.robots.gridmap import GridMap
    from botstage.robots.interfaces import Pose2D
    from botstage.robots.located_yaml import Problem
    from botstage.robots.profile import Profile

ENTRY_POINT_GROUP = "botstage.backends"

Gathering = tuple[float, tuple[float, float], int, float]  # (time, centre, size, stay) of a scripted crowd


@dataclass(frozen=True)
class ScriptedWalk:
    """A simulated person who walks ``path`` (points in metres, on the map) at ``speed`` m/s from
    mission time ``at``, ``repeat`` times round, standing ``pause`` s at each point (a mission's
    ``walks:``; robots/sim/people.py walks it)."""

    path: tuple[tuple[float, float], ...]
    speed: float = 1.0
    at: float = 0.0
    repeat: int = 1
    pause: float = 0.0


Fault = Callable[..., None]  # injects one fault now; its docstring says what it does and takes


@dataclass(frozen=True)
class OpenRequest:
    """What the caller (a mission, teleop) gives every backend; a backend uses what it can."""

    profile: Profile
    start: Pose2D
    clock: Clock
    seed: int = 0
    grid: GridMap | None = None  # the map the robot is on (needed by simulated worlds and localisation)
    people: int = 0  # simulated people walking about
    gatherings: tuple[Gathering, ...] = ()
    walks: tuple[ScriptedWalk, ...] = ()  # simulated people who walk a given path
    voices: Mapping[str, Any] | None = None  # the simulator's voice settings (None: its defaults)


@runtime_checkable
class Backend(Protocol):
    """An open robot: its devices, and what a run does with it around every tick."""

    devices: dict[str, Any]
    """Interface name -> device (``drive``, ``odometry``, ``laser``, ...), as the profile lists them."""

    profile: Profile
    grid: GridMap | None

    @property
    def faults(self) -> Mapping[str, Fault]:
        """The faults it can inject by name (an emulator's garbage bytes, unplugging, ...); often none."""
        ...

    def step(self) -> None:
        """After each tick: move a simulated world over the tick's period (a real robot moves itself)."""
        ...

    def use_clock(self, clock: Clock) -> None:
        """Stamp readings with this clock from now on (a wall-clock run's, started once the robot is up)."""
        ...

    def true_pose(self) -> Pose2D | None:
        """Where the robot really is (a simulation knows); None on a real robot."""
        ...

    def close(self) -> None:
        """Stop the robot (zero velocity) and release the devices; safe on every exit path."""
        ...

    def summary(self) -> dict[str, Any]:
        """Its block of summary.json (distance, bumps, link statistics, ...)."""
        ...

    def write_results(self, folder: Path) -> None:
        """Leave its files in the run folder (a simulation's trajectory.csv), if it has any."""
        ...


class BackendOptions(BaseModel):
    """A backend's own options (from the robot profile's ``backends:`` or ``--backend-opt``)."""

    model_config = ConfigDict(extra="forbid", coerce_numbers_to_str=True)


class BackendKind:
    """A kind of backend as the registry lists it: name, description, clock, options and how to open one.

    ``simulated`` kinds run on the simulated clock (faster than real time, deterministic); the
    others pace a wall clock and need a robot (the run refuses a robot-less mission on them).
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    simulated: ClassVar[bool] = False
    Options: ClassVar[type[BackendOptions]] = BackendOptions

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        """The open backend; ``ValueError``/``ConnectionError``/``OSError`` say why it cannot open."""
        raise NotImplementedError

    profile_section: ClassVar[str] = ""  # the profile's section this backend reads, if any (``ros2``)

    def check_profile(self, profile: Profile) -> list[tuple[tuple[str, ...], str, str]]:
        """Problems with this backend's own section of ``profile``: (where under the profile,
        message, hint). The core checks a profile's shape; each backend checks what it reads."""
        return []

    def describe(self) -> dict[str, Any]:
        """Name, description, clock and options (with their types, defaults and descriptions)."""
        options = {}
        for key, field in self.Options.model_fields.items():
            kind = getattr(field.annotation, "__name__", str(field.annotation))
            options[key] = {
                "type": kind,
                "required": field.is_required(),
                "default": None if field.is_required() else field.default,
                "description": field.description or "",
            }
        return {"name": self.name, "description": self.description, "simulated": self.simulated, "options": options}


class BackendError(Exception):
    """A backend cannot be chosen or opened as asked: a ``message``, and ``problems`` located in a
    file (the robot profile's options), either of which may be empty."""

    def __init__(self, message: str, problems: list[Problem] | None = None) -> None:
        self.message = message
        self.problems = list(problems or [])
        super().__init__("\n".join([*([message] if message else []), *map(str, self.problems)]))

    def lines(self) -> list[str]:
        """One line per problem, as a command line prints them: located ones, then ``error: ...``."""
        return [str(p) for p in self.problems] + [f"error: {line}" for line in self.message.splitlines()]
