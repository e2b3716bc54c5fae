"""track_face: the book's face tracker (chapter 2) as a skill: track the face, sweep when it is lost.

Each new camera frame goes to the chapter's detector (``skills/perception/face_tracking.py``) on
the worker pool, so a tick never waits for the cascade and the result arrives a tick later, as a
detector node's would. A frame is new when it is another array than the last one analysed (a
camera returns the same array until a newer frame comes): a tick faster than the camera never
analyses a frame twice. The tracked face's x moves the chapter's pan controller (its dead band and
its step a frame, or the proportional step) and the pan is sent there.

The proportional step (``mode: proportional``, beyond the chapter) is ``gain`` rad per pixel of the
face's offset from the centre, at most ``max_step`` a frame: 0.04 rad, about what the AX-12A turns
in a frame (1.17 rad/s at 30 fps). A larger cap lets the commands run ahead of the shaft while the
frames still show the face far off, and the face overshoots the dead band (``python -m
tests.bench facetracker``).

With no face for ``lost_after`` s the pan sweeps between the controller's limits at
``sweep_rate`` rad/s, first towards the side the face was last seen on (where a walker went),
until a face is seen again; the controller then tracks from where the sweep had got to.

Blackboard: ``seen_key`` is true from a detection until the face has been missing for
``lost_after`` s (while it is false the pan sweeps); the face's x, its pixel error from the image
centre (positive: right of it) and the pan angle last sent are written when ``seen`` changes and
at most every ``every`` s besides, so the trace is not a copy of the frame stream.

Ends after ``duration`` s with success and its counts, or runs until cancelled (duration 0). A
pan that takes no command (``move_to`` False: its driver reopens an unplugged port on its own) is
sent the same angle again each tick and fails the skill after ``unplugged_after`` s with that
reason. On every way out the pan is held where it is (its ``hold()`` when it has one).
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from botstage.skills.base import In, Out, Outcome, PositiveSeconds, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.perception.face_tracking import FaceDetector, PanController

_EPSILON = 1e-9


class FaceTrackParams(BaseModel):
    """The chapter's ``servo_param.yaml`` (its values are the defaults), the proportional step and the sweep."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["fixed", "proportional"] = Field(
        "fixed", description="fixed: the chapter's `step` a frame; proportional: `gain` per pixel off the centre"
    )
    step: float = Field(0.01, gt=0, le=0.5, description="rad a frame towards the face (step_distancex)")
    centre_offset: int = Field(50, ge=0, description="px either side of the image centre: the dead band")
    low: float = Field(-0.5, ge=-math.pi, le=math.pi, description="rad: the lowest pan angle sent (servomin)")
    high: float = Field(0.5, ge=-math.pi, le=math.pi, description="rad: the highest pan angle sent (servomaxx)")
    gain: float = Field(0.0005, gt=0, le=0.1, description="rad a frame per px off the image centre (proportional)")
    max_step: float = Field(
        0.04, gt=0, le=0.5, description="rad a frame at most (proportional): about what an AX-12A turns in a frame"
    )
    sweep_rate: float = Field(0.3, gt=0, le=5.0, description="rad/s while sweeping for a lost face")
    unplugged_after: float = Field(
        5.0, gt=0, le=3600, description="s the pan may refuse commands before the skill fails"
    )

    @model_validator(mode="after")
    def _limits(self) -> FaceTrackParams:
        if not self.low < self.high:
            raise ValueError(f"low ({self.low}) must be below high ({self.high})")
        return self


def _write(ctx: SkillContext, key: str, value: Any) -> None:
    """Only a change reaches the blackboard (and so the trace)."""
    if not ctx.blackboard.exists(key) or ctx.blackboard.get(key) != value:
        ctx.blackboard.set(key, value)


class TrackFace(Skill):
    name = "track_face"
    description = "Keep a face in the middle of the camera's image with the pan joint; sweep for it when lost."
    inputs = {
        "duration": In(Seconds, default=0.0, doc="s of mission time to track; 0: until cancelled"),
        "lost_after": In(PositiveSeconds, default=1.0, doc="s without a face before the pan sweeps for one"),
        "every": In(Seconds, default=0.5, doc="s between writes of the face's x, error and the pan angle"),
        "seen_key": In(str, default="face_seen", doc="the bool key: a face is being tracked", names_key="write"),
        "x_key": In(str, default="face_x", doc="the float key: the face's x (px) when last seen", names_key="write"),
        "error_key": In(
            str, default="face_error", doc="the float key: face x - image centre (px) when last seen", names_key="write"
        ),
        "pan_key": In(str, default="pan_angle", doc="the float key: the pan angle last sent (rad)", names_key="write"),
    }
    outputs = {
        "frames": Out(int, doc="camera frames analysed"),
        "detections": Out(int, doc="frames with a face"),
        "sweeps": Out(int, doc="times the pan started sweeping for a face"),
        "seen": Out(bool, doc="a face was being tracked at the end"),
    }
    Params = FaceTrackParams

    def run(
        self,
        ctx: SkillContext,
        duration: float,
        lost_after: float,
        every: float,
        seen_key: str,
        x_key: str,
        error_key: str,
        pan_key: str,
    ) -> SkillRun:
        params = ctx.params if isinstance(ctx.params, FaceTrackParams) else FaceTrackParams()
        camera = ctx.interface("camera")
        pan = ctx.interface("pan")
        low, high = max(params.low, pan.min_angle), min(params.high, pan.max_angle)
        if not low < high:
            return Outcome.failure(
                f"the limits {params.low:g}..{params.high:g} rad leave nothing of the pan's "
                f"{pan.min_angle:g}..{pan.max_angle:g} rad"
            )
        width = camera.info.width
        middle = width / 2
        present = pan.position()
        if present is None:
            ctx.logger.warning("cannot read the pan's position: starting from the centre")
            present = 0.0
        controller = PanController(
            screen_width=width,
            centre_offset=params.centre_offset,
            step=params.step,
            low=low,
            high=high,
            gain=params.gain if params.mode == "proportional" else 0.0,
            max_step=params.max_step,
            position=min(high, max(low, present)),
        )
        start = previous = ctx.clock.now()
        _write(ctx, seen_key, False)
        detector: FaceDetector = yield ctx.submit(FaceDetector)
        end = start + duration if duration > 0 else math.inf
        target = controller.position
        sent: float | None = None  # the angle the pan last took
        refused_since: float | None = None
        last_seen = start  # the first sweep waits `lost_after` too: the first frames may show a face
        face_x = middle
        seen = sweeping = False
        direction = 1.0
        frames = detections = sweeps = 0
        last_frame: Any = None
        written = -math.inf
        try:
            while True:
                now = ctx.clock.now()
                if now >= end - _EPSILON:
                    break
                if not sweeping and now - last_seen >= lost_after - _EPSILON:
                    sweeping, sweeps = True, sweeps + 1
                    direction = 1.0 if face_x < middle else -1.0  # positive turns the camera left
                    side = "left" if direction > 0 else "right"
                    what = "the face lost" if seen else "no face yet"
                    ctx.logger.info(f"{what} for {lost_after:g} s: sweeping from {target:+.2f} rad, {side} first")
                    if seen:
                        seen = False
                        written = -math.inf
                elif sweeping:
                    target, direction = _sweep(target, direction, params.sweep_rate * (now - previous), low, high)
                previous = now

                if sent is None or abs(target - sent) > 1e-12:
                    if pan.move_to(target):
                        sent = target
                        if refused_since is not None:
                            ctx.logger.info(f"the pan takes commands again after {now - refused_since:.1f} s")
                        refused_since = None
                    else:
                        if sent is not None and not sweeping:
                            controller.position = sent  # no steps piled up on a pan that does not move
                        if refused_since is None:
                            refused_since = now
                            ctx.logger.warning("the pan refused a command (unplugged?): sending it again each tick")
                else:
                    refused_since = None  # nothing to send: nothing refused (a face that came into the band)
                if refused_since is not None and now - refused_since >= params.unplugged_after - _EPSILON:
                    return Outcome.failure(
                        f"the pan took no command for {now - refused_since:.1f} s (unplugged?)",
                        frames=frames,
                        detections=detections,
                        sweeps=sweeps,
                        seen=seen,
                    )

                if now - written >= every - _EPSILON:
                    written = now
                    _write(ctx, seen_key, seen)
                    if seen:
                        _write(ctx, x_key, round(face_x, 1))
                        _write(ctx, error_key, round(face_x - middle, 1))
                    _write(ctx, pan_key, round(sent if sent is not None else target, 4))

                frame = camera.frame()
                if frame is None or frame is last_frame:
                    yield
                    continue
                last_frame = frame
                frames += 1
                centre = yield ctx.submit(detector.centre, frame)  # the result comes a tick later
                if centre is None:
                    continue
                detections += 1
                face_x, last_seen = centre[0], ctx.clock.now()
                if not seen:
                    seen, sweeping, written = True, False, -math.inf
                    controller.position = target  # track on from where the sweep got to
                    ctx.logger.info(f"a face at x {face_x:.0f} px, the pan at {target:+.2f} rad: tracking")
                target = controller.update(face_x)
        finally:
            _hold(pan)
        return Outcome.success(
            f"{detections} of {frames} frames with a face, {sweeps} sweeps",
            frames=frames,
            detections=detections,
            sweeps=sweeps,
            seen=seen,
        )


def _hold(pan: Any) -> None:
    """Stop a step or a sweep under way where the shaft is: the joint's own ``hold`` (the AX-12A
    driver's and the simulator's), else its present position sent as the goal."""
    hold = getattr(pan, "hold", None)
    if callable(hold):
        hold()
        return
    present = pan.position()
    if present is not None:
        pan.move_to(present)


def _sweep(angle: float, direction: float, distance: float, low: float, high: float) -> tuple[float, float]:
    """``distance`` rad further along the sweep; a limit is sent as it is (the view's edge is looked
    at too) and turns the sweep back."""
    angle += direction * distance
    if angle >= high:
        return high, -1.0
    if angle <= low:
        return low, 1.0
    return angle, direction
