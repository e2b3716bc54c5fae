"""One robot's pose estimate: odometry and IMU through the pose EKF, corrected against the map
with the laser.

A ``Localizer`` is per robot and updated once per tick, after the world (or the hardware)
moved; ``estimate()`` then hands out the same immutable ``PoseEstimate`` to every caller of the
tick, so it is free to call often. Time is the readings' stamps, never the wall clock.

Scan matching costs about a millisecond, so it runs at most every ``match_period`` seconds of
reading time, and only when the robot moved or turned since the last match (a robot standing
still learns nothing new from the same view), or when ``match_interval`` seconds passed anyway
(people may have walked into the last view). The sources an estimate names:

- ``odometry``: wheels alone (no IMU, no accepted map fix lately);
- ``ekf``: wheels and gyro fused;
- ``map``: a scan match was accepted within the last ``map_fresh`` seconds.

Rejected matches are counted by reason (``summary()``). A match that fits the map well but is
gated out as a jump inflates the covariance (``jump_inflation``): repeated, the estimate was
overconfident (a bump, a push), and the map is let in again. The scan is taken to be as old as
the odometry reading of the same update; an older scan (a scanner slower than the tick) waits
for the next one. A real laser's latency is not compensated yet.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Imu, Laser, Odometry, OdometryReading, Pose2D
from botstage.robots.profile import Profile
from botstage.skills.nav.ekf import MotionNoise, PoseEKF, wrap
from botstage.skills.nav.scan_match import MatchParams, MatchResult, ScanMatcher


@dataclass(frozen=True)
class LocalizerParams:
    match_period: float = 0.2  # s of reading time between two scan matches, at least
    match_travel: float = 0.05  # m moved since the last match before matching again
    match_turn: float = math.radians(2)  # or this much turned
    match_interval: float = 2.0  # s: match at least this often while standing still
    map_fresh: float = 2.0  # s: an estimate is "map" this long after an accepted match
    jump_inflation: float = 1.5  # the covariance grows this much each time a good match is gated out as a jump
    initial_covariance: tuple[float, float, float] = (0.02**2, 0.02**2, math.radians(1) ** 2)
    motion: MotionNoise = field(default_factory=MotionNoise)
    match: MatchParams = field(default_factory=MatchParams)


@dataclass(frozen=True)
class PoseEstimate:
    time: float  # s, the odometry reading's stamp
    pose: Pose2D
    covariance: np.ndarray  # 3x3 over x, y, theta; read-only
    source: str  # odometry, ekf or map


class Localizer:
    """Fuses a robot's odometry, IMU and laser into a pose with covariance; see the module."""

    def __init__(
        self,
        odometry: Odometry,
        imu: Imu | None = None,
        laser: Laser | None = None,
        grid: GridMap | None = None,
        laser_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        params: LocalizerParams | None = None,
    ) -> None:
        self.params = params or LocalizerParams()
        self.odometry = odometry
        self.imu = imu
        self.laser = laser if grid is not None else None
        self.matcher: ScanMatcher | None = None
        if laser is not None and grid is not None:
            self.matcher = ScanMatcher(grid, laser_pose, self.params.match)
        self.ekf: PoseEKF | None = None
        self.matches_accepted = 0
        self.matches_rejected = 0
        self.rejections: Counter[str] = Counter()  # why matches were rejected
        self.last_match: MatchResult | None = None
        self._last_odometry: OdometryReading | None = None
        self._last_yaw: float | None = None
        self._last_match_time = -math.inf
        self._last_match_pose: Pose2D | None = None
        self._last_accepted_time = -math.inf
        self._pending_reset: tuple[Pose2D, np.ndarray | None] | None = None
        self._estimate: PoseEstimate | None = None

    @classmethod
    def for_devices(
        cls,
        devices: Mapping[str, Any],
        grid: GridMap | None = None,
        profile: Profile | None = None,
        params: LocalizerParams | None = None,
    ) -> Localizer:
        """A localiser from what a robot has: odometry (required), an IMU and a laser if present;
        the laser's mount and the wheel separation come from the profile."""
        if "odometry" not in devices:
            raise ValueError("a localiser needs odometry")
        params = params or LocalizerParams()
        laser_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
        if profile is not None:
            params = replace(params, motion=replace(params.motion, wheel_separation=profile.base.wheel_separation))
            if "laser" in profile.interfaces:
                laser_pose = profile.interfaces["laser"].pose
                noise = profile.interfaces["laser"].noise
                if noise:
                    params = replace(params, match=replace(params.match, laser_noise=noise))
        return cls(devices["odometry"], devices.get("imu"), devices.get("laser"), grid, laser_pose, params)

    # -- the tick -----------------------------------------------------------------------------

    def update(self) -> PoseEstimate:
        """Read the devices once and bring the estimate up to date."""
        reading = self.odometry.read()
        yaw = self.imu.read().yaw if self.imu is not None else None
        previous = self._last_odometry
        if self.ekf is None:
            pose, covariance = self._pending_reset or (reading.pose, None)
            if covariance is None:
                covariance = np.diag(self.params.initial_covariance)
            self.ekf = PoseEKF(pose, covariance, self.params.motion)
            self._pending_reset = None
        elif previous is not None:
            distance, d_theta = increment(previous.pose, reading.pose)
            dt = reading.stamp - previous.stamp
            gyro = wrap(yaw - self._last_yaw) if yaw is not None and self._last_yaw is not None else None
            if distance or d_theta or dt > 0:
                self.ekf.predict(distance, d_theta, gyro, dt)
        self._last_odometry, self._last_yaw = reading, yaw
        if self._due(reading.stamp):
            self._match(reading.stamp)
        self._publish(reading.stamp)
        return self._estimate  # type: ignore[return-value]

    def estimate(self) -> PoseEstimate:
        """The estimate of the last update (updating first if there was none)."""
        return self._estimate if self._estimate is not None else self.update()

    def pose(self) -> Pose2D:
        return self.estimate().pose

    def reset(self, pose: Pose2D, covariance: np.ndarray | None = None) -> None:
        """Put the robot at ``pose`` (e.g. a mission's known start, or after being carried)."""
        cov = np.asarray(covariance, dtype=float) if covariance is not None else None
        if self.ekf is None:
            self._pending_reset = (pose, cov)
            return
        self.ekf.reset(pose, cov if cov is not None else np.diag(self.params.initial_covariance))
        self._last_match_time = -math.inf
        self._last_match_pose = None
        self._publish(self._estimate.time if self._estimate is not None else 0.0)

    def summary(self) -> dict[str, Any]:
        """Counters for reports."""
        total = self.matches_accepted + self.matches_rejected
        return {
            "matches_accepted": self.matches_accepted,
            "matches_rejected": self.matches_rejected,
            "acceptance": round(self.matches_accepted / total, 4) if total else None,
            "rejections": dict(sorted(self.rejections.items())),
            "gyro_bias": round(self.ekf.bias, 6) if self.ekf is not None else None,
        }

    # -- internals ----------------------------------------------------------------------------

    def _due(self, now: float) -> bool:
        p = self.params
        if self.matcher is None or now - self._last_match_time < p.match_period - 1e-9:
            return False
        if self._last_match_pose is None or now - self._last_match_time >= p.match_interval - 1e-9:
            return True
        pose, last = self.ekf.pose, self._last_match_pose  # type: ignore[union-attr]
        moved = math.hypot(pose.x - last.x, pose.y - last.y) >= p.match_travel
        return moved or abs(wrap(pose.theta - last.theta)) >= p.match_turn

    def _match(self, now: float) -> None:
        ekf, matcher = self.ekf, self.matcher
        assert ekf is not None and matcher is not None and self.laser is not None
        scan = self.laser.scan()
        if scan.stamp < now - 1e-6:
            return  # the scanner has not turned since: match its next scan, taken where the robot is
        result = matcher.match(scan, ekf.pose, ekf.covariance)
        self.last_match = result
        self._last_match_time = now
        self._last_match_pose = ekf.pose
        if result.accepted:
            ekf.correct(result.pose, result.covariance)
            self.matches_accepted += 1
            self._last_accepted_time = now
        else:
            self.matches_rejected += 1
            self.rejections[result.reason] += 1
            if result.reason == "jump":
                # a match that fits the map well but lies outside the gate, again and again, means the
                # estimate is overconfident (a bump, a push): doubt it until the gate lets the map in
                ekf.inflate(self.params.jump_inflation)

    def _publish(self, now: float) -> None:
        assert self.ekf is not None
        covariance = self.ekf.covariance
        covariance.flags.writeable = False
        if now - self._last_accepted_time <= self.params.map_fresh:
            source = "map"
        else:
            source = "ekf" if self.imu is not None else "odometry"
        self._estimate = PoseEstimate(now, self.ekf.pose, covariance, source)


def increment(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    """The odometry increment from ``a`` to ``b``: the signed distance along the mid-point heading
    (diff_tf's model, inverted exactly) and the heading change."""
    d_theta = wrap(b.theta - a.theta)
    heading = a.theta + d_theta / 2
    return (b.x - a.x) * math.cos(heading) + (b.y - a.y) * math.sin(heading), d_theta
