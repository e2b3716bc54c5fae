"""FollowPath: Nav2's controller server, as botstage's path follower (regulated pure pursuit).

It follows the path it was started with: Nav2's server takes a new path in the middle of a goal
(the BT node preempts it), here a new path reaches the follower when the tree starts FollowPath
again, which it does after a failure. So a blocked follower fails soon, with Nav2's codes, and
the tree's recoveries and replanning take over (``blocked_patience``, Nav2's progress checker).
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav.contact import ContactWatch, touched
from botstage.skills.nav.controller import Command, PathFollower
from botstage.skills.nav2.common import FOLLOW_PATH, PATH, SERVER, ignored, path_heading, sense, xy
from botstage.skills.navigate import nav_stack


class FollowParams(BaseModel):
    """Nav2's general goal checker and simple progress checker, with their default tolerances."""

    model_config = ConfigDict(extra="forbid")
    xy_goal_tolerance: float = Field(default=0.25, gt=0, description="m from the path's end that counts as there")
    yaw_goal_tolerance: float = Field(default=0.25, gt=0, description="rad from the goal's heading")
    blocked_patience: float = Field(default=2.0, gt=0, description="s stopped by an obstacle before failing")
    required_movement_radius: float = Field(default=0.5, gt=0, description="m of progress needed ...")
    movement_time_allowance: float = Field(default=10.0, gt=0, description="... within this many s")


def _tracking(follower: PathFollower, pose: Any, travelled: float) -> dict[str, float]:
    gx, gy = follower.path[-1]
    return {
        "distance_to_goal": round(math.hypot(gx - pose.x, gy - pose.y), 3),
        "distance_travelled": round(travelled, 3),
    }


class FollowPath(Skill):
    name = "FollowPath"
    description = "Nav2's FollowPath: drive along `path` to its end; RUNNING while following, fails when blocked."
    inputs = {
        "path": In(PATH, doc="[[x, y], ...] (map frame), e.g. {path} from ComputePathToPose"),
        "controller_id": ignored("botstage has one controller, regulated pure pursuit"),
        "goal_checker_id": ignored("the goal checker's tolerances are this skill's parameters"),
        "progress_checker_id": ignored("the progress checker's limits are this skill's parameters"),
        "path_handler_id": ignored("the path is followed as given"),
        **SERVER,
    }
    outputs = {
        "tracking_feedback": Out(dict, doc="distance_to_goal and distance_travelled, m"),
        "error_code_id": Out(int, doc="0, or Nav2's FollowPath code (103 INVALID_PATH, 105 FAILED_TO_MAKE_PROGRESS)"),
        "error_msg": Out(str, doc="why following failed"),
    }
    Params = FollowParams

    def run(self, ctx: SkillContext, path: list[list[float]], **_: Any) -> SkillRun:
        params: FollowParams = self.params  # type: ignore[assignment]
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        if not path or not all(len(p) in (2, 3) and all(math.isfinite(v) for v in p) for p in path):
            reason = f"not a path of [x, y] points: {str(path)[:60]}"
            return Outcome.failure(reason, error_code_id=FOLLOW_PATH["INVALID_PATH"], error_msg=reason)
        follower = PathFollower(
            [tuple(p) for p in xy(path)],
            path_heading(path),
            stack.follower_params(params.xy_goal_tolerance, params.yaw_goal_tolerance, None),
        )
        clock = ctx.clock
        pose = last = stack.pose()
        travelled = 0.0
        checkpoint, checked_at = (pose.x, pose.y), clock.now()
        blocked_since: float | None = None
        # the last resort, as navigate's: stop at the first contact no sensor showed, not push
        watch = ContactWatch.for_robot({"navigation": stack}, clock)
        stack.path = [(float(x), float(y)) for x, y in xy(path)]  # the monitor's map shows it
        try:
            while True:
                pose, now = stack.pose(), clock.now()
                travelled += math.hypot(pose.x - last.x, pose.y - last.y)
                last = pose
                obstacles = stack.obstacles()
                command = follower.command(pose, obstacles, stack.unmapped_distance(obstacles))
                contact = watch.check() if watch is not None else None
                if watch is not None and contact is not None and command.state != "arrived":
                    stack.mark(pose, touched(watch.last_command, stack.robot_radius))
                    command = Command(0.0, 0.0, "blocked", contact)
                if command.state == "arrived":
                    drive.stop()
                    return Outcome.success(
                        f"at the path's end after {travelled:.1f} m",
                        tracking_feedback=_tracking(follower, pose, travelled),
                        error_code_id=0,
                        error_msg="",
                    )
                if math.hypot(pose.x - checkpoint[0], pose.y - checkpoint[1]) >= params.required_movement_radius:
                    checkpoint, checked_at = (pose.x, pose.y), now
                failed = ""
                if command.state == "blocked":
                    drive.stop()
                    sense(stack)  # the local costmap sees it: the next plan goes around
                    blocked_since = now if blocked_since is None else blocked_since
                    if now - blocked_since >= params.blocked_patience:
                        failed = f"blocked for {now - blocked_since:.1f} s: {command.reason}"
                else:
                    blocked_since = None
                    drive.cmd_vel(command.v, command.w)
                if watch is not None:
                    moving = command.state != "blocked"
                    watch.commanded(command.v if moving else 0.0, command.w if moving else 0.0)
                if not failed and now - checked_at >= params.movement_time_allowance:
                    failed = f"less than {params.required_movement_radius:g} m in {params.movement_time_allowance:g} s"
                if failed:
                    return Outcome.failure(
                        failed,
                        tracking_feedback=_tracking(follower, pose, travelled),
                        error_code_id=FOLLOW_PATH["FAILED_TO_MAKE_PROGRESS"],
                        error_msg=failed,
                    )
                yield
        finally:
            drive.stop()
            stack.path = None
