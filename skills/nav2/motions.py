"""Nav2's behaviour server actions (Spin, BackUp, DriveOnHeading, Wait) as botstage's recoveries.

Each runs botstage's own skill (``botstage.skills.recoveries``, ``botstage.skills.wait``), which checks the sweep
of the robot's footprint and stops at the first contact, and reports Nav2's codes on failure.
"""

from __future__ import annotations

import math
from typing import Any

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.nav.contact import ContactWatch
from botstage.skills.nav.sweep import sweep
from botstage.skills.nav2.common import BEHAVIOR, SERVER, WAIT, ignored
from botstage.skills.navigate import nav_stack
from botstage.skills.recoveries import BackUp as BotstageBackUp
from botstage.skills.recoveries import Spin as BotstageSpin
from botstage.skills.wait import Wait as BotstageWait

RESULT = {
    "error_code_id": Out(int, doc="0, or Nav2's behaviour code (701 TIMEOUT, 703 COLLISION_AHEAD, 704 INVALID_INPUT)"),
    "error_msg": Out(str, doc="why it failed"),
}
TIME_ALLOWANCE = In(float, default=10.0, doc="s of mission time before it fails as TIMEOUT")
COLLISIONS = ignored("botstage always checks the footprint's sweep and stops at contact", False)


def _result(outcome: Outcome) -> Outcome:
    """botstage's outcome with Nav2's result ports."""
    if outcome.name == "success":
        return Outcome.success(outcome.reason, error_code_id=0, error_msg="")
    code = BEHAVIOR["TIMEOUT"] if outcome.name == "timeout" else BEHAVIOR["COLLISION_AHEAD"]
    if "must be positive" in outcome.reason:
        code = BEHAVIOR["INVALID_INPUT"]
    return Outcome.failure(outcome.reason, error_code_id=code, error_msg=outcome.reason)


class Spin(Skill):
    name = "Spin"
    description = "Nav2's Spin: turn in place by spin_dist rad."
    inputs = {
        "spin_dist": In(float, default=1.57, doc="rad, counter-clockwise positive"),
        "time_allowance": TIME_ALLOWANCE,
        "is_recovery": ignored("botstage counts recoveries in the trace", True),
        "disable_collision_checks": COLLISIONS,
        **SERVER,
    }
    outputs = RESULT

    def run(self, ctx: SkillContext, spin_dist: float, time_allowance: float, **_: Any) -> SkillRun:
        outcome = yield from BotstageSpin().run(ctx, angle=spin_dist, speed=0.8, timeout=time_allowance)
        return _result(outcome)


class BackUp(Skill):
    name = "BackUp"
    description = "Nav2's BackUp: reverse backup_dist m at backup_speed, as far as there is room."
    inputs = {
        "backup_dist": In(float, default=0.15, doc="m"),
        "backup_speed": In(float, default=0.025, doc="m/s"),
        "time_allowance": TIME_ALLOWANCE,
        "disable_collision_checks": COLLISIONS,
        **SERVER,
    }
    outputs = RESULT

    def run(
        self, ctx: SkillContext, backup_dist: float, backup_speed: float, time_allowance: float, **_: Any
    ) -> SkillRun:
        outcome = yield from BotstageBackUp().run(
            ctx, distance=abs(backup_dist), speed=abs(backup_speed), timeout=time_allowance
        )
        return _result(outcome)


class DriveOnHeading(Skill):
    name = "DriveOnHeading"
    description = "Nav2's DriveOnHeading: drive straight dist_to_travel m at speed (negative: backwards)."
    inputs = {
        "dist_to_travel": In(float, default=0.15, doc="m"),
        "speed": In(float, default=0.025, doc="m/s; the sign of the product says forwards or backwards"),
        "time_allowance": TIME_ALLOWANCE,
        "disable_collision_checks": COLLISIONS,
        **SERVER,
    }
    outputs = RESULT

    def run(self, ctx: SkillContext, dist_to_travel: float, speed: float, time_allowance: float, **_: Any) -> SkillRun:
        if dist_to_travel == 0 or speed == 0 or (dist_to_travel > 0) != (speed > 0):
            reason = f"dist_to_travel {dist_to_travel:g} and speed {speed:g} must be non-zero, of the same sign"
            return Outcome.failure(reason, error_code_id=BEHAVIOR["INVALID_INPUT"], error_msg=reason)
        stack, drive = nav_stack(ctx), ctx.interface("drive")
        watch = ContactWatch.for_robot(ctx.interfaces, ctx.clock)
        start, target = stack.pose(), abs(dist_to_travel)
        deadline = ctx.clock.now() + time_allowance
        try:
            while True:
                pose = stack.pose()
                gone = math.hypot(pose.x - start.x, pose.y - start.y)
                if gone >= target - 0.01:
                    return Outcome.success(f"drove {gone:.2f} m", error_code_id=0, error_msg="")
                failed, code = "", 0
                if ctx.clock.now() >= deadline:
                    failed, code = f"drove {gone:.2f} of {target:.2f} m in {time_allowance:g} s", BEHAVIOR["TIMEOUT"]
                contact = watch.check() if watch is not None else None
                ahead = sweep(stack, pose, speed, 0.0, min(target - gone, 1.0) / abs(speed))
                if contact is not None or not ahead.clear:
                    failed = f"stopped after {gone:.2f} m: {contact or ahead.blocker} ahead"
                    code = BEHAVIOR["COLLISION_AHEAD"]
                if failed:
                    return Outcome.failure(failed, error_code_id=code, error_msg=failed)
                drive.cmd_vel(speed, 0.0)
                if watch is not None:
                    watch.commanded(speed, 0.0)
                yield
        finally:
            drive.stop()


class Wait(Skill):
    name = "Wait"
    description = "Nav2's Wait: succeed after wait_duration s of mission time."
    inputs = {"wait_duration": In(float, default=1.0, doc="s of mission time"), **SERVER}
    outputs = RESULT

    def run(self, ctx: SkillContext, wait_duration: float, **_: Any) -> SkillRun:
        if not (math.isfinite(wait_duration) and wait_duration >= 0):
            reason = f"wait_duration must be a number of seconds ≥ 0, got {wait_duration}"
            return Outcome.failure(reason, error_code_id=WAIT["UNKNOWN"], error_msg=reason)
        outcome = yield from BotstageWait().run(ctx, duration=wait_duration)
        return Outcome.success(outcome.reason, error_code_id=0, error_msg="")
