"""Dead reckoning from encoder steps: the book's diff_tf node.

Each step of the two counters moves the robot along an arc: the distance is the mean of the
wheels', the turn their difference over the wheel separation, and the heading at the arc's
middle places it (as the simulator's odometry does, so both drift alike). The covariance grows
with the distance and the turn, 2 % and 5 % as standard deviations.
"""

from __future__ import annotations

import math

import numpy as np

from botstage.robots.interfaces import Pose2D, Twist2D


class DiffOdometry:
    def __init__(self, ticks_per_metre: float, wheel_separation: float, start: Pose2D | None = None) -> None:
        self.per_tick = 1.0 / ticks_per_metre
        self.separation = wheel_separation
        start = start or Pose2D(0.0, 0.0, 0.0)
        self.x, self.y, self.theta = start.x, start.y, start.theta
        self.v = self.w = 0.0  # the last step's speeds
        self.var_xy = self.var_theta = 0.0
        self.distance = 0.0  # m travelled, for reports

    def add(self, left_ticks: int, right_ticks: int, dt: float) -> None:
        """Integrate one step of the counters, taken over ``dt`` seconds."""
        d_left, d_right = left_ticks * self.per_tick, right_ticks * self.per_tick
        distance, d_theta = (d_left + d_right) / 2, (d_right - d_left) / self.separation
        middle = self.theta + d_theta / 2
        self.x += distance * math.cos(middle)
        self.y += distance * math.sin(middle)
        self.theta = math.atan2(math.sin(self.theta + d_theta), math.cos(self.theta + d_theta))
        if dt > 0:
            self.v, self.w = distance / dt, d_theta / dt
        self.var_xy += (0.02 * distance) ** 2
        self.var_theta += (0.05 * d_theta) ** 2
        self.distance += abs(distance)

    def still(self) -> None:
        """No motion reported for a while (or the link is down): the twist is zero."""
        self.v = self.w = 0.0

    @property
    def pose(self) -> Pose2D:
        return Pose2D(self.x, self.y, self.theta)

    @property
    def twist(self) -> Twist2D:
        return Twist2D(self.v, self.w)

    @property
    def covariance(self) -> np.ndarray:
        return np.diag([self.var_xy, self.var_xy, self.var_theta])
