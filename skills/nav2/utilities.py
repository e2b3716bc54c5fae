"""Nav2's small path, pose and goal utilities, and its Cancel* actions, on botstage's values."""

from __future__ import annotations

from typing import Any

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav2.common import GOAL, GOALS, PATH, SERVER, ignored
from botstage.skills.navigate import nav_stack

POSE = list[float]
FRAMES = {
    "robot_base_frame": ignored("the robot's pose comes from its navigation stack"),
    "global_frame": ignored("botstage's poses are in the map frame"),
}


class GetPoseFromPath(Skill):
    name = "GetPoseFromPath"
    description = "Nav2's GetPoseFromPath: the path's point at `index` (negative: from the end) as a pose."
    inputs = {"path": In(PATH, doc="the path"), "index": In(int, default=0, doc="which point; -1 the last")}
    outputs = {"pose": Out(POSE, doc="[x, y] or [x, y, yaw]")}

    def run(self, ctx: SkillContext, path: list[list[float]], index: int) -> Outcome:
        if not -len(path) <= index < len(path):
            return Outcome.failure(f"index {index} is outside the path's {len(path)} points")
        return Outcome.success(pose=list(path[index]))


class GetCurrentPose(Skill):
    name = "GetCurrentPose"
    description = "Nav2's GetCurrentPose: where the robot is, [x, y, yaw] in the map frame."
    inputs = dict(FRAMES)
    outputs = {"current_pose": Out(POSE, doc="[x, y, yaw]")}

    def run(self, ctx: SkillContext, **_: Any) -> Outcome:
        pose = nav_stack(ctx).pose()
        return Outcome.success(current_pose=[round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)])


class ConcatenatePaths(Skill):
    name = "ConcatenatePaths"
    description = "Nav2's ConcatenatePaths: input_path1 then input_path2."
    inputs = {"input_path1": In(PATH, doc="the first path"), "input_path2": In(PATH, doc="the second path")}
    outputs = {"output_path": Out(PATH, doc="both, in order")}

    def run(self, ctx: SkillContext, input_path1: list[list[float]], input_path2: list[list[float]]) -> Outcome:
        if not input_path1 and not input_path2:
            return Outcome.failure("both paths are empty")
        return Outcome.success(output_path=[*input_path1, *input_path2])


class AppendGoalPoseToGoals(Skill):
    name = "AppendGoalPoseToGoals"
    description = "Nav2's AppendGoalPoseToGoals: input_goals with goal_pose at the end."
    inputs = {"goal_pose": In(GOAL, doc="a place or [x, y(, yaw)]"), "input_goals": In(GOALS, doc="the goals")}
    outputs = {"output_goals": Out(GOALS, doc="the goals, goal_pose last")}

    def run(self, ctx: SkillContext, goal_pose: Any, input_goals: list[Any]) -> Outcome:
        return Outcome.success(output_goals=[*input_goals, goal_pose])


class GetNextFewGoals(Skill):
    name = "GetNextFewGoals"
    description = "Nav2's GetNextFewGoals: the first num_goals of input_goals."
    inputs = {"num_goals": In(int, doc="how many"), "input_goals": In(GOALS, doc="the goals")}
    outputs = {"output_goals": Out(GOALS, doc="the first num_goals of them")}

    def run(self, ctx: SkillContext, num_goals: int, input_goals: list[Any]) -> Outcome:
        if num_goals < 0:
            return Outcome.failure(f"num_goals must not be negative, got {num_goals}")
        return Outcome.success(output_goals=list(input_goals[:num_goals]))


OCCUPANCY = {
    "cost_threshold": ignored("botstage's costmap has lethal cells and free ones", 254.0),
    "use_footprint": ignored("the robot's round footprint is in the inflated costmap", True),
    "consider_unknown_as_obstacle": ignored("unknown space is always an obstacle on botstage", False),
}


class CheckPoseOccupancy(Skill):
    name = "CheckPoseOccupancy"
    description = "Nav2's CheckPoseOccupancy: success when the robot cannot stand at `pose` (map and what is seen)."
    kind = "condition"
    inputs = {
        "pose": In(GOAL, doc="a place or [x, y(, yaw)]"),
        **OCCUPANCY,
        "service_name": ignored("botstage checks its own costmap, no service"),
        "server_timeout": ignored("no service to wait for"),
    }

    def run(self, ctx: SkillContext, pose: Any, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        try:
            x, y, _ = stack.resolve(pose)
        except ValueError as exc:
            return Outcome.failure(str(exc))
        return Outcome.failure(f"({x:g}, {y:g}) is free") if stack.free(x, y) else Outcome.success("occupied")


class RemoveInCollisionGoals(Skill):
    name = "RemoveInCollisionGoals"
    description = "Nav2's RemoveInCollisionGoals: drop the goals where the robot cannot stand."
    inputs = {
        "input_goals": In(GOALS, doc="the goals"),
        **OCCUPANCY,
        "input_waypoint_statuses": In(list | None, default=None, doc="one status per goal (Nav2's WaypointStatus)"),
        "service_name": ignored("botstage checks its own costmap, no service"),
        "server_timeout": ignored("no service to wait for"),
    }
    outputs = {
        "output_goals": Out(GOALS, doc="the goals the robot can stand at"),
        "output_waypoint_statuses": Out(list, doc="the statuses, dropped goals marked skipped"),
    }

    def run(self, ctx: SkillContext, input_goals: list[Any], input_waypoint_statuses: Any, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        statuses = [dict(s) if isinstance(s, dict) else {"status": s} for s in (input_waypoint_statuses or [])]
        kept = []
        for index, goal in enumerate(input_goals):
            try:
                x, y, _ = stack.resolve(goal)
            except ValueError as exc:
                return Outcome.failure(str(exc))
            if stack.free(x, y):
                kept.append(goal)
            elif index < len(statuses):
                statuses[index]["status"] = "skipped"
        return Outcome.success(
            f"{len(input_goals) - len(kept)} in collision", output_goals=kept, output_waypoint_statuses=statuses
        )


class CheckStopStatus(Skill):
    name = "CheckStopStatus"
    description = "Nav2's CheckStopStatus: RUNNING until the robot has been still for duration_stopped ms."
    inputs = {
        "velocity_threshold": In(float, default=0.01, doc="m/s (and rad/s) under which the robot is still"),
        "duration_stopped": In(int, default=1000, doc="ms it must stay still"),
    }

    def run(self, ctx: SkillContext, velocity_threshold: float, duration_stopped: int) -> SkillRun:
        odometry = ctx.interface("odometry")
        still_since: float | None = None
        while True:
            twist = odometry.read().twist
            now = ctx.clock.now()
            if abs(twist.v) < velocity_threshold and abs(twist.w) < velocity_threshold:
                still_since = now if still_since is None else still_since
                if now - still_since >= duration_stopped / 1000 - 1e-9:
                    return Outcome.success(f"still for {duration_stopped} ms")
            else:
                still_since = None
            yield


def _cancel(action: str, skill: str) -> type[Skill]:
    name = f"Cancel{action}"

    def run(self: Skill, ctx: SkillContext, **_: Any) -> Outcome:
        ctx.interface("drive").stop()
        return Outcome.success(f"stopped the robot ({skill})")

    return type(
        name,
        (Skill,),
        {
            "__module__": __name__,
            "name": name,
            "description": (
                f"Nav2's {name}: stop the robot. A running {skill} is cancelled when the tree halts it; "
                "this stops the motors now"
            ),
            "inputs": dict(SERVER),
            "run": run,
        },
    )


CancelControl = _cancel("Control", "FollowPath")
CancelBackUp = _cancel("BackUp", "BackUp")
CancelSpin = _cancel("Spin", "Spin")
CancelWait = _cancel("Wait", "Wait")
CancelDriveOnHeading = _cancel("DriveOnHeading", "DriveOnHeading")
