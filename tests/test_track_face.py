"""track_face on the sim clock: the real cascade on drawn faces, a pan joint that turns the view.

The camera draws the simulator's person (``robots/sim/camera.py``'s ``draw_person``) 2 m away at
a bearing in the room; where the face lands in the image depends on the pan's present angle, so
the loop is closed as on the robot: the skill detects, steps the pan, the pan turns at its joint
speed, the next frame shows the face nearer the centre. Nothing sleeps; no timing is asserted.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from botstage.robots.clock import SimClock
from botstage.robots.interfaces import CameraInfo, Pan
from botstage.robots.profile import Device
from botstage.robots.sim.camera import CameraView, draw_person
from botstage.skills.base import Outcome, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.registry import Registry
from botstage.skills.testing import DictBoard
from botstage.skills.track_face import FaceTrackParams, TrackFace
from botstage.skills.workers import Workers

WIDTH, HEIGHT, FOV = 640, 480, 1.085
FOCAL = (WIDTH / 2) / math.tan(FOV / 2)
DISTANCE = 2.0  # m: the cascade (30 px at least, 15 neighbours) finds the drawn face from 1 to 2 m
BAND = math.atan(50 / FOCAL)  # the dead band's half-width as an angle: 0.094 rad


class FakePan:
    """A pan joint turning towards its goal at the AX-12A's joint speed (1.17 rad/s)."""

    def __init__(self, speed: float = 1.17, limit: float = 1.0) -> None:
        self.angle = 0.0
        self.goal = 0.0
        self.speed = speed
        self.limit = limit
        self.plugged = True
        self.commands: list[float] = []

    @property
    def min_angle(self) -> float:
        return -self.limit

    @property
    def max_angle(self) -> float:
        return self.limit

    def move_to(self, angle: float) -> bool:
        if not self.plugged:
            return False
        self.goal = max(-self.limit, min(self.limit, angle))
        self.commands.append(angle)
        return True

    def position(self) -> float | None:
        return self.angle if self.plugged else None

    def advance(self, dt: float) -> None:
        change = self.goal - self.angle
        self.angle += max(-self.speed * dt, min(self.speed * dt, change))


class PanCamera:
    """640x480 frames of a person at ``bearing`` (rad, positive left; None: nobody), seen through the pan.

    A new frame every ``frame_ticks`` ticks; between them the same (read-only) array, as the
    simulator's and the USB camera's drivers return."""

    def __init__(self, clock: SimClock, pan: FakePan, frame_ticks: int = 1) -> None:
        self.clock = clock
        self.pan = pan
        self.frame_ticks = frame_ticks
        self.info = CameraInfo(WIDTH, HEIGHT, FOV)
        self.bearing: float | None = 0.0
        self.renders = 0
        self.xs: list[float | None] = []  # where each frame shows the face (None: not in the image)
        self._frame: np.ndarray | None = None
        self._at = -1
        view = CameraView(Device(width=WIDTH, height=HEIGHT, field_of_view=FOV, mount_height=1.5))
        packed = np.ascontiguousarray(view.background)  # the simulator's ceiling and floor, BGR + a spare byte
        self._background = np.ascontiguousarray(packed.view(np.uint8).reshape(HEIGHT, WIDTH, 4)[:, :, :3])

    def face_x(self) -> float | None:
        if self.bearing is None:
            return None
        relative = self.bearing - self.pan.angle
        return WIDTH / 2 - FOCAL * math.tan(relative) if abs(relative) < 1.4 else None

    def frame(self) -> np.ndarray:
        tick = self.clock.ticks - self.clock.ticks % self.frame_ticks
        if tick != self._at:
            image = self._background.copy()
            x = self.face_x()
            if x is not None and -100 < x < WIDTH + 100:
                draw_person(image, x, HEIGHT / 2, FOCAL / DISTANCE, 3, 1.5)
            image.setflags(write=False)
            self._frame, self._at = image, tick
            self.renders += 1
            self.xs.append(x if x is not None and 0 <= x < WIDTH else None)
        assert self._frame is not None
        return self._frame


class Rig:
    """The sim clock, a dict blackboard and the worker pool, drained each tick as the engine does."""

    def __init__(self, rate_hz: float = 10.0, frame_ticks: int = 1) -> None:
        self.clock = SimClock(rate_hz)
        self.pan = FakePan()
        self.camera = PanCamera(self.clock, self.pan, frame_ticks)
        self.board = DictBoard()
        self.workers = Workers()
        self.logs: list[str] = []
        self.writes: list[tuple[float, str, Any]] = []
        board_set = self.board.set

        def record(key: str, value: Any) -> None:
            self.writes.append((self.clock.now(), key, value))
            board_set(key, value)

        self.board.set = record  # type: ignore[method-assign]

    def start(self, skill: TrackFace | None = None, **inputs: Any) -> tuple[SkillExecution, Outcome | None]:
        skill = skill or TrackFace()
        ctx = SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger(skill.name, sink=lambda node, level, message: self.logs.append(message)),
            blackboard=self.board,
            workers=self.workers,
            interfaces={"camera": self.camera, "pan": self.pan},
            rng=random.Random(0),
        )
        execution = SkillExecution(skill, ctx)
        return execution, execution.start(inputs)

    def tick(self, execution: SkillExecution) -> Outcome | None:
        self.workers.drain()
        self.clock.next_tick()
        self.pan.advance(self.clock.period)
        return execution.step()

    def ticks(self, execution: SkillExecution, seconds: float, each: Callable[[float], None] | None = None) -> None:
        for _ in range(round(seconds / self.clock.period)):
            if each is not None:
                each(self.clock.now())
            assert self.tick(execution) is None, "the skill ended early"

    def seen(self) -> list[tuple[float, bool]]:
        return [(t, value) for t, key, value in self.writes if key == "face_seen"]


def test_it_is_a_registered_skill_that_needs_a_camera_and_a_pan() -> None:
    assert Registry.builtin().get("track_face") is TrackFace
    assert isinstance(FakePan(), Pan)
    ctx = SkillContext(SimClock(), TrackFace().params, SkillLogger("t"), DictBoard(), Workers(), {"pan": FakePan()})
    outcome = SkillExecution(TrackFace(), ctx).start({})
    assert outcome is not None and outcome.name == "failure" and "no 'camera' interface" in outcome.reason


def test_a_face_on_the_left_is_brought_into_the_dead_band_step_by_step() -> None:
    rig = Rig()
    rig.camera.bearing = 0.3  # 164 px left of the centre at the start
    execution, _ = rig.start()
    rig.ticks(execution, 4.0)
    angles = [0.0, *rig.pan.commands]
    steps = np.diff(angles)
    assert np.all(steps >= 0) and np.all(steps <= 0.01 + 1e-9)  # the chapter's step, always to the left
    assert abs(rig.camera.face_x() - WIDTH / 2) <= 50  # type: ignore[operator]
    assert 0.3 - BAND - 0.02 <= rig.pan.angle <= 0.3  # just inside the band's edge, not beyond the face
    assert rig.board.values["face_seen"] is True
    assert abs(rig.board.values["face_error"]) <= 60 and rig.board.values["pan_angle"] > 0.15


def test_a_face_in_the_dead_band_is_left_alone() -> None:
    rig = Rig()
    rig.camera.bearing = -0.07  # 37 px right of the centre: inside 270-370
    execution, _ = rig.start()
    rig.ticks(execution, 3.0)
    assert rig.pan.commands == [0.0]  # the start position only
    assert rig.board.values["face_seen"] is True
    assert rig.board.values["face_error"] == pytest.approx(37, abs=3)


def test_each_frame_is_analysed_once_when_frames_come_slower_than_ticks() -> None:
    rig = Rig(rate_hz=30.0, frame_ticks=3)  # a 10 fps camera under a 30 Hz tick
    rig.camera.bearing = 0.45  # 0.36 rad from the band: more than 3 s of 0.01 rad steps at 10 fps
    execution, _ = rig.start(duration=3.0)
    outcome = None
    while outcome is None:
        outcome = rig.tick(execution)
    assert outcome.name == "success"
    assert outcome.outputs["frames"] in (rig.camera.renders, rig.camera.renders - 1)  # the last may be unread
    assert 25 <= outcome.outputs["frames"] <= 31
    assert outcome.outputs["detections"] == outcome.outputs["frames"]  # the face is in every frame
    steps = rig.pan.commands[1:-1]  # after the start, before the hold at the end
    assert len(steps) == outcome.outputs["frames"]  # one step a frame, none in the ticks between


def test_a_lost_face_is_swept_for_and_tracked_again() -> None:
    rig = Rig()
    rig.camera.bearing = 0.0
    execution, _ = rig.start(lost_after=1.0)

    def walk_off_left(t: float) -> None:  # 0.5 rad/s: faster than 0.01 rad a frame can follow
        rig.camera.bearing = 0.5 * (t - 1.0) if t > 1.0 else 0.0
        if t > 4.0:
            rig.camera.bearing = None  # gone out of the door

    rig.ticks(execution, 6.0, walk_off_left)
    seen = rig.seen()
    assert seen[0] == (0.0, False) and seen[1][1] is True and seen[-1][1] is False  # found, then lost
    assert any("the face lost for 1 s: sweeping" in line and "left first" in line for line in rig.logs)
    rig.ticks(execution, 6.0)
    commands = rig.pan.commands
    assert 0.5 in commands and -0.5 in commands  # the sweep goes out to each limit,
    assert commands.index(0.5) < commands.index(-0.5)  # the left one first
    assert rig.board.values["face_seen"] is False

    rig.camera.bearing = -0.25  # someone comes back, on the right
    found: list[float] = []

    def watch(t: float) -> None:
        if rig.board.values["face_seen"] and not found:
            found.append(t)

    rig.ticks(execution, 12.0, watch)
    assert found, "the face was never found again"
    assert abs(rig.camera.face_x() - WIDTH / 2) <= 50  # type: ignore[operator]  # tracked into the band
    assert abs(rig.pan.angle + 0.25) <= BAND + 0.02
    assert any("a face at x" in line and "tracking" in line for line in rig.logs[-3:])


def test_the_proportional_step_recentres_a_face_at_the_edge_in_fewer_frames() -> None:
    def frames_to_centre(mode: str) -> int:
        rig = Rig()
        rig.camera.bearing = 0.45  # 275 px left: 45 px from the image's edge
        execution, _ = rig.start(TrackFace({"mode": mode}))
        for frame in range(100):
            rig.tick(execution)
            if abs(rig.camera.face_x() - WIDTH / 2) <= 50:  # type: ignore[operator]
                return frame
        raise AssertionError(f"{mode}: not re-centred in 100 frames")

    fixed, proportional = frames_to_centre("fixed"), frames_to_centre("proportional")
    assert proportional < fixed / 2


def test_duration_ends_with_success_and_cancelling_holds_the_pan() -> None:
    rig = Rig()
    rig.camera.bearing = None
    execution, _ = rig.start(duration=2.5)
    outcome = None
    while outcome is None:
        outcome = rig.tick(execution)
    assert rig.clock.now() == pytest.approx(2.5)
    assert outcome.name == "success" and outcome.outputs["detections"] == 0 and outcome.outputs["sweeps"] == 1
    assert outcome.outputs["seen"] is False and rig.pan.goal == rig.pan.angle  # held where it was

    rig = Rig()
    rig.camera.bearing = None
    execution, _ = rig.start()  # until cancelled
    rig.ticks(execution, 3.0)  # sweeping, still running
    assert rig.pan.goal != rig.pan.angle  # the sweep's next angle is on its way
    assert execution.cancel() is None
    assert rig.pan.goal == rig.pan.angle  # stopped where it was, sent as the goal

    rig = Rig()
    rig.pan.hold = lambda: rig.pan.holds.append(rig.pan.angle)  # type: ignore[attr-defined]
    rig.pan.holds = []  # type: ignore[attr-defined]
    execution, _ = rig.start()
    rig.ticks(execution, 2.0)
    commands = len(rig.pan.commands)
    assert execution.cancel() is None
    assert rig.pan.holds == [rig.pan.angle] and len(rig.pan.commands) == commands  # type: ignore[attr-defined]


def test_an_unplugged_pan_is_retried_then_fails_with_its_reason() -> None:
    rig = Rig()
    rig.camera.bearing = 0.3
    execution, _ = rig.start(TrackFace({"unplugged_after": 2.0}))
    rig.ticks(execution, 1.0)
    rig.pan.plugged = False
    rig.ticks(execution, 1.0)
    rig.pan.plugged = True  # back within 2 s: the same step is sent again and tracking goes on
    rig.ticks(execution, 0.5)
    assert any("refused a command" in line for line in rig.logs)
    assert any("takes commands again" in line for line in rig.logs)
    rig.pan.plugged = False
    outcome = None
    for _ in range(40):
        outcome = rig.tick(execution)
        if outcome is not None:
            break
    assert outcome is not None and outcome.name == "failure"
    assert "the pan took no command for 2.0 s (unplugged?)" in outcome.reason
    assert max(rig.pan.commands) <= 0.3  # no steps piled up while it was away: never past the face


def test_a_pan_with_nothing_to_do_is_no_failure_while_unplugged() -> None:
    rig = Rig()
    rig.camera.bearing = 0.3
    execution, _ = rig.start(TrackFace({"unplugged_after": 1.0}))
    rig.ticks(execution, 1.0)
    rig.pan.plugged = False  # a step is refused...
    rig.ticks(execution, 0.5)
    rig.camera.bearing = rig.pan.angle  # ...then the visitor steps into the middle: nothing left to send
    rig.ticks(execution, 3.0)  # still tracking, well past `unplugged_after`
    assert rig.board.values["face_seen"] is True


def test_a_camera_that_raises_fails_the_skill_with_the_reason_and_the_pan_held() -> None:
    rig = Rig()
    rig.camera.bearing = None
    execution, _ = rig.start()
    rig.ticks(execution, 2.0)  # sweeping

    def unplugged() -> np.ndarray:
        raise OSError("camera unplugged")

    rig.camera.frame = unplugged  # type: ignore[method-assign]
    outcome = rig.tick(execution)
    assert outcome is not None and outcome.name == "failure" and "OSError: camera unplugged" in outcome.reason
    assert rig.pan.goal == rig.pan.angle


@pytest.mark.parametrize(
    ("params", "problem"),
    [
        ({"low": 0.5, "high": -0.5}, "must be below high"),
        ({"mode": "pid"}, "'fixed' or 'proportional'"),
        ({"step": 0}, "greater than 0"),
        ({"steps": 0.02}, "Extra inputs"),
    ],
)
def test_wrong_parameters_are_refused(params: dict[str, Any], problem: str) -> None:
    with pytest.raises(ValidationError, match=problem):
        FaceTrackParams(**params)


def test_limits_outside_the_joint_leave_nothing_to_track_with() -> None:
    rig = Rig()
    rig.pan.limit = 0.2
    outcome = rig.start(TrackFace({"low": 0.3, "high": 0.6}))[1]
    assert outcome is not None and outcome.name == "failure" and "leave nothing" in outcome.reason
