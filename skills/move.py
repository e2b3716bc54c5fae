"""move: drive at a speed and turn rate for a while (open loop), then stop."""

from __future__ import annotations

from skills.base import In, Outcome, Skill, SkillContext, SkillRun


class Move(Skill):
    name = "move"
    description = "Drive at `v` m/s turning at `w` rad/s for `duration` s of mission time, then stop."
    inputs = {
        "v": In(float, default=0.0, doc="m/s forward (negative: backwards)"),
        "w": In(float, default=0.0, doc="rad/s counter-clockwise"),
        "duration": In(float, doc="seconds of mission time"),
    }

    def run(self, ctx: SkillContext, v: float, w: float, duration: float) -> SkillRun:
        if duration < 0:
            return Outcome.failure(f"duration must not be negative, got {duration}")
        drive = ctx.interface("drive")
        deadline = ctx.clock.now() + duration - 1e-9
        try:
            while ctx.clock.now() < deadline:
                drive.cmd_vel(v, w)  # every tick: the base's watchdog stops a robot left without commands
                yield
        finally:
            drive.stop()  # on success, failure and cancel alike
        return Outcome.success()
