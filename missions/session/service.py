"""Run services: what a run gives skills beyond the robot's devices (uploads, the run folder's
files, the order inbox, localisation and navigation), opened for every run.

A service is built without arguments (one per run), then ``open(session)`` returns the interfaces
it adds (name -> object, after the backend's devices); ``close()`` releases them after the
engine stopped and before the backend closes. A service may also have any observer hook
(``missions/session/observer.py``): ``after_tick`` runs after the world moved, in the order the
services were registered (the robot's localisation first, then uploads), and ``finished`` adds
its block to summary.json.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from botstage.missions.session.session import RunSession


class RunService(Protocol):
    name: str

    def open(self, session: RunSession) -> Mapping[str, Any]:
        """The interfaces this service gives the run's skills."""
        ...

    def close(self) -> None:
        """Release what ``open`` took (the engine has stopped; the backend is still open)."""
        ...
