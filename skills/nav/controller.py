"""Following a path: regulated pure pursuit with collision checking on the laser.

Pure pursuit steers towards a point one look-ahead distance along the path; "regulated" slows
the robot on tight curves, when nearing the goal, and when the laser sees something close ahead
(Macenski et al., the controller Nav2 ships). When something is closer than the stop distance
in the robot's path, it stops and reports `blocked` so the skill can replan or recover. When
the path lies behind the robot, it turns in place first; at the goal it turns to the goal's
heading.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from botstage.robots.interfaces import LaserScan, Pose2D


@dataclass(frozen=True)
class FollowerParams:
    max_linear: float = 0.35
    max_angular: float = 1.5
    lookahead: float = 0.6
    goal_tolerance: float = 0.08  # m
    arrive_ahead: float = 0.0025  # m: in the tolerance, the goal may lie this far ahead when stopping
    heading_tolerance: float = 0.06  # rad
    slow_near_goal: float = 0.8  # m: ramp down over this distance
    min_linear: float = 0.05
    min_turning_radius: float = 0.4  # m: slow down on curves tighter than this
    rotate_threshold: float = math.radians(60)  # turn in place when the path is this far off
    robot_radius: float = 0.2
    margin: float = 0.05  # m kept free around the footprint: never squeeze through a gap the exact width
    stop_clearance: float = 0.25  # m beyond the robot's radius: room left to turn away
    slow_clearance: float = 0.8
    laser_x: float = 0.0  # m: where the laser sits ahead of the base's centre (for a LaserScan)
    max_decel: float = 0.5  # m/s²: never faster than can stop before what is ahead
    evade: bool = True  # try other arcs when blocked: only with sensors that see the sides (a laser)
    caution_gain: float = 0.35  # 1/s: near something not on the map (people), at most this x its distance


@dataclass(frozen=True)
class Command:
    v: float
    w: float
    state: str  # following, rotating, aligning, arrived, blocked
    reason: str = ""


def _angle(theta: float) -> float:
    return (theta + math.pi) % (2 * math.pi) - math.pi


class PathFollower:
    def __init__(self, path: list[tuple[float, float]], goal_heading: float | None, params: FollowerParams) -> None:
        if not path:
            raise ValueError("a path needs at least its goal")
        self.path = _densify(np.asarray(path, dtype=float), 0.05)  # so the look-ahead never falls behind
        self.goal_heading = goal_heading
        self.params = params
        self._progress = 0  # index of the path point closest to the robot so far (never goes back)
        # once there, stay there: turn to the goal's heading in place, without chasing the
        # millimetres a turn on slipping wheels moves the robot (nav2's stateful goal checker)
        self._in_position = False

    def command(
        self, pose: Pose2D, obstacles: LaserScan | np.ndarray | None = None, unmapped: float = math.inf
    ) -> Command:
        """The velocity for this tick. ``obstacles``: a laser scan (mounted ``laser_x`` ahead of the
        base's centre) or sensed points in the base frame (x ahead, y left). ``unmapped``: how far
        the nearest thing the map does not have is (a person may step out of it): the robot
        keeps to a speed it can stop from well before it."""
        p = self.params
        gx, gy = self.path[-1]
        to_goal = math.hypot(gx - pose.x, gy - pose.y)
        if to_goal > 3 * p.goal_tolerance:
            self._in_position = False  # pushed away: go back
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        goal_ahead = c * (gx - pose.x) + s * (gy - pose.y)
        # within the tolerance, still creep on while the goal lies ahead: the tolerance is what is
        # accepted, the goal is what is aimed at (arrivals spread over the tolerance disk otherwise)
        there = to_goal <= p.goal_tolerance and (goal_ahead <= p.arrive_ahead or to_goal <= p.arrive_ahead)
        if there or self._in_position:
            if not self._in_position:
                # stop rolling before turning: on a base that limits each wheel's acceleration, a
                # turn started at speed keeps the robot rolling forward while the wheels cross over
                self._in_position = True
                return Command(0.0, 0.0, "aligning")
            if self.goal_heading is None:
                return Command(0.0, 0.0, "arrived")
            error = _angle(self.goal_heading - pose.theta)
            if abs(error) <= p.heading_tolerance:
                return Command(0.0, 0.0, "arrived")
            return Command(0.0, _clamp(2.0 * error, p.max_angular, minimum=0.2), "aligning")
        tx, ty = self._lookahead_point(pose)
        dx, dy = tx - pose.x, ty - pose.y
        ahead, left = c * dx + s * dy, -s * dx + c * dy  # the target in the robot's frame
        bearing = math.atan2(left, ahead)
        if abs(bearing) > p.rotate_threshold:
            return Command(0.0, _clamp(2.0 * bearing, p.max_angular, minimum=0.3), "rotating")
        distance_sq = ahead * ahead + left * left
        curvature = 2.0 * left / distance_sq if distance_sq > 1e-9 else 0.0
        v = p.max_linear
        if abs(curvature) > 1.0 / p.min_turning_radius:
            v = max(p.min_linear, v / (p.min_turning_radius * abs(curvature)))
        v = min(v, max(p.min_linear, p.max_linear * to_goal / p.slow_near_goal))
        if math.isfinite(unmapped):
            v = min(v, max(p.min_linear, p.caution_gain * (unmapped - p.robot_radius)))
        if obstacles is not None:
            points = obstacles.points() + np.array([p.laser_x, 0.0]) if isinstance(obstacles, LaserScan) else obstacles
            clearance = _clearance_along(points, curvature, p)
            if clearance > to_goal + 0.02:
                clearance = math.inf  # the goal comes first: stopping there, short of what is seen
            if clearance < p.stop_clearance:
                return (self._evade(points, bearing) if p.evade else None) or Command(
                    0.0, 0.0, "blocked", f"an obstacle {clearance + p.robot_radius:.2f} m ahead"
                )
            if clearance < p.slow_clearance:
                v *= max(0.2, (clearance - p.stop_clearance) / (p.slow_clearance - p.stop_clearance))
            if math.isfinite(clearance):  # able to stop in what is left, whatever else the rules say
                v = min(v, max(p.min_linear, math.sqrt(2 * p.max_decel * max(clearance - p.stop_clearance, 0.0))))
        w = v * curvature
        if abs(w) > p.max_angular:
            v *= p.max_angular / abs(w)
            w = math.copysign(p.max_angular, w)
        return Command(v, w, "following")

    def _evade(self, points: np.ndarray, bearing: float) -> Command | None:
        """The pursuit arc is blocked (a person stepped in, the path passes close): the clear arc
        that turns most nearly towards the path, slowly; else turn in place towards the path."""
        p = self.params
        best: tuple[float, float] | None = None
        for curvature in np.linspace(-1 / p.min_turning_radius, 1 / p.min_turning_radius, 13):
            if _clearance_along(points, float(curvature), p) < p.stop_clearance + 0.15:
                continue
            miss = abs(float(curvature) * 0.5 - bearing)  # heading after half a metre vs the path's
            if best is None or miss < best[0]:
                best = (miss, float(curvature))
        if best is not None and best[0] < math.pi / 2:
            v = max(p.min_linear, min(0.15, p.max_linear))
            return Command(v, v * best[1], "evading")
        if abs(bearing) > math.radians(20):
            return Command(0.0, _clamp(2.0 * bearing, p.max_angular, minimum=0.3), "rotating")
        return None

    def _lookahead_point(self, pose: Pose2D) -> tuple[float, float]:
        path, p = self.path, self.params
        window = path[self._progress :]
        distances = np.hypot(window[:, 0] - pose.x, window[:, 1] - pose.y)
        self._progress += int(np.argmin(distances[: max(1, min(len(distances), 40))]))
        beyond = np.hypot(path[self._progress :, 0] - pose.x, path[self._progress :, 1] - pose.y)
        far = np.nonzero(beyond >= p.lookahead)[0]
        index = self._progress + int(far[0]) if len(far) else len(path) - 1
        return float(path[index, 0]), float(path[index, 1])


def _clearance_along(points: np.ndarray, curvature: float, p: FollowerParams) -> float:
    """How far the robot can go along the commanded arc before its footprint touches a point
    (base frame), looking as far as it needs to stop from its top speed."""
    if len(points) == 0:
        return math.inf
    horizon = max(p.slow_clearance, p.stop_clearance + p.max_linear**2 / (2 * p.max_decel)) + p.robot_radius
    points = points[np.hypot(points[:, 0], points[:, 1]) <= horizon + p.robot_radius]
    if len(points) == 0:
        return math.inf
    s = np.arange(0.0, horizon + 0.05, 0.05)
    if abs(curvature) < 1e-6:
        arc = np.column_stack((s, np.zeros_like(s)))
    else:
        arc = np.column_stack((np.sin(curvature * s) / curvature, (1 - np.cos(curvature * s)) / curvature))
    reach = p.robot_radius + p.margin
    distance = np.hypot(points[None, :, 0] - arc[:, None, 0], points[None, :, 1] - arc[:, None, 1])
    # touching is coming closer than the margin: moving away from something already near is fine
    near = (distance < reach) & (distance < distance[:1] - 1e-6)
    touching = np.nonzero(near.any(axis=1))[0]
    return float(s[touching[0]]) if len(touching) else math.inf


def _densify(path: np.ndarray, spacing: float) -> np.ndarray:
    points = [path[0]]
    for a, b in itertools.pairwise(path):
        steps = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing))
        points.extend(a + (b - a) * k / steps for k in range(1, steps + 1))
    return np.asarray(points)


def _clamp(value: float, limit: float, minimum: float = 0.0) -> float:
    magnitude = min(abs(value), limit)
    return math.copysign(max(magnitude, minimum), value)
