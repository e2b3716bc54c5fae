"""move: drive at a speed and turn rate for a while (open loop), then stop.

Open loop is no licence to drive into things: on a robot with a navigation stack the footprint
swept along the arc is checked against its map and what its sensors see, before the start and
every tick, and the move ends short of the first thing in the way; with odometry it stops at the
first contact instead of pushing until the time is up.
"""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav.contact import ContactWatch
from botstage.skills.nav.stack import NavStack
from botstage.skills.nav.sweep import Sweep, sweep

RECHECK = 1.5  # m of the arc still to drive that is checked again every tick (people step in)
MIN_MOVE = 0.01  # m: less room than this is none


class Move(Skill):
    name = "move"
    description = (
        "Drive at `v` m/s turning at `w` rad/s for `duration` s of mission time, then stop; "
        "shorter when the robot's map or sensors show something in the way."
    )
    inputs = {
        "v": In(float, default=0.0, doc="m/s forward (negative: backwards)"),
        "w": In(float, default=0.0, doc="rad/s counter-clockwise"),
        "duration": In(float, doc="seconds of mission time"),
    }

    def run(self, ctx: SkillContext, v: float, w: float, duration: float) -> SkillRun:
        if not duration >= 0:
            return Outcome.failure(f"duration must not be negative, got {duration}")
        drive = ctx.interface("drive")
        stack = ctx.interfaces.get("navigation")
        watch = ContactWatch.for_robot(ctx.interfaces, ctx.clock)
        start = ctx.clock.now()
        end, blocker = start + duration, ""
        if stack is not None:
            room = sweep(stack, stack.pose(), v, w, duration)
            if not room.clear:
                end, blocker = start + self._stop_in(stack, v, room), room.blocker
                if abs(v) * (end - start) < MIN_MOVE:
                    return Outcome.failure(f"no room to move: {room.blocker} is in the way")
        try:
            while ctx.clock.now() < end - 1e-9:
                contact = watch.check() if watch is not None else None
                if contact is not None:
                    return Outcome.failure(f"stopped after {ctx.clock.now() - start:.1f} s: {contact}")
                if stack is not None:
                    ahead = self._ahead(stack, v, w, end - ctx.clock.now())
                    if not ahead.clear:  # something came into the way
                        end, blocker = ctx.clock.now() + self._stop_in(stack, v, ahead), ahead.blocker
                        if ctx.clock.now() >= end - 1e-9:
                            break
                drive.cmd_vel(v, w)  # every tick: the base's watchdog stops a robot left without commands
                if watch is not None:
                    watch.commanded(v, w)
                yield
        finally:
            drive.stop()  # on success, failure and cancel alike
        if blocker:
            return Outcome.success(f"stopped after {ctx.clock.now() - start:.1f} of {duration:g} s, short of {blocker}")
        return Outcome.success()

    @staticmethod
    def _ahead(stack: NavStack, v: float, w: float, left: float) -> Sweep:
        """The next stretch of the arc, at most ``RECHECK`` metres, as the robot sees it now."""
        horizon = min(left, RECHECK / abs(v)) if v else left
        return sweep(stack, stack.pose(), v, w, horizon)

    @staticmethod
    def _stop_in(stack: NavStack, v: float, room: Sweep) -> float:
        """Seconds to keep commanding so that, braking after, the robot stops within the room."""
        braking = v * v / (2 * stack.limits.max_accel) if stack.limits.max_accel > 0 else 0.0
        return max(room.time - braking / abs(v), 0.0)
