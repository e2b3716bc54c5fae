"""navigate: drive to a goal pose (a named place or coordinates) on the robot's map."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.expression import EvaluationError, compile_expression
from botstage.skills.nav.navigator import OUTCOMES, NavParams, NavResult, drive_to
from botstage.skills.nav.stack import NavStack

GOAL = str | list[float]


def nav_stack(ctx: SkillContext) -> NavStack:
    """The robot's navigation stack (the runner provides it for missions on a map)."""
    return ctx.interface("navigation")


def cancel_condition(ctx: SkillContext, source: str) -> Callable[[], bool] | None:
    """A blackboard condition that, once true, cancels the drive (None for the default ``false``)."""
    expression = compile_expression(source)
    if not expression.keys and not expression.test(lambda key: None):
        return None

    def cancelled() -> bool:
        try:
            return bool(expression.test(ctx.blackboard.get))
        except (LookupError, EvaluationError):
            return False  # a key nobody wrote yet cannot have asked to cancel

    return cancelled


def nav_outcome(result: NavResult) -> Outcome:
    pose = result.pose
    return Outcome(
        result.outcome,
        result.reason,
        {
            "pose": [round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)],
            "distance": round(result.travelled, 3),
            "result": result.outcome,
        },
    )


NAV_OUTPUTS = {
    "pose": Out(list[float], doc="where the robot ended: [x, y, theta] (map frame, estimated)"),
    "distance": Out(float, doc="metres driven"),
    "result": Out(str, doc="the outcome's name, for a tree to branch on (e.g. to recover when blocked)"),
}
CANCEL = In(str, default="false", doc="a condition that cancels the drive once true", expression=True)
TIMEOUT = In(Seconds, default=0.0, doc="s of mission time; 0: from the path's length")


class Navigate(Skill):
    name = "navigate"
    description = "Plan a path to `goal` and follow it, avoiding what the laser or sonar sees; replans when blocked."
    inputs = {
        "goal": In(GOAL, doc="a place of the map (e.g. `exhibit_a`) or [x, y] / [x, y, theta] in metres and rad"),
        "tolerance": In(float, default=0.05, doc="m from the goal's position that counts as there"),
        "heading_tolerance": In(float, default=0.05, doc="rad from the goal's heading (when it has one)"),
        "timeout": TIMEOUT,
        "cancel": CANCEL,
    }
    outputs = NAV_OUTPUTS
    outcomes = OUTCOMES
    success_outcomes = ("succeeded",)
    Params = NavParams

    def run(
        self,
        ctx: SkillContext,
        goal: Any,
        tolerance: float,
        heading_tolerance: float,
        timeout: float,
        cancel: str,
    ) -> SkillRun:
        stack = nav_stack(ctx)
        try:
            target = stack.resolve(goal)
        except ValueError as exc:
            return Outcome("unreachable", str(exc))
        result = yield from drive_to(
            stack,
            ctx.interface("drive"),
            target,
            self.params,  # type: ignore[arg-type]
            tolerance=tolerance,
            heading_tolerance=heading_tolerance,
            timeout=timeout,
            cancel=cancel_condition(ctx, cancel),
            log=ctx.logger.info,
        )
        return nav_outcome(result)
