"""Recovery behaviours for when navigation is stuck: spin, back up, clear the costmap.

They are skills of their own so a mission composes them in a tree around navigate (see
``missions/lib/navigation.yaml``), as Nav2 does with its recovery behaviour tree.
"""

from __future__ import annotations

import math

from skills.base import In, Outcome, Skill, SkillContext, SkillRun
from skills.navigate import nav_stack


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
        if speed <= 0:
            return Outcome.failure(f"speed must be positive, got {speed}")
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        deadline = ctx.clock.now() + timeout
        last = stack.pose().theta
        turned = 0.0
        try:
            while abs(turned) < abs(angle) - 0.02:
                if ctx.clock.now() >= deadline:
                    return Outcome("timeout", f"turned {math.degrees(turned):.0f}° of {math.degrees(angle):.0f}°")
                left = abs(angle) - abs(turned)
                drive.cmd_vel(0.0, math.copysign(max(0.2, min(speed, 2.0 * left)), angle))
                yield
                theta = stack.pose().theta
                turned += math.remainder(theta - last, 2 * math.pi)
                last = theta
        finally:
            drive.stop()
        return Outcome.success(f"turned {math.degrees(turned):.0f}°")


class BackUp(Skill):
    name = "back_up"
    description = "Reverse `distance` metres slowly, if nothing seen or mapped is behind."
    inputs = {
        "distance": In(float, default=0.3, doc="m"),
        "speed": In(float, default=0.1, doc="m/s"),
        "timeout": In(float, default=15.0, doc="s of mission time"),
    }
    outcomes = ("timeout",)

    def run(self, ctx: SkillContext, distance: float, speed: float, timeout: float) -> SkillRun:
        if distance <= 0 or speed <= 0:
            return Outcome.failure("distance and speed must be positive")
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        start = stack.pose()
        c, s = math.cos(start.theta), math.sin(start.theta)
        end = (start.x - c * distance, start.y - s * distance)
        if not stack.free(*end):  # the robot has no eyes behind: trust the map and what it saw
            return Outcome.failure(f"no room to back up {distance:.2f} m")
        deadline = ctx.clock.now() + timeout
        try:
            while True:
                pose = stack.pose()
                gone = math.hypot(pose.x - start.x, pose.y - start.y)
                if gone >= distance - 0.01:
                    return Outcome.success(f"backed up {gone:.2f} m")
                if ctx.clock.now() >= deadline:
                    return Outcome("timeout", f"backed up {gone:.2f} of {distance:.2f} m")
                drive.cmd_vel(-min(speed, max(0.03, distance - gone)), 0.0)
                yield
        finally:
            drive.stop()


class ClearCostmap(Skill):
    name = "clear_costmap"
    description = "Forget the obstacles seen on the way (they may have walked off); the map stays."

    def run(self, ctx: SkillContext) -> Outcome:
        nav_stack(ctx).clear()
        return Outcome.success()
