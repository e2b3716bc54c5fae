"""wait: succeed after a duration on the mission clock."""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Seconds, Skill, SkillContext, SkillRun

# Times are products of tick counts and periods; compare with a tolerance far below one tick.
_EPSILON = 1e-9


class Wait(Skill):
    name = "wait"
    description = "Succeed once `duration` seconds of mission time have passed."
    inputs = {"duration": In(Seconds, doc="seconds of mission time (simulated or real)")}

    def run(self, ctx: SkillContext, duration: float) -> SkillRun:
        if duration < 0:
            return Outcome.failure(f"duration must not be negative, got {duration}")
        deadline = ctx.clock.now() + duration - _EPSILON
        while ctx.clock.now() < deadline:
            yield
        return Outcome.success()
