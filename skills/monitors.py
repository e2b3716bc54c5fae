"""Monitors: skills that run beside a mission and turn a device's readings into blackboard keys.

Machine preemptions and guards are conditions on the blackboard, so a battery that runs low or
something standing in front of the robot must reach the blackboard first. Each monitor runs
until it is cancelled (put it in a parallel beside the machine) and writes only when what it
reports changes, so the trace is not a copy of the sensor stream:

- ``watch_battery``: the battery's percent (to 0.5 %) and a ``low`` flag, latched once the
  percent has stayed below ``low`` for ``confirm`` seconds (a voltage that sags under load for a
  moment does not send the robot home; one that stays low does, and it does not change its mind;
  a reading that fails is logged once and the last values kept);
- ``watch_sonar``: a ``blocked`` flag while the ultrasonic range is below ``threshold`` and what
  it sees is not on the map (a wall or a table the robot is meant to stop at is not an obstacle);
- ``odometer``: the distance driven, integrated from the odometry's pose increments;
- ``watch_people``: an ``ahead`` flag while a tracked person stands in the robot's way (within
  ``distance`` ahead and ``half_width`` either side of its heading), from the people tracking
  (a people sensor, or faces in a camera) and the robot's pose estimate.
"""

from __future__ import annotations

import math

import numpy as np

from botstage.skills.base import In, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.nav.stack import sonar_points


def _write(ctx: SkillContext, key: str, value: object) -> None:
    if not ctx.blackboard.exists(key) or ctx.blackboard.get(key) != value:
        ctx.blackboard.set(key, value)


class WatchBattery(Skill):
    name = "watch_battery"
    description = "Until cancelled: write the battery's percent and latch `low_key` once it stays below `low`."
    inputs = {
        "low": In(float, default=20.0, doc="percent below which the battery is low"),
        "confirm": In(Seconds, default=3.0, doc="s the percent must stay below `low` before it counts"),
        "percent_key": In(str, doc="the float key for the percent (to 0.5 %)", names_key="write"),
        "low_key": In(str, doc="the bool key set true once the battery is low", names_key="write"),
    }

    def run(self, ctx: SkillContext, low: float, confirm: float, percent_key: str, low_key: str) -> SkillRun:
        battery = ctx.interface("battery")
        below_since: float | None = None
        latched = False
        failing = False
        while True:
            try:
                state = battery.read()
            except Exception as error:  # a board that stopped reporting: keep what was written
                if not failing:
                    ctx.logger.warning(f"cannot read the battery: {error}")
                failing = True
                yield
                continue
            failing = False
            now = ctx.clock.now()
            _write(ctx, percent_key, round(state.percent * 2) / 2)
            if state.percent < low:
                below_since = now if below_since is None else below_since
                if not latched and now - below_since >= confirm - 1e-9:
                    latched = True
                    ctx.logger.warning(f"battery low: {state.percent:.1f} % ({state.voltage:.2f} V) under {low:g} %")
            else:
                below_since = None
            _write(ctx, low_key, latched)
            yield


class WatchSonar(Skill):
    name = "watch_sonar"
    description = "Until cancelled: set `blocked_key` while the sonar sees something not on the map within `threshold`."
    inputs = {
        "threshold": In(float, default=0.4, doc="m from the sonar: anything nearer is in the way"),
        "blocked_key": In(str, doc="the bool key: something is in front of the robot", names_key="write"),
        "range_key": In(str, doc="the float key: the range (m) when `blocked` last changed", names_key="write"),
    }

    def run(self, ctx: SkillContext, threshold: float, blocked_key: str, range_key: str) -> SkillRun:
        if threshold <= 0:
            return Outcome.failure(f"threshold must be positive, got {threshold}")
        sonar = ctx.interface("sonar")
        navigation = ctx.interfaces.get("navigation")
        blocked: bool | None = None
        while True:
            reading = sonar.read()
            near = math.isfinite(reading.range) and reading.range < threshold
            if near and navigation is not None:
                near = math.isfinite(navigation.unmapped_distance(_in_base(reading, navigation.sonar_mount)))
            if near != blocked:
                blocked = near
                shown = round(reading.range, 3) if math.isfinite(reading.range) else -1.0
                ctx.blackboard.set(range_key, shown)
                ctx.blackboard.set(blocked_key, near)
                if near:
                    ctx.logger.info(f"something {reading.range:.2f} m in front, not on the map")
            yield


def _in_base(reading: object, mount: tuple[float, float, float]) -> np.ndarray:
    """The echo's points in the robot's base frame (the sonar sits at ``mount``)."""
    points = sonar_points(reading)  # type: ignore[arg-type]
    mx, my, mtheta = mount
    c, s = math.cos(mtheta), math.sin(mtheta)
    return np.column_stack((mx + c * points[:, 0] - s * points[:, 1], my + s * points[:, 0] + c * points[:, 1]))


class Odometer(Skill):
    name = "odometer"
    description = "Until cancelled: add up the distance the odometry says the robot drove, into `key` (metres)."
    inputs = {
        "key": In(str, doc="the float key for the distance (to the centimetre)", names_key="write"),
        "every": In(Seconds, default=1.0, doc="s between writes (and one when cancelled)"),
    }

    def run(self, ctx: SkillContext, key: str, every: float) -> SkillRun:
        if every <= 0:
            return Outcome.failure(f"every must be positive, got {every}")
        odometry = ctx.interface("odometry")
        start = ctx.blackboard.get(key) if ctx.blackboard.exists(key) else 0.0
        total = float(start or 0.0)
        last = odometry.read().pose
        written = ctx.clock.now()
        try:
            while True:
                yield
                pose = odometry.read().pose
                total += math.hypot(pose.x - last.x, pose.y - last.y)
                last = pose
                if ctx.clock.now() - written >= every - 1e-9:
                    written = ctx.clock.now()
                    _write(ctx, key, round(total, 2))
        finally:
            _write(ctx, key, round(total, 2))


class WatchPeople(Skill):
    name = "watch_people"
    description = "Until cancelled: set `ahead_key` while a tracked person stands in the robot's way."
    inputs = {
        "distance": In(float, default=3.0, doc="m ahead of the robot within which a person is in its way"),
        "half_width": In(float, default=0.6, doc="m either side of the robot's heading that count as its way"),
        "ahead_key": In(str, doc="the bool key: someone stands in front of the robot", names_key="write"),
        "distance_key": In(
            str, doc="the float key: the nearest one's distance (m) when `ahead` last changed", names_key="write"
        ),
    }

    def run(self, ctx: SkillContext, distance: float, half_width: float, ahead_key: str, distance_key: str) -> SkillRun:
        if distance <= 0 or half_width <= 0:
            return Outcome.failure(f"distance and half_width must be positive, got {distance} and {half_width}")
        tracking = ctx.interface("people_tracking")
        localization = ctx.interface("localization")
        ahead: bool | None = None
        while True:
            pose = localization.pose()
            c, s = math.cos(pose.theta), math.sin(pose.theta)
            nearest = math.inf
            for _id, x, y in tracking.update().people:
                forward, side = (x - pose.x) * c + (y - pose.y) * s, -(x - pose.x) * s + (y - pose.y) * c
                if 0.0 < forward <= distance and abs(side) <= half_width:
                    nearest = min(nearest, forward)
            now_ahead = math.isfinite(nearest)
            if now_ahead != ahead:
                ahead = now_ahead
                ctx.logger.info(f"a person {nearest:.1f} m ahead" if now_ahead else "nobody ahead")
                _write(ctx, distance_key, round(nearest, 2) if now_ahead else 0.0)
                _write(ctx, ahead_key, now_ahead)
            yield
