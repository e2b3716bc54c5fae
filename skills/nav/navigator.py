"""Driving to a goal: plan, follow, and replan around what blocks the way.

One generator, shared by navigate, wander, approach and back_to_point: it yields once per tick
and returns a ``NavResult`` whose outcome is one of ``succeeded``, ``unreachable``, ``blocked``,
``timeout`` or ``cancelled``, with a reason. What it does when the way is blocked:

0. when the odometry shows no headway under a motion command, it touched something no sensor
   showed: it stops at once, puts that spot on the obstacle layer and goes on as blocked;
1. stop, and wait ``patience`` seconds: a person walking past moves on by themselves;
2. stamp what the sensors see into the stack's obstacle layer and plan again around it;
3. when no path is left, keep looking until ``blocked_timeout`` (people move, the layer
   forgets), then give up with ``blocked``. The heavier recoveries (clear the costmap, spin,
   back up, wait longer) are skills of their own, composed in a tree around navigate
   (``missions/lib/navigation.yaml``), so a mission can change them.

The robot is stopped on every way out, cancellation included.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from botstage.robots.interfaces import Pose2D
from botstage.skills.nav.contact import ContactWatch, touched
from botstage.skills.nav.controller import Command, PathFollower
from botstage.skills.nav.planner import Unreachable
from botstage.skills.nav.stack import NavStack

OUTCOMES = ("succeeded", "unreachable", "blocked", "timeout", "cancelled")
# at rest: moved under a millimetre and turned under 0.05 deg in a tick; waited for at most a second
SETTLED_MOVE = 0.001
SETTLED_TURN = math.radians(0.05)
SETTLE_LIMIT = 1.0


class NavParams(BaseModel):
    """Tuning of goal-directed driving (set per robot in a profile's `skills:` or per node)."""

    model_config = ConfigDict(extra="forbid")
    patience: float = Field(default=1.5, gt=0, description="s stopped before planning around an obstacle")
    blocked_timeout: float = Field(default=20.0, gt=0, description="s without a way through before `blocked`")
    replan_every: float = Field(default=0.0, ge=0, description="s between replans while moving (0: only when blocked)")
    max_speed: float | None = Field(default=None, gt=0, description="m/s, below the robot's own limit")
    time_per_metre: float = Field(default=6.0, gt=0, description="s per metre of path for the automatic timeout")
    min_timeout: float = Field(default=30.0, gt=0, description="s: the automatic timeout is at least this")


@dataclass(frozen=True)
class NavResult:
    outcome: str
    reason: str
    pose: Pose2D
    travelled: float
    replans: int

    @property
    def succeeded(self) -> bool:
        return self.outcome == "succeeded"


def drive_to(
    stack: NavStack,
    drive: Any,
    goal: tuple[float, float, float | None],
    params: NavParams,
    *,
    tolerance: float = 0.05,
    heading_tolerance: float = 0.05,
    timeout: float = 0.0,
    cancel: Callable[[], bool] | None = None,
    log: Callable[[str], None] | None = None,
) -> Generator[None, None, NavResult]:
    """Drive to ``goal`` (x, y, heading or None); ``timeout`` 0 means from the path's length."""
    clock = stack.clock
    start_time = clock.now()
    gx, gy, heading = goal
    pose = stack.pose()
    travelled, replans, last = 0.0, 0, pose
    follower_params = stack.follower_params(tolerance, heading_tolerance, params.max_speed)

    def result(outcome: str, reason: str) -> NavResult:
        return NavResult(outcome, reason, stack.pose(), travelled, replans)

    try:
        plan = stack.plan((pose.x, pose.y), (gx, gy))
    except Unreachable as exc:
        return result("unreachable", str(exc))
    if timeout <= 0:
        timeout = max(params.min_timeout, params.time_per_metre * plan.length)
    deadline = start_time + timeout
    follower = PathFollower(plan.points, heading, follower_params)
    stack.path = plan.points  # what the robot drives now, for viewers (the monitor's map)
    blocked_since: float | None = None  # this stop
    stuck_since: float | None = None  # the first stop since the robot last made headway
    stuck_travelled = 0.0
    planned_at = start_time
    settling_since: float | None = None
    # the last resort: stop at the first contact, not push (needs the wheels' odometry)
    watch = ContactWatch.for_robot({"navigation": stack}, clock)
    try:
        while True:
            if cancel is not None and cancel():
                return result("cancelled", "cancelled by its condition")
            now = clock.now()
            if now >= deadline:
                left = math.hypot(gx - pose.x, gy - pose.y)
                return result("timeout", f"not there after {timeout:.0f} s ({left:.2f} m to go)")
            pose = stack.pose()
            moved = math.hypot(pose.x - last.x, pose.y - last.y)
            turned = abs(math.remainder(pose.theta - last.theta, math.tau))
            travelled += moved
            last = pose
            obstacles = stack.obstacles()
            command = follower.command(pose, obstacles, stack.unmapped_distance(obstacles))
            contact = watch.check() if watch is not None else None
            if watch is not None and contact is not None and command.state != "arrived":
                # it touched something no sensor showed: put it on the obstacle layer, then as blocked
                stack.mark(pose, touched(watch.last_command, stack.robot_radius))
                command = Command(0.0, 0.0, "blocked", contact)
            if command.state == "arrived":
                drive.stop()
                if watch is not None:
                    watch.commanded(0.0, 0.0)
                # there is where the robot came to rest: while it still rolls or turns, look again
                # next tick (the follower corrects if it rolled out of the tolerance)
                still = moved < SETTLED_MOVE and turned < SETTLED_TURN
                if settling_since is None:
                    settling_since = now
                if not still and now - settling_since < SETTLE_LIMIT:
                    yield
                    continue
                return result("succeeded", f"at ({pose.x:.2f}, {pose.y:.2f}) after {travelled:.1f} m")
            settling_since = None
            if command.state != "blocked":
                blocked_since = None
                if stuck_since is not None and travelled - stuck_travelled >= 0.5:
                    stuck_since = None
                drive.cmd_vel(command.v, command.w)
                if watch is not None:
                    watch.commanded(command.v, command.w)
                if params.replan_every and now - planned_at >= params.replan_every:
                    try:
                        points = stack.plan((pose.x, pose.y), (gx, gy)).points
                        follower = PathFollower(points, heading, follower_params)
                        stack.path = points
                        planned_at = now
                    except Unreachable:
                        pass  # keep the path it has; the follower stops if it becomes blocked
                yield
                continue
            drive.stop()
            if watch is not None:
                watch.commanded(0.0, 0.0)
            if stuck_since is None:
                stuck_since, stuck_travelled = now, travelled
            if blocked_since is None:
                blocked_since = now
                if log is not None:
                    log(f"blocked: {command.reason}; waiting {params.patience:g} s")
            if now - blocked_since >= params.patience:
                stack.mark(pose, stack.obstacles())
                try:
                    plan = stack.plan((pose.x, pose.y), (gx, gy))
                except Unreachable as exc:
                    if now - stuck_since >= params.blocked_timeout:
                        return result("blocked", f"{command.reason}, and no way around: {exc}")
                else:
                    replans += 1
                    follower = PathFollower(plan.points, heading, follower_params)
                    stack.path = plan.points
                    blocked_since = None
                    planned_at = now
                    if log is not None:
                        log(f"replanned around what blocked the way ({plan.length:.1f} m)")
            if now - stuck_since >= params.blocked_timeout:
                return result("blocked", f"{command.reason}; no headway for {now - stuck_since:.0f} s")
            yield
    finally:
        stack.path = None
        drive.stop()
