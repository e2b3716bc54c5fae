"""detect_crowd: look for a crowd (the PeopleBot paper's Crowd Detection state).

People come from the robot's people tracker, tracked on the map (``skills/perception``); a crowd
is more than one person, each within ``distance`` of another (single linkage), and it must stay
a crowd for ``confirm`` seconds before it counts, so two visitors passing each other are not a
crowd. The largest confirmed crowd wins (the nearer on a tie).
"""

from __future__ import annotations

import math

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.perception.crowd import CROWD_DISTANCE

_EPSILON = 1e-9


class DetectCrowd(Skill):
    name = "detect_crowd"
    description = "Look for a crowd for up to `duration` s; its centre of mass on the map, size and members."
    inputs = {
        "duration": In(Seconds, default=5.0, doc="s of mission time to look"),
        "distance": In(float, default=CROWD_DISTANCE, doc="m: each member within this of another"),
        "min_size": In(int, default=2, doc="people in a crowd, at least (the paper: more than one)"),
        "confirm": In(Seconds, default=1.0, doc="s a crowd must last before it counts"),
    }
    outputs = {
        "centre": Out(list[float], doc="[x, y] centre of mass in the map frame"),
        "size": Out(int, doc="people in the crowd"),
        "members": Out(list[int], doc="track ids of its members"),
        "crowd_id": Out(int, doc="stays the same while the crowd does"),
    }
    outcomes = ("crowd_found", "no_crowd", "timeout")
    success_outcomes = ("crowd_found",)

    def run(self, ctx: SkillContext, duration: float, distance: float, min_size: int, confirm: float) -> SkillRun:
        for name, value in (("duration", duration), ("distance", distance), ("confirm", confirm)):
            if not math.isfinite(value) or value < 0:
                return Outcome.failure(f"{name} must be a finite number >= 0, got {value}")
        if distance == 0:
            return Outcome.failure("distance must be above 0")
        tracking = ctx.interfaces.get("people_tracking")
        if tracking is None:
            return Outcome.failure("this robot has no people tracker (or camera) to detect crowds with")
        crowds = tracking.crowd_tracker(distance, min_size)
        start = ctx.clock.now()
        first_seen: dict[int, float] = {}
        seen_any = False
        dropped = 0
        while True:
            now = ctx.clock.now()
            frame = tracking.update()
            dropped += frame.dropped
            current = crowds.update(frame.people)
            first_seen = {c.id: first_seen.get(c.id, now) for c in current}  # a crowd must last unbroken
            seen_any = seen_any or bool(current)
            lasting = [c for c in current if now - first_seen[c.id] >= confirm - _EPSILON]
            if lasting:
                pose = tracking.pose()
                best = min(lasting, key=lambda c: (-c.size, math.hypot(c.centre[0] - pose.x, c.centre[1] - pose.y)))
                reason = f"{best.size} people around ({best.centre[0]:.2f}, {best.centre[1]:.2f})"
                if dropped:
                    reason += f"; {dropped} tracker readings dropped (not finite)"
                return Outcome(
                    "crowd_found",
                    reason,
                    {
                        "centre": [round(best.centre[0], 4), round(best.centre[1], 4)],
                        "size": best.size,
                        "members": list(best.members),
                        "crowd_id": best.id,
                    },
                )
            if now - start >= duration - _EPSILON:
                if seen_any:
                    return Outcome("timeout", f"people gathered but no crowd lasted {confirm:g} s in {duration:g} s")
                return Outcome("no_crowd", f"no crowd in {duration:g} s ({len(frame.people)} people in view)")
            yield
