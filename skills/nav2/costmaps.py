"""Nav2's costmap services: clear what was seen, all of it, outside or inside a square round the robot.

botstage has one obstacle layer for planning and following (Nav2 has a global and a local costmap),
so ``service_name`` (which costmap) is ignored: both clear the same layer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from botstage.skills.base import In, Outcome, Skill, SkillContext
from botstage.skills.nav.stack import NavStack
from botstage.skills.nav2.common import ignored
from botstage.skills.navigate import nav_stack

COSTMAP = {
    "service_name": ignored("botstage's one obstacle layer serves as the global and the local costmap"),
    "server_timeout": ignored("no service to wait for"),
    "plugins": ignored("botstage's obstacle layer is the only clearable layer"),
}


def _square(stack: NavStack, side: float) -> np.ndarray:
    """The cells of the square of ``side`` metres centred on the robot."""
    pose, grid = stack.pose(), stack.grid
    mask = np.zeros(grid.data.shape, dtype=bool)
    r0, c0 = grid.cell(pose.x - side / 2, pose.y - side / 2)
    r1, c1 = grid.cell(pose.x + side / 2, pose.y + side / 2)
    rows, cols = sorted((r0, r1)), sorted((c0, c1))
    mask[max(rows[0], 0) : max(rows[1] + 1, 0), max(cols[0], 0) : max(cols[1] + 1, 0)] = True
    return mask


class ClearEntireCostmap(Skill):
    name = "ClearEntireCostmap"
    description = "Nav2's ClearEntireCostmap: forget every obstacle seen; the map stays."
    inputs = dict(COSTMAP)

    def run(self, ctx: SkillContext, **_: Any) -> Outcome:
        nav_stack(ctx).clear()
        return Outcome.success()


class ClearCostmapExceptRegion(Skill):
    name = "ClearCostmapExceptRegion"
    description = "Nav2's ClearCostmapExceptRegion: forget what was seen except in a square round the robot."
    inputs = {"reset_distance": In(float, default=1.0, doc="m, the side of the square kept"), **COSTMAP}

    def run(self, ctx: SkillContext, reset_distance: float, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        stack.forget(~_square(stack, reset_distance))
        return Outcome.success()


class ClearCostmapAroundRobot(Skill):
    name = "ClearCostmapAroundRobot"
    description = "Nav2's ClearCostmapAroundRobot: forget what was seen in a square round the robot."
    inputs = {"reset_distance": In(float, default=1.0, doc="m, the side of the square cleared"), **COSTMAP}

    def run(self, ctx: SkillContext, reset_distance: float, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        stack.forget(_square(stack, reset_distance))
        return Outcome.success()


class ClearCostmapAroundPose(Skill):
    name = "ClearCostmapAroundPose"
    description = "Nav2's ClearCostmapAroundPose: forget what was seen within reset_distance of `pose`."
    inputs = {
        "pose": In(str | list[float], doc="a place or [x, y(, yaw)]"),
        "reset_distance": In(float, default=1.0, doc="m round the pose"),
        **COSTMAP,
    }

    def run(self, ctx: SkillContext, pose: Any, reset_distance: float, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        try:
            x, y, _ = stack.resolve(pose)
        except ValueError as exc:
            return Outcome.failure(str(exc))
        grid = stack.grid
        rows, cols = np.indices(grid.data.shape)
        row, col = grid.cell(x, y)
        near = np.hypot(rows - row, cols - col) * grid.resolution <= reset_distance
        stack.forget(near)
        return Outcome.success()
