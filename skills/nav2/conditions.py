"""Nav2's condition nodes that read the robot or a value: error codes, battery, goal, poses."""

from __future__ import annotations

import math
from typing import Any

from botstage.skills.base import In, Outcome, Skill, SkillContext
from botstage.skills.nav2.common import CODES, GOAL, codes, ignored
from botstage.skills.navigate import nav_stack

ERROR_CODE = In(int, doc="the last error code of the server (e.g. {follow_path_error_code})")
TO_CHECK = In(CODES, default=None, doc="codes that count, 'a;b' or a list; unset: the node's own set")


class _WouldHelp(Skill):
    """Success when ``error_code`` is one a recovery can do something about."""

    kind = "condition"
    inputs = {"error_code": ERROR_CODE, "error_codes_to_check": TO_CHECK}
    helps: tuple[int, ...] = ()

    def run(self, ctx: SkillContext, error_code: int, error_codes_to_check: Any) -> Outcome:
        try:
            wanted = codes(error_codes_to_check, self.helps)
        except ValueError as exc:
            return Outcome.failure(str(exc))
        if error_code in wanted:
            return Outcome.success(f"error code {error_code} is one a recovery may help")
        return Outcome.failure(f"error code {error_code} is not among {sorted(wanted)}")


class WouldAControllerRecoveryHelp(_WouldHelp):
    name = "WouldAControllerRecoveryHelp"
    description = "Nav2's WouldAControllerRecoveryHelp: FollowPath failed in a way a recovery may fix (100, 104-106)."
    helps = (100, 104, 105, 106)


class WouldAPlannerRecoveryHelp(_WouldHelp):
    name = "WouldAPlannerRecoveryHelp"
    description = "Nav2's WouldAPlannerRecoveryHelp: planning failed in a way a recovery may fix (x00, x07, x08)."
    helps = (200, 207, 208, 300, 307, 308)


class WouldASmootherRecoveryHelp(_WouldHelp):
    name = "WouldASmootherRecoveryHelp"
    description = "Nav2's WouldASmootherRecoveryHelp: smoothing failed in a way a recovery may fix (500, 501, 503)."
    helps = (500, 501, 503)


class WouldARouteRecoveryHelp(_WouldHelp):
    name = "WouldARouteRecoveryHelp"
    description = "Nav2's WouldARouteRecoveryHelp: routing failed in a way a recovery may fix (400, 404-406)."
    helps = (400, 404, 405, 406)


class AreErrorCodesPresent(_WouldHelp):
    name = "AreErrorCodesPresent"
    description = "Nav2's AreErrorCodesPresent: success when error_code is among error_codes_to_check."
    inputs = {"error_code": ERROR_CODE, "error_codes_to_check": In(CODES, doc="codes that count, 'a;b' or a list")}


class TransformAvailable(Skill):
    name = "TransformAvailable"
    description = "Nav2's TransformAvailable: botstage has no tf tree; the map and robot frames always exist."
    kind = "condition"
    inputs = {"child": In(str, default="", doc="child frame"), "parent": In(str, default="", doc="parent frame")}

    def run(self, ctx: SkillContext, child: str, parent: str) -> Outcome:
        if not child or not parent:
            return Outcome.failure("TransformAvailable needs both `child` and `parent`")
        return Outcome.success(f"{parent} -> {child}: botstage's poses are all in the map frame")


class IsBatteryLow(Skill):
    name = "IsBatteryLow"
    description = "Nav2's IsBatteryLow: success when the robot's battery is at or under min_battery."
    kind = "condition"
    inputs = {
        "min_battery": In(float, doc="a fraction 0..1 (ROS BatteryState.percentage), or volts with is_voltage"),
        "battery_topic": ignored("the robot's battery interface is read directly", "/battery_status"),
        "is_voltage": In(bool, default=False, doc="compare volts instead of the charge"),
    }

    def run(self, ctx: SkillContext, min_battery: float, is_voltage: bool, **_: Any) -> Outcome:
        state = ctx.interface("battery").read()
        value = state.voltage if is_voltage else state.percent / 100
        shown = f"{value:.2f} V" if is_voltage else f"{value:.0%}"
        if value <= min_battery:
            return Outcome.success(f"battery low: {shown}")
        return Outcome.failure(f"battery at {shown}")


class IsBatteryCharging(Skill):
    name = "IsBatteryCharging"
    description = "Nav2's IsBatteryCharging: success when current flows into the robot's battery."
    kind = "condition"
    inputs = {"battery_topic": ignored("the robot's battery interface is read directly", "/battery_status")}

    def run(self, ctx: SkillContext, **_: Any) -> Outcome:
        state = ctx.interface("battery").read()
        if state.current < 0:
            return Outcome.success(f"charging at {-state.current:.2f} A")
        return Outcome.failure("not charging")


class GoalReached(Skill):
    name = "GoalReached"
    description = "Nav2's GoalReached: success when the robot is within 0.25 m of `goal`."
    kind = "condition"
    inputs = {
        "goal": In(GOAL, doc="a place of the map or [x, y(, theta)]"),
        "robot_base_frame": ignored("the robot's pose comes from its navigation stack"),
    }

    def run(self, ctx: SkillContext, goal: Any, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        try:
            gx, gy, _ = stack.resolve(goal)
        except ValueError as exc:
            return Outcome.failure(str(exc))
        pose = stack.pose()
        gap = math.hypot(gx - pose.x, gy - pose.y)
        return Outcome.success(f"{gap:.2f} m away") if gap <= 0.25 else Outcome.failure(f"{gap:.2f} m away")


class InitialPoseReceived(Skill):
    name = "InitialPoseReceived"
    description = "Nav2's InitialPoseReceived: success when `initial_pose_received` is true."
    kind = "condition"
    inputs = {"initial_pose_received": In(bool, doc="usually {initial_pose_received}")}

    def run(self, ctx: SkillContext, initial_pose_received: bool) -> Outcome:
        return Outcome.success() if initial_pose_received else Outcome.failure("no initial pose yet")


class ArePosesNear(Skill):
    name = "ArePosesNear"
    description = "Nav2's ArePosesNear: success when two poses are within `tolerance` m."
    kind = "condition"
    inputs = {
        "ref_pose": In(GOAL, doc="a place or [x, y(, theta)]"),
        "target_pose": In(GOAL, doc="a place or [x, y(, theta)]"),
        "global_frame": ignored("botstage's poses are in the map frame"),
        "tolerance": In(float, default=0.5, doc="m"),
    }

    def run(self, ctx: SkillContext, ref_pose: Any, target_pose: Any, tolerance: float, **_: Any) -> Outcome:
        stack = nav_stack(ctx)
        try:
            (ax, ay, _), (bx, by, _) = stack.resolve(ref_pose), stack.resolve(target_pose)
        except ValueError as exc:
            return Outcome.failure(str(exc))
        gap = math.hypot(ax - bx, ay - by)
        return Outcome.success(f"{gap:.2f} m apart") if gap <= tolerance else Outcome.failure(f"{gap:.2f} m apart")
