"""approach: go towards a point (a crowd's centre of mass), stop at a standoff distance, face it.

The stopping point lies on the line from the target to the robot, ``standoff`` metres from the
target. When that spot is taken (a wall, an exhibit, visitors seen there), the nearest free
spot on the circle around the target is used instead, then wider circles.
"""

from __future__ import annotations

import math

import numpy as np

from botstage.skills.base import In, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav.navigator import OUTCOMES, NavParams, drive_to
from botstage.skills.navigate import CANCEL, NAV_OUTPUTS, TIMEOUT, cancel_condition, nav_outcome, nav_stack


class Approach(Skill):
    name = "approach"
    description = "Drive to `standoff` metres from `target` (e.g. a crowd's centre) and face it."
    inputs = {
        "target": In(list[float], doc="[x, y] in the map frame"),
        "standoff": In(float, default=1.2, doc="m between the robot's centre and the target"),
        "tolerance": In(float, default=0.15, doc="m"),
        "timeout": TIMEOUT,
        "cancel": CANCEL,
    }
    outputs = NAV_OUTPUTS
    outcomes = OUTCOMES
    success_outcomes = ("succeeded",)
    Params = NavParams

    def run(
        self, ctx: SkillContext, target: list[float], standoff: float, tolerance: float, timeout: float, cancel: str
    ) -> SkillRun:
        if len(target) < 2 or not all(math.isfinite(v) for v in target[:2]):
            return Outcome("unreachable", f"a target is [x, y], got {target!r}")
        if standoff < 0:
            return Outcome("unreachable", f"standoff must not be negative, got {standoff}")
        stack = nav_stack(ctx)
        tx, ty = float(target[0]), float(target[1])
        pose = stack.pose()
        spot = self._spot(ctx, tx, ty, standoff, (pose.x, pose.y))
        if spot is None:
            return Outcome("unreachable", f"no free spot within {standoff + 1.5:.1f} m of ({tx:.2f}, {ty:.2f})")
        heading = math.atan2(ty - spot[1], tx - spot[0])
        if math.hypot(spot[0] - pose.x, spot[1] - pose.y) <= tolerance:
            spot = (pose.x, pose.y)  # already there: only turn to face it
        result = yield from drive_to(
            stack,
            ctx.interface("drive"),
            (spot[0], spot[1], heading),
            self.params,  # type: ignore[arg-type]
            tolerance=tolerance,
            heading_tolerance=0.1,
            timeout=timeout,
            cancel=cancel_condition(ctx, cancel),
            log=ctx.logger.info,
        )
        return nav_outcome(result)

    @staticmethod
    def _spot(
        ctx: SkillContext, tx: float, ty: float, standoff: float, robot: tuple[float, float]
    ) -> tuple[float, float] | None:
        stack = nav_stack(ctx)
        towards = math.atan2(robot[1] - ty, robot[0] - tx)
        for radius in standoff + 0.25 * np.arange(7):  # then wider, up to 1.5 m further out
            for k in range(0, 37):  # 0, +10°, -10°, +20°, ... round the circle from the robot's side
                angle = towards + math.radians(10 * ((k + 1) // 2) * (1 if k % 2 else -1))
                x, y = tx + float(radius) * math.cos(angle), ty + float(radius) * math.sin(angle)
                if stack.free(x, y, margin=0.2):  # room to stop there short of what it faces
                    return x, y
        return None
