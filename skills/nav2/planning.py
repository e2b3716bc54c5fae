"""ComputePathToPose and ComputePathThroughPoses: the global plan, from the robot's planner."""

from __future__ import annotations

from typing import Any

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext
from botstage.skills.nav.planner import Unreachable
from botstage.skills.nav.stack import NavStack
from botstage.skills.nav2.common import COMPUTE_PATH, GOAL, GOALS, PATH, SERVER, THROUGH_POSES, as_path, ignored, sense
from botstage.skills.navigate import nav_stack

PLAN_OUTPUTS = {
    "path": Out(PATH, doc="[[x, y], ...] in the map frame; the last point has the goal's heading when it has one"),
    "error_code_id": Out(int, doc="0, or Nav2's ComputePathToPose code (208 NO_VALID_PATH ...)"),
    "error_msg": Out(str, doc="why planning failed"),
}


def _code(reason: str, table: dict[str, int]) -> int:
    """Nav2's error code for a planner's reason (skills/nav/planner.py says which case it was)."""
    if "off the map" in reason:
        return table["START_OUTSIDE_MAP"] if "the start" in reason else table["GOAL_OUTSIDE_MAP"]
    if "inside an obstacle" in reason:
        return table["START_OCCUPIED"] if "the start" in reason else table["GOAL_OCCUPIED"]
    return table["NO_VALID_PATH"]


def _plan(
    stack: NavStack, start: tuple[float, float], goals: list[Any]
) -> tuple[list[tuple[float, float]], float | None]:
    """One path through every goal in turn; raises Unreachable or ValueError (an unknown place)."""
    points: list[tuple[float, float]] = []
    heading = None
    for goal in goals:
        gx, gy, heading = stack.resolve(goal)
        leg = stack.plan(start, (gx, gy)).points
        points.extend(leg if not points else leg[1:])
        start = (gx, gy)
    return points, heading


class ComputePathToPose(Skill):
    name = "ComputePathToPose"
    description = "Nav2's ComputePathToPose: plan from the robot (or `start`) to `goal` around what is known."
    inputs = {
        "start": In(GOAL | None, default=None, doc="plan from here instead of the robot's pose (with use_start)"),
        "use_start": In(bool | None, default=None, doc="use `start`; unset: use it when given"),
        "goal": In(GOAL, doc="a place of the map or [x, y(, theta)]"),
        "viapoints": In(GOALS | None, default=None, doc="places to pass on the way, before the goal"),
        "planner_id": ignored("botstage has one planner, A* on the costmap"),
        **SERVER,
    }
    outputs = PLAN_OUTPUTS

    def run(
        self, ctx: SkillContext, start: Any, use_start: bool | None, goal: Any, viapoints: Any, **_: Any
    ) -> Outcome:
        stack = nav_stack(ctx)
        pose = stack.pose()
        origin = (pose.x, pose.y)
        try:
            if start is not None and use_start is not False:
                origin = stack.resolve(start)[:2]
            sense(stack)
            points, heading = _plan(stack, origin, [*(viapoints or []), goal])
        except (Unreachable, ValueError) as exc:
            code = COMPUTE_PATH["GOAL_OUTSIDE_MAP"] if isinstance(exc, ValueError) else _code(str(exc), COMPUTE_PATH)
            return Outcome.failure(str(exc), error_code_id=code, error_msg=str(exc))
        return Outcome.success(f"{len(points)} points", path=as_path(points, heading), error_code_id=0, error_msg="")


class ComputePathThroughPoses(Skill):
    name = "ComputePathThroughPoses"
    description = "Nav2's ComputePathThroughPoses: one path from the robot through every goal in order."
    inputs = {
        "start": In(GOAL | None, default=None, doc="plan from here instead of the robot's pose"),
        "goals": In(GOALS, doc="places of the map or [x, y(, theta)], in order"),
        "planner_id": ignored("botstage has one planner, A* on the costmap"),
        **SERVER,
    }
    outputs = {
        **PLAN_OUTPUTS,
        "last_reached_index": Out(int, doc="-1: the path reaches every goal (botstage never plans part of the way)"),
    }

    def run(self, ctx: SkillContext, start: Any, goals: list[Any], **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        if not goals:
            reason = "no goals to plan through"
            return Outcome.failure(reason, error_code_id=THROUGH_POSES["NO_VIAPOINTS_GIVEN"], error_msg=reason)
        pose = stack.pose()
        try:
            origin = stack.resolve(start)[:2] if start is not None else (pose.x, pose.y)
            sense(stack)
            points, heading = _plan(stack, origin, goals)
        except (Unreachable, ValueError) as exc:
            code = THROUGH_POSES["GOAL_OUTSIDE_MAP"] if isinstance(exc, ValueError) else _code(str(exc), THROUGH_POSES)
            return Outcome.failure(str(exc), error_code_id=code, error_msg=str(exc))
        path = as_path(points, heading)
        return Outcome.success(f"{len(points)} points", path=path, error_code_id=0, error_msg="", last_reached_index=-1)
