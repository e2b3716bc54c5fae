"""Pose EKF: wheel odometry and a gyro fused into a pose (x, y, theta) with a 3x3 covariance.

Built on filterpy's ``ExtendedKalmanFilter``; only the motion model (a differential drive's
mid-point arc, the one diff_tf integrates) replaces its linear ``predict_x``.

Why the filter looks as it does:

- **Prediction from odometry increments**: the distance and heading change between two
  consecutive odometry readings. Their noise comes from the wheels: each wheel's distance is off
  by ``wheel_slip`` times itself (the simulator's slip model), which puts most of the error in
  the heading (two wheels 0.33 m apart: 2% slip is 0.5° a 5 cm step), plus small floors that
  grow with the distance and the turning for errors the slip model does not cover.
- **The gyro replaces part of the odometry's heading change**, weighted by their variances:
  the wheels' heading change is noisy when moving (slip) and exact when standing still; the
  gyro's is smooth but drifts with its bias (0.002 rad/s in the simulator, 12° in 100 s). A
  raw gyro would therefore lose to the wheels over a long drive, so the bias is estimated: a
  scalar Kalman filter on ``(gyro increment - wheel increment) / dt``, which is the bias plus
  zero-mean slip noise while moving and the bias plus gyro noise alone while standing still
  (then it settles in seconds, as a gyro is calibrated at rest). The bias is kept outside the
  pose state so the state and its covariance stay the 3x3 pose the rest of the stack uses; the
  cost is that the bias's error is treated as white per increment (slightly optimistic).
- **Map fixes** (``correct``) are a direct measurement of the whole pose with their own
  covariance; the heading residual is wrapped to (-pi, pi] so a fix at +179° against an estimate
  at -179° is a 2° correction, not 358°.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from botstage.robots.interfaces import Pose2D


def wrap(theta: float) -> float:
    """An angle in [-pi, pi)."""
    return (theta + math.pi) % (2 * math.pi) - math.pi


def pose_residual(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a - b for poses as column vectors, the heading difference wrapped."""
    y = np.subtract(a, b, dtype=float)
    y.flat[2] = wrap(float(y.flat[2]))
    return y


@dataclass(frozen=True)
class MotionNoise:
    """How wrong odometry and the gyro are, per increment."""

    wheel_separation: float = 0.33  # m: turns the wheels' errors into heading error
    wheel_slip: float = 0.02  # std of each wheel's distance per increment, as a fraction of it
    distance_var_per_m: float = 2e-5  # m²/m: floor on the distance's variance growth
    heading_var_per_m: float = 2e-6  # rad²/m: floor on the heading's variance growth driving
    heading_var_per_rad: float = 1e-5  # rad²/rad: floor on the heading's variance growth turning
    gyro_noise: float = 0.002  # rad/sqrt(s): angle random walk of the integrated gyro
    gyro_bias_std: float = 0.01  # rad/s: prior std of the gyro's bias
    gyro_bias_walk: float = 1e-5  # rad/s/sqrt(s): how fast the bias itself may wander
    bias_gate: float = 16.0  # squared standard deviations: wheels and gyro disagreeing more teach nothing


@functools.cache
def _pose_filter() -> Any:
    """filterpy's EKF with the non-linear motion model in place of ``F x + B u``; the class is made
    on first use, as filterpy imports scipy.stats (a second for every command that never localises)."""
    from filterpy.kalman import ExtendedKalmanFilter

    class PoseFilter(ExtendedKalmanFilter):
        def predict_x(self, u: object = 0) -> None:
            distance, d_theta = u  # type: ignore[misc]
            x, y, theta = (float(v) for v in self.x[:, 0])
            heading = theta + d_theta / 2
            self.x = np.array(
                [[x + distance * math.cos(heading)], [y + distance * math.sin(heading)], [wrap(theta + d_theta)]]
            )

    return PoseFilter


def _identity(x: np.ndarray) -> np.ndarray:
    return np.eye(3)


def _state(x: np.ndarray) -> np.ndarray:
    return x


class PoseEKF:
    """The pose (x, y, theta) and its covariance, driven by odometry and a gyro, fixed by the map."""

    def __init__(self, pose: Pose2D, covariance: np.ndarray | None = None, noise: MotionNoise | None = None) -> None:
        self.noise = noise or MotionNoise()
        self._kf = _pose_filter()(dim_x=3, dim_z=3)
        self.bias = 0.0  # rad/s, the gyro's estimated bias
        self.bias_var = self.noise.gyro_bias_std**2
        self.reset(pose, covariance)

    def reset(self, pose: Pose2D, covariance: np.ndarray | None = None) -> None:
        """Put the robot at ``pose`` (the gyro's bias estimate is kept: it belongs to the sensor)."""
        self._kf.x = np.array([[pose.x], [pose.y], [wrap(pose.theta)]])
        self._kf.P = np.array(covariance, dtype=float) if covariance is not None else np.zeros((3, 3))
        if self._kf.P.shape != (3, 3):
            raise ValueError(f"a pose covariance is 3x3, got shape {self._kf.P.shape}")

    @property
    def pose(self) -> Pose2D:
        x, y, theta = (float(v) for v in self._kf.x[:, 0])
        return Pose2D(x, y, theta)

    @property
    def covariance(self) -> np.ndarray:
        return self._kf.P.copy()

    # -- prediction ---------------------------------------------------------------------------

    def odometry_noise(self, distance: float, d_theta: float) -> np.ndarray:
        """2x2 covariance of (distance, heading change) from the wheels' slip and the floors."""
        n = self.noise
        half = d_theta * n.wheel_separation / 2
        var_left, var_right = (n.wheel_slip * (distance - half)) ** 2, (n.wheel_slip * (distance + half)) ** 2
        var_d = (var_left + var_right) / 4 + n.distance_var_per_m * abs(distance)
        var_t = (
            (var_left + var_right) / n.wheel_separation**2
            + n.heading_var_per_m * abs(distance)
            + n.heading_var_per_rad * abs(d_theta)
        )
        cov = (var_right - var_left) / (2 * n.wheel_separation)
        return np.array([[var_d, cov], [cov, var_t]])

    def predict(self, distance: float, d_theta: float, gyro_d_theta: float | None = None, dt: float = 0.0) -> None:
        """Move by an odometry increment (signed distance along the mid-point heading, heading
        change); with ``gyro_d_theta`` (the gyro's heading change over the same ``dt`` seconds)
        the heading change is the variance-weighted blend of both, the gyro's bias removed."""
        noise = self.odometry_noise(distance, d_theta)
        if gyro_d_theta is not None and dt > 0:
            d_theta, noise = self._fuse_gyro(d_theta, noise, gyro_d_theta, dt)
        theta = float(self._kf.x[2, 0])
        heading = theta + d_theta / 2
        c, s = math.cos(heading), math.sin(heading)
        self._kf.F = np.array([[1.0, 0.0, -distance * s], [0.0, 1.0, distance * c], [0.0, 0.0, 1.0]])
        v = np.array([[c, -distance * s / 2], [s, distance * c / 2], [0.0, 1.0]])  # d state / d (distance, d_theta)
        self._kf.Q = v @ noise @ v.T
        self._kf.predict(u=(distance, d_theta))

    def _fuse_gyro(self, d_theta: float, noise: np.ndarray, gyro_d_theta: float, dt: float) -> tuple[float, np.ndarray]:
        n = self.noise
        var_wheels = float(noise[1, 1])
        var_gyro = n.gyro_noise**2 * dt + self.bias_var * dt * dt
        gyro = gyro_d_theta - self.bias * dt
        total = var_wheels + var_gyro
        weight = var_gyro / total if total > 0 else 1.0  # of the wheels: 1 standing still, small when slipping
        fused = weight * d_theta + (1 - weight) * gyro
        fused_noise = noise.copy()
        fused_noise[1, 1] = var_wheels * var_gyro / total if total > 0 else 0.0
        fused_noise[0, 1] = fused_noise[1, 0] = weight * noise[0, 1]
        # the bias: (gyro - wheels) / dt measures it, with both increments' noise
        self.bias_var += n.gyro_bias_walk**2 * dt
        measured = wrap(gyro_d_theta - d_theta) / dt
        r = (var_wheels + n.gyro_noise**2 * dt) / (dt * dt)
        innovation = measured - self.bias
        if self.bias_var + r > 0 and innovation * innovation <= n.bias_gate * (self.bias_var + r):
            # (beyond the gate: a bump, a push, a lifted wheel, which teach nothing about the gyro)
            gain = self.bias_var / (self.bias_var + r)
            self.bias += gain * innovation
            self.bias_var *= 1 - gain
        return fused, fused_noise

    def inflate(self, factor: float) -> None:
        """Admit more doubt (the map keeps disagreeing: the estimate is worse than it thinks)."""
        self._kf.P = self._kf.P * factor

    # -- correction ---------------------------------------------------------------------------

    def innovation(self, pose: Pose2D, covariance: np.ndarray) -> float:
        """The squared Mahalanobis distance of a pose fix from the estimate (chi² with 3 degrees
        of freedom when both are right): what gates a scan match before it is used."""
        y = pose_residual(np.array([[pose.x], [pose.y], [pose.theta]]), self._kf.x)
        s = self._kf.P + np.asarray(covariance, dtype=float)
        return float((y.T @ np.linalg.solve(s, y))[0, 0])

    def correct(self, pose: Pose2D, covariance: np.ndarray) -> None:
        """Fuse a measurement of the whole pose (a scan match against the map)."""
        z = np.array([[pose.x], [pose.y], [pose.theta]])
        self._kf.update(z, _identity, _state, R=np.asarray(covariance, dtype=float), residual=pose_residual)
        self._kf.x[2, 0] = wrap(float(self._kf.x[2, 0]))
        self._kf.P = (self._kf.P + self._kf.P.T) / 2  # keep it symmetric against rounding
