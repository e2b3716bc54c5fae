"""The live monitor as a run observer: the trace's events feed the pages' view of the run, the
operator's requests are carried out between ticks, and the robot's Display is watched so the
``/display`` page shows what it shows (on a robot without a screen of its own, that page is it).

It also leaves ``poses.csv`` in the run folder: the true pose and the localiser's estimate every
``POSE_EVERY_S`` of mission time, for the map of ``botstage monitor RUN_FOLDER``. Read from what is
already there between ticks, never from a device, so the trace is the same with or without it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import IO, TYPE_CHECKING, Any

import cv2

from botstage.behaviors.render import describe, to_plain
from botstage.missions.monitor.control import NODE, Control
from botstage.missions.monitor.hub import Hub
from botstage.missions.monitor.robot_view import POSES_FILE, POSES_HEADER, SAMPLE_S, pose_row, poses, robot_sample

FRAME_S = 0.2  # camera frames for the teleop view, at most 5 a second
POSE_EVERY_S = 0.2  # poses.csv: a row per this much mission time at most (18,000 rows an hour)

if TYPE_CHECKING:
    from botstage.missions.session.result import RunResult
    from botstage.missions.session.session import RunSession


class WatchedDisplay:
    """The robot's Display (or none), with every layout it is told to show told to the pages too."""

    def __init__(self, hub: Hub, inner: Any | None) -> None:
        self.hub = hub
        self.inner = inner

    def show(self, layout: str, **content: str) -> None:
        self.hub.shown(layout, content)
        if self.inner is not None:
            self.inner.show(layout, **content)

    def __getattr__(self, name: str) -> Any:  # anything else a display offers, as it is
        if self.inner is None:
            raise AttributeError(name)
        return getattr(self.inner, name)


class MonitorObserver:
    """Feeds a ``Hub`` and runs a ``Control`` for one run (see ``missions/session/observer.py``)."""

    name = "monitor"

    def __init__(self, hub: Hub | None = None, control: Control | None = None) -> None:
        self.hub = hub or Hub()
        self.control = control
        self._next_sample = 0.0
        self._next_frame = 0.0
        self._poses: IO[str] | None = None
        self._next_pose = 0.0

    def started(self, session: RunSession) -> None:
        assert session.root is not None and session.engine is not None and session.trace is not None
        mission = session.mission
        simulated = session.kind.simulated  # a simulated world can be held, even paced in real time
        self.hub.info = {
            "mode": "live",
            "mission": mission.name,
            "robot": mission.robot,
            "simulated": simulated,
            "rate_hz": mission.rate_hz,
        }
        self.hub.structure = to_plain(describe(session.root))
        if self.control is None:
            self.control = Control(self.hub, simulated)
        self.control.simulated = simulated
        self.control.started(session)
        self.control.on_change = self._held
        self.hub.grid = session.backend.grid if session.backend is not None else None
        self.hub.folder = session.folder
        self._sample(session)
        if session.backend is not None and session.folder is not None:
            self._poses = open(session.folder / POSES_FILE, "w", encoding="utf-8")  # noqa: SIM115 (closed in finished)
            self._poses.write(POSES_HEADER + "\n")
        trace = session.trace
        self.control.attach(lambda message: trace.emit("log", NODE, "info", message))
        interfaces = session.engine.interfaces
        if "display" in interfaces:
            interfaces["display"] = WatchedDisplay(self.hub, interfaces["display"])
        self.hub.ready.set()  # last: a request may now name anything the run has

    def event(self, record: Mapping[str, Any]) -> None:
        self.hub.apply(record)
        if self.control is not None:
            self.control.event(record)

    def before_tick(self, session: RunSession) -> None:
        if self.control is not None:
            self.control.before_tick(session)

    def after_tick(self, session: RunSession) -> None:
        if self.control is not None:
            self.control.after_tick(session)
        now = time.monotonic()  # the map is for eyes: sampled in wall time, not every tick
        if now >= self._next_sample:
            self._next_sample = now + SAMPLE_S
            self._sample(session)
        if self._poses is not None:  # the record is in mission time: the same rows however fast
            t = self.hub.flags.t
            if t >= self._next_pose:
                self._next_pose = t + POSE_EVERY_S - 1e-6  # 0.2 s: every other tick at 10 Hz
                self._poses.write(pose_row(self.hub.flags.tick, t, *poses(session)) + "\n")

    def _sample(self, session: RunSession) -> None:
        control = self.control
        teleop = {"active": False, "v": 0.0, "w": 0.0, "allowed": False, "why": ""}
        if control is not None:
            allowed, why = control.teleop_allowed()
            teleop = {**control.teleop_state, "allowed": allowed, "why": why}
        self.hub.set_robot(robot_sample(session, teleop, self.hub.camera[1]))

    def _held(self, session: RunSession) -> None:
        """While the run is held: the map follows, and when the page drives, the camera shows what
        the robot sees."""
        now = time.monotonic()
        camera = session.interfaces.get("camera")
        driven = self.control is not None and self.control.teleop_state["active"]
        if camera is not None and driven and now >= self._next_frame:
            self._next_frame = now + FRAME_S
            frame = camera.frame()
            if frame is not None:
                ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 80])
                if ok:
                    self.hub.set_camera(jpeg.tobytes())
        self._sample(session)

    def finished(self, session: RunSession, result: RunResult) -> None:
        if self._poses is not None:
            self._poses.close()
            self._poses = None
        self.hub.set_flags(ended=True, paused=False, outcome=result.outcome)
        if self.control is not None:
            self.control.close()
