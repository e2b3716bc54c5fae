"""gesture_drive: the book's gesture controller as a skill: a hand's IMU drives the robot.

Each tick the newest orientation of the ``gesture`` interface (an object with ``orientation()``
giving yaw, pitch, roll in degrees and ``received``, the mission time it arrived) goes through
the chapter's converter (``skills/gesture.py``, its quirks fixed), scaled to the robot's limits
(the navigation stack's, else the skill's ``max_linear``/``max_angular``); a hand silent for
``stale_s`` stops the robot. Ends after ``duration`` s, or when cancelled; the robot stops on
every way out.
"""

from __future__ import annotations

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.gesture import GestureCommands, GestureConfig


class GestureDrive(Skill):
    name = "gesture_drive"
    description = "Drive the robot from a hand's IMU (the book's gesture controller) for `duration` s."
    inputs = {
        "duration": In(Seconds, doc="s of mission time to drive"),
        "max_linear": In(float, default=0.3, doc="m/s at full tilt, when the robot has no navigation stack"),
        "max_angular": In(float, default=1.0, doc="rad/s at a full turn, when the robot has no navigation stack"),
    }
    outputs = {"samples": Out(int, doc="the hand's orientations the converter took")}
    Params = GestureConfig

    def run(self, ctx: SkillContext, duration: float, max_linear: float, max_angular: float) -> SkillRun:
        if duration < 0:
            return Outcome.failure(f"duration must not be negative, got {duration}")
        drive = ctx.interface("drive")
        glove = ctx.interface("gesture")
        limits = getattr(ctx.interfaces.get("navigation"), "limits", None)
        if limits is not None:
            max_linear, max_angular = limits.max_linear, limits.max_angular
        config = self.params if isinstance(self.params, GestureConfig) else GestureConfig()
        commands = GestureCommands(glove, max_linear, max_angular, config, monotonic=ctx.clock.now)
        end = ctx.clock.now() + duration
        stale = False
        try:
            while ctx.clock.now() < end - 1e-9:
                drive.cmd_vel(*commands())
                if commands.stale != stale:
                    stale = commands.stale
                    if stale:
                        ctx.logger.warning("the hand went quiet: stopped")
                    else:
                        ctx.logger.info("the hand is heard")
                yield
        finally:
            drive.stop()
        return Outcome.success(samples=commands.samples)
