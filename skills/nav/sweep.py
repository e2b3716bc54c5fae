"""How far an open-loop motion may go: the robot's footprint swept along it, checked against
what the robot knows (its map, its obstacle layer, what its range sensors see).

A skill that drives blind (back up, move, turn) asks this before it starts and again every tick
and stops short of the first thing in the way. The end point alone is not enough: a reverse of a
metre may clear a plinth at its end and meet its corner on the way. The footprint is the
profile's circle, so a turn in place sweeps nothing new; the centre is sampled every half cell
along the arc. A point of the path is in the way when the footprint would come within
``margin`` of something (room for the pose estimate's error) and nearer than it starts: moving
away from or along something already close is allowed, closing in is not. The range sensors
are read only when one of them looks the way the robot goes; reversing, what they saw near it
of late is all it knows of what is behind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from botstage.robots.interfaces import Pose2D
from botstage.skills.nav.stack import NavStack

MARGIN = 0.05  # m kept between the footprint and what the robot knows of: the estimate's error
CLOSING = 0.01  # m: nearer than the start by more than this counts as closing in (sensor noise)
MAX_SAMPLES = 4000


@dataclass(frozen=True)
class Sweep:
    """The part of a motion that stays clear: ``time`` s of the ``duration`` asked for."""

    time: float
    duration: float
    blocker: str = ""  # what ends it early (on the map, or seen by the sensors); "" for nothing
    at: tuple[float, float] | None = None  # where the robot's centre would be when it touched

    @property
    def clear(self) -> bool:
        return self.time >= self.duration


def arc(pose: Pose2D, v: float, w: float, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres of a robot driven at (v, w) from ``pose`` after each of ``times`` seconds."""
    if abs(w) < 1e-9:
        return pose.x + v * times * math.cos(pose.theta), pose.y + v * times * math.sin(pose.theta)
    theta = pose.theta + w * times
    radius = v / w
    return (
        pose.x + radius * (np.sin(theta) - math.sin(pose.theta)),
        pose.y - radius * (np.cos(theta) - math.cos(pose.theta)),
    )


def sweep(stack: NavStack, pose: Pose2D, v: float, w: float, duration: float, *, margin: float = MARGIN) -> Sweep:
    """How long the robot may drive at (v, w) from ``pose`` before its footprint comes too close
    to what its map, its obstacle layer or its sensors show."""
    duration = max(duration, 0.0)
    length = abs(v) * duration
    if length <= 0.0:
        return Sweep(duration, duration)  # turning in place: a round footprint sweeps nothing new
    count = min(MAX_SAMPLES, math.ceil(length / (stack.grid.resolution / 2)))
    times = np.linspace(0.0, duration, count + 1)
    xs, ys = arc(pose, v, w, times)
    first, blocker = len(times), ""
    for name, clearance in (
        ("an obstacle on the robot's map", stack.map_clearance(xs, ys)),
        ("an obstacle its sensors see", stack.sensed_clearance(xs, ys, fresh=stack.sees(0.0 if v > 0 else math.pi))),
    ):
        hits = np.nonzero(in_the_way(clearance, stack.robot_radius, margin))[0]
        if len(hits) and hits[0] < first:
            first, blocker = int(hits[0]), name
    if not blocker:
        return Sweep(duration, duration)
    return Sweep(float(times[first - 1]), duration, blocker, (float(xs[first]), float(ys[first])))


def in_the_way(clearance: np.ndarray, radius: float, margin: float) -> np.ndarray:
    """Which points of a path (clearances from the first, where the robot is) it may not reach:
    where the footprint would touch, or come within the margin nearer than it starts."""
    start = clearance[0]
    touching = clearance <= radius + 1e-6
    blocked = (clearance < radius + margin) & (clearance < start - CLOSING)
    if start > radius + 1e-6:
        blocked |= touching  # an estimate already inside something may still move out of it
    blocked[0] = False  # where the robot is, it is
    return blocked
