"""Recovery behaviours for when navigation is stuck: spin, back up, clear the costmap.

They are skills of their own so a mission composes them in a tree around navigate (see
``missions/lib/navigation.yaml``), as Nav2 does with its recovery behaviour tree. They drive
without a plan, so they check the robot's footprint swept along the motion against what the
robot knows (``skills/nav/sweep.py``) and stop at the first contact (``skills/nav/contact.py``).
"""

from __future__ import annotations

import math

from botstage.skills.base import In, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav.contact import ContactWatch
from botstage.skills.nav.sweep import sweep
from botstage.skills.navigate import nav_stack

MIN_BACK_UP = 0.02  # m: less room than this behind is none
RECHECK = 1.5  # m of the way still to go that is checked again every tick (people step in)


class Spin(Skill):
    name = "spin"
    description = "Turn in place by `angle` rad (the sensors get a look around; people notice the robot)."
    inputs = {
        "angle": In(float, default=math.pi, doc="rad, counter-clockwise positive"),
        "speed": In(float, default=0.8, doc="rad/s"),
        "timeout": In(float, default=20.0, doc="s of mission time"),
    }
    outcomes = ("timeout",)

    def run(self, ctx: SkillContext, angle: float, speed: float, timeout: float) -> SkillRun:
        if not speed > 0:
            return Outcome.failure(f"speed must be positive, got {speed}")
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        watch = ContactWatch.for_robot(ctx.interfaces, ctx.clock)
        deadline = ctx.clock.now() + timeout
        last = stack.pose().theta
        turned = 0.0
        try:
            while abs(turned) < abs(angle) - 0.02:
                if ctx.clock.now() >= deadline:
                    return Outcome("timeout", f"turned {math.degrees(turned):.0f}° of {math.degrees(angle):.0f}°")
                contact = watch.check() if watch is not None else None
                if contact is not None:  # a round robot turning in place touches only what slipped against it
                    return Outcome.failure(f"stopped after turning {math.degrees(turned):.0f}°: {contact}")
                left = abs(angle) - abs(turned)
                w = math.copysign(max(0.2, min(speed, 2.0 * left)), angle)
                drive.cmd_vel(0.0, w)
                if watch is not None:
                    watch.commanded(0.0, w)
                yield
                theta = stack.pose().theta
                turned += math.remainder(theta - last, 2 * math.pi)
                last = theta
        finally:
            drive.stop()
        return Outcome.success(f"turned {math.degrees(turned):.0f}°")


class BackUp(Skill):
    name = "back_up"
    description = (
        "Reverse up to `distance` metres slowly: as far as the map and what was seen leave room for "
        "the robot's footprint all the way, stopping at the first contact."
    )
    inputs = {
        "distance": In(float, default=0.3, doc="m"),
        "speed": In(float, default=0.1, doc="m/s"),
        "timeout": In(float, default=15.0, doc="s of mission time"),
    }
    outcomes = ("timeout",)

    def run(self, ctx: SkillContext, distance: float, speed: float, timeout: float) -> SkillRun:
        if not (distance > 0 and speed > 0):
            return Outcome.failure("distance and speed must be positive")
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        watch = ContactWatch.for_robot(ctx.interfaces, ctx.clock)
        start = stack.pose()
        # the robot has no eyes behind: the map, what it saw and its recent surroundings decide
        room = sweep(stack, start, -speed, 0.0, distance / speed)
        target, blocker = room.time * speed, room.blocker
        if target < MIN_BACK_UP:
            return Outcome.failure(f"no room to back up: {blocker} is right behind the robot ({target:.2f} m free)")
        deadline = ctx.clock.now() + timeout
        try:
            while True:
                pose = stack.pose()
                gone = math.hypot(pose.x - start.x, pose.y - start.y)
                if gone >= target - 0.01:
                    short = f" of {distance:.2f} m, short of {blocker}" if blocker else ""
                    return Outcome.success(f"backed up {gone:.2f} m{short}")
                if ctx.clock.now() >= deadline:
                    return Outcome("timeout", f"backed up {gone:.2f} of {target:.2f} m")
                contact = watch.check() if watch is not None else None
                if contact is not None:
                    return Outcome.failure(f"stopped after {gone:.2f} m: {contact}")
                ahead = sweep(stack, pose, -speed, 0.0, min(target - gone, RECHECK) / speed)
                if not ahead.clear:  # something came into the way (a person behind, seen of late)
                    target, blocker = gone + ahead.time * speed, ahead.blocker
                    if gone >= target - 0.01:
                        continue  # there already
                v = -min(speed, max(0.03, target - gone))
                drive.cmd_vel(v, 0.0)
                if watch is not None:
                    watch.commanded(v, 0.0)
                yield
        finally:
            drive.stop()


class ClearCostmap(Skill):
    name = "clear_costmap"
    description = "Forget the obstacles seen on the way (they may have walked off); the map stays."

    def run(self, ctx: SkillContext) -> Outcome:
        nav_stack(ctx).clear()
        return Outcome.success()
