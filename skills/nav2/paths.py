"""Nav2's path and goal utilities: IsGoalNearby, TruncatePath(Local), IsPathValid/ValidatePath,
RemovePassedGoals. Paths are lists of [x, y] points (skills/nav2/common.py)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext
from botstage.skills.nav2.common import GOALS, PATH, SERVER, closest_index, ignored, length, sense, xy
from botstage.skills.navigate import nav_stack

FRAMES = {
    "global_frame": ignored("botstage's goals and paths are in the map frame"),
    "robot_base_frame": ignored("the robot's pose comes from its navigation stack"),
}


class IsGoalNearby(Skill):
    name = "IsGoalNearby"
    description = (
        "Nav2's IsGoalNearby: success when what is left of `path` past the robot is shorter than the threshold."
    )
    kind = "condition"
    inputs = {
        "path": In(PATH, doc="the planned path"),
        "proximity_threshold": In(float, default=1.0, doc="m of path left that counts as nearby"),
        "max_robot_pose_search_dist": In(float, default=-1.0, doc="m along the path to look for the robot; <0: all"),
        **FRAMES,
    }

    def run(
        self,
        ctx: SkillContext,
        path: list[list[float]],
        proximity_threshold: float,
        max_robot_pose_search_dist: float,
        **_: Any,
    ) -> Outcome:
        if not path:
            return Outcome.failure("the path is empty")
        pose = nav_stack(ctx).pose()
        at = closest_index(path, pose.x, pose.y, max_robot_pose_search_dist)
        left = length(xy(path)[at:])
        if left < proximity_threshold:
            return Outcome.success(f"{left:.2f} m of path left")
        return Outcome.failure(f"{left:.2f} m of path left, not under {proximity_threshold:g} m")


class TruncatePathLocal(Skill):
    name = "TruncatePathLocal"
    description = "Nav2's TruncatePathLocal: `input_path` from distance_backward behind to distance_forward ahead"
    inputs = {
        "input_path": In(PATH, doc="the path to cut"),
        "distance_forward": In(float, default=8.0, doc="m ahead of the robot kept; <0: to the end"),
        "distance_backward": In(float, default=4.0, doc="m behind the robot kept"),
        "robot_base_frame": ignored("the robot's pose comes from its navigation stack"),
        "transform_tolerance": ignored("no transforms to wait for", 0.2),
        "pose": In(list[float] | None, default=None, doc="[x, y(, theta)] to cut around instead of the robot's pose"),
        "angular_distance_weight": ignored("the nearest point by position alone", 0.0),
        "max_robot_pose_search_dist": In(float, default=math.inf, doc="m along the path to look for the robot"),
    }
    outputs = {"output_path": Out(PATH, doc="the part kept")}

    def run(
        self,
        ctx: SkillContext,
        input_path: list[list[float]],
        distance_forward: float,
        distance_backward: float,
        pose: Any,
        max_robot_pose_search_dist: float,
        **_: Any,
    ) -> Outcome:
        if not input_path:
            return Outcome.failure("the path is empty")
        if pose is None:
            here = nav_stack(ctx).pose()
            pose = [here.x, here.y]
        search = -1.0 if math.isinf(max_robot_pose_search_dist) else max_robot_pose_search_dist
        at = closest_index(input_path, pose[0], pose[1], search)
        steps = np.hypot(*np.diff(xy(input_path), axis=0).T) if len(input_path) > 1 else np.empty(0)
        along = np.concatenate(([0.0], np.cumsum(steps)))
        keep = along >= along[at] - distance_backward
        if distance_forward >= 0:
            keep &= along <= along[at] + distance_forward
        kept = [list(p) for p, k in zip(input_path, keep, strict=True) if k]
        return Outcome.success(f"{len(kept)} of {len(input_path)} points", output_path=kept)


class TruncatePath(Skill):
    name = "TruncatePath"
    description = "Nav2's TruncatePath: `input_path` without its last `distance` metres."
    inputs = {
        "input_path": In(PATH, doc="the path to cut"),
        "distance": In(float, default=1.0, doc="m cut off the end"),
    }
    outputs = {"output_path": Out(PATH, doc="the path, shortened")}

    def run(self, ctx: SkillContext, input_path: list[list[float]], distance: float) -> Outcome:
        if not input_path:
            return Outcome.failure("the path is empty")
        points = xy(input_path)
        to_end = np.concatenate((np.cumsum(np.hypot(*np.diff(points, axis=0).T)[::-1])[::-1], [0.0]))
        kept = [list(p) for p, d in zip(input_path, to_end, strict=True) if d >= distance] or [list(input_path[0])]
        return Outcome.success(f"{len(kept)} of {len(input_path)} points", output_path=kept)


def _collisions(ctx: SkillContext, path: list[list[float]], lookahead: float, first_only: bool) -> list[list[float]]:
    """The points of `path` (within `lookahead` m of the robot along it; <0: all) where the robot
    cannot stand on the map plus what the sensors see now; those under the robot do not count."""
    stack = nav_stack(ctx)
    sense(stack)
    pose = stack.pose()
    points = xy(path)
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T)))) if len(points) else points
    hits: list[list[float]] = []
    for (x, y), s in zip(points, along, strict=True):
        if lookahead >= 0 and s > lookahead:
            break
        if math.hypot(x - pose.x, y - pose.y) <= stack.robot_radius:
            continue
        if not stack.free(float(x), float(y)):
            hits.append([round(float(x), 4), round(float(y), 4)])
            if first_only:
                break
    return hits


class IsPathValid(Skill):
    name = "IsPathValid"
    description = "Nav2's IsPathValid: success when no point of `path` is blocked on the costmap."
    kind = "condition"
    inputs = {
        "path": In(PATH, doc="the path to check"),
        "max_cost": ignored("botstage's costmap has lethal cells and free ones; lethal is invalid", 254),
        "consider_unknown_as_obstacle": ignored("unknown space is always an obstacle on botstage", False),
        **SERVER,
    }

    def run(self, ctx: SkillContext, path: list[list[float]], **_: Any) -> Outcome:
        if not path:
            return Outcome.failure("the path is empty")
        hits = _collisions(ctx, path, -1.0, True)
        return Outcome.failure(f"blocked at {hits[0]}") if hits else Outcome.success()


class ValidatePath(Skill):
    name = "ValidatePath"
    description = "Nav2's ValidatePath: success when no point of `path` (up to the look-ahead) is blocked."
    kind = "condition"
    inputs = {
        "path": In(PATH, doc="the path to check"),
        "max_cost": ignored("botstage's costmap has lethal cells and free ones; lethal is invalid", 254),
        "consider_unknown_as_obstacle": ignored("unknown space is always an obstacle on botstage", False),
        "layer_name": ignored("botstage checks the whole costmap"),
        "footprint": ignored("the robot's round footprint is in the inflated costmap"),
        "stop_at_first_collision": In(bool, default=True, doc="stop at the first blocked point"),
        "max_lookahead_distance": In(float, default=-1.0, doc="m along the path checked; <0: all of it"),
        "service_name": ignored("botstage checks its own costmap, no service"),
        "server_timeout": ignored("no service to wait for"),
    }
    outputs = {"collision_poses": Out(PATH, doc="the blocked points; empty when valid")}

    def run(
        self,
        ctx: SkillContext,
        path: list[list[float]],
        stop_at_first_collision: bool,
        max_lookahead_distance: float,
        **_: Any,
    ) -> Outcome:
        if not path:
            return Outcome.failure("the path is empty", collision_poses=[])
        hits = _collisions(ctx, path, max_lookahead_distance, stop_at_first_collision)
        if hits:
            return Outcome.failure(f"blocked at {hits[0]}", collision_poses=hits)
        return Outcome.success(collision_poses=[])


class RemovePassedGoals(Skill):
    name = "RemovePassedGoals"
    description = "Nav2's RemovePassedGoals: drop the goals at the front of the list the robot is within `radius` of."
    inputs = {
        "radius": In(float, default=0.5, doc="m from a goal that counts as passed"),
        "robot_base_frame": ignored("the robot's pose comes from its navigation stack"),
        "input_goals": In(GOALS, doc="the goals left"),
        "input_waypoint_statuses": In(list | None, default=None, doc="one status per goal (Nav2's WaypointStatus)"),
    }
    outputs = {
        "output_goals": Out(GOALS, doc="the goals not yet passed"),
        "output_waypoint_statuses": Out(list, doc="the statuses, passed goals marked completed"),
    }

    def run(
        self, ctx: SkillContext, radius: float, input_goals: list[Any], input_waypoint_statuses: Any, **_: Any
    ) -> Outcome:
        stack = nav_stack(ctx)
        pose = stack.pose()
        goals = list(input_goals)
        statuses = [dict(s) if isinstance(s, dict) else {"status": s} for s in (input_waypoint_statuses or [])]
        passed = 0
        while len(goals) > 1:  # the last goal is the destination: never dropped (as Nav2)
            try:
                gx, gy, _ = stack.resolve(goals[0])
            except ValueError as exc:
                return Outcome.failure(str(exc))
            if math.hypot(gx - pose.x, gy - pose.y) > radius:
                break
            goals.pop(0)
            passed += 1
        done = sum(1 for s in statuses if s.get("status") == "completed")
        for status in statuses[done : done + passed]:
            status["status"] = "completed"
        return Outcome.success(f"{passed} passed", output_goals=goals, output_waypoint_statuses=statuses)
