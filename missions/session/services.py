"""The built-in run services, registered under ``botstage.services`` like any plugin's.

Their order is the order of after-tick work, which the trace depends on: the world has moved
(the session steps the backend), then the robot's estimates update, then uploads settle.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from botstage.missions.services import RobotServices
from botstage.missions.session.uploads import fill_counters, run_uploads
from botstage.skills.delivery.inbox import OrderInbox
from botstage.skills.files import RunFiles

if TYPE_CHECKING:
    from botstage.missions.session.result import RunResult
    from botstage.missions.session.session import RunSession
    from botstage.skills.outbox.service import Uploads


class RobotService:
    """localization, navigation and people_tracking over the backend's devices, on the run's map."""

    name = "robot"

    def __init__(self) -> None:
        self.services: RobotServices | None = None

    def open(self, session: RunSession) -> Mapping[str, Any]:
        backend = session.backend
        if backend is None or backend.grid is None:
            return {}  # a robot-less mission, or a robot with no map: nothing to localise against
        self.services = RobotServices.for_robot(backend.devices, backend.grid, backend.profile, session.clock)
        return self.services.interfaces

    def after_tick(self, session: RunSession) -> None:
        if self.services is not None:
            for update in self.services.updates:
                update()

    def close(self) -> None:
        if self.services is not None:
            self.services.close()

    def finished(self, session: RunSession, result: RunResult) -> None:
        if self.services is None or self.services.localizer is None:
            return
        truth = session.backend.true_pose() if session.backend is not None else None
        result.summary["localization"] = self.services.summary(truth)


class UploadsService:
    """uploads: the upload skill's outboxes (and the run's own gallery), opened only when used."""

    name = "uploads"

    def __init__(self) -> None:
        self.uploads: Uploads | None = None

    def open(self, session: RunSession) -> Mapping[str, Any]:
        self.uploads = run_uploads(session.folder, session.clock, session.seed, session.interfaces)
        return {"uploads": self.uploads}

    def after_tick(self, session: RunSession) -> None:
        if self.uploads is not None:
            self.uploads.after_tick()

    def resting(self) -> bool:
        """Whether after_tick has nothing to do until a skill records another photo."""
        return self.uploads is None or self.uploads.resting()

    def close(self) -> None:
        if self.uploads is not None:
            self.uploads.close()  # uploads in flight get a few seconds; pending photos stay in the outbox

    def finished(self, session: RunSession, result: RunResult) -> None:
        if self.uploads is None or not self.uploads.used:
            return
        summary = self.uploads.summary()
        result.summary["upload"] = summary
        fill_counters(result.summary["counters"], summary)


class FilesService:
    """files: the run folder, where skills write photos and other artefacts."""

    name = "files"

    def open(self, session: RunSession) -> Mapping[str, Any]:
        return {"files": RunFiles(session.folder)}

    def close(self) -> None:
        """Nothing to release: every write is finished when it returns."""


class OrdersService:
    """orders: the inbox `botstage order` posts to (inbox/ in the run folder)."""

    name = "orders"

    def open(self, session: RunSession) -> Mapping[str, Any]:
        return {"orders": OrderInbox(session.folder / "inbox")}

    def close(self) -> None:
        """Nothing to release: orders are files, read when a skill asks."""
