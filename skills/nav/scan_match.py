"""Map correction with the laser: scan matching against a signed distance field of the map.

**The choice: scan matching, not a particle filter.** The pose EKF already tracks the robot
from a known start (a mission names where the robot starts), so what it needs from the laser is
a local correction with an honest covariance, at a few hertz, for several robots per process.
A scan match gives exactly that (a pose and a covariance from the fit's curvature) in about a
millisecond; a particle filter (AMCL) solves the harder global problem but needs hundreds of
particles x 181 beams per update (tens of ms in numpy), is random (determinism then hangs on
its seed and on the order of reads) and gives a covariance only as a particle spread. What is
left alone: global localisation (a kidnapped robot, an unknown start). A robot whose estimate is
off but still within the search window (0.3 m, 6°) while its covariance claims better gets its
good matches gated out as jumps; the ``Localizer`` then inflates the covariance at each such
rejection until the gate lets the map in (tested with 0.22 m and 3° off at 1 cm confidence).

Figures (``python -m tests.bench.bench_localization``, 2-core VM): 0.47 ms median and 0.55 ms
p90 per match on the museum loop (181 beams, 0.05 m map; target 5 ms), 1.5 ms median and 2.2
ms p90 with the window at its widest; from 300 random museum poses with the prior 0.15 m and 4°
off, 93% accepted (the rest refused as ambiguous: a robot facing one wall) with 0.5 cm mean and
1.8 cm worst error; over a 56 m loop the map-corrected pose stays within 1.2 cm and 0.4°, where
odometry alone drifts 1-3 m and 10-17° at worst (docs/benchmarks.md, Navigation and localisation).

How a match works:

1. **The field**, precomputed once per map (``LikelihoodField.for_grid`` caches it): the signed
   distance from each cell to the boundary of free space (positive in free space, negative
   inside walls and unknown space, in metres), from ``scipy.ndimage.distance_transform_edt``
   both ways, and a score ``exp(-d² / 2 sigma²)`` from it. The boundary, not the occupied cells'
   centres, is where the simulated and a real laser's beams end, so a fitted scan is not pulled
   half a cell into the walls.
2. **A correlative search** over a small window around the EKF's pose (half-widths from 3
   standard deviations of its covariance, clamped: 0.1-0.3 m and 2-6°), at one cell and 1°
   steps, with at most ``coarse_points`` beams: for each angle the points are rotated once and
   the translations are whole-cell shifts of their indices, so the whole window is one numpy
   gather. This finds the right basin even when the EKF is a few cells off.
3. **Gauss-Newton refinement** of the signed distances (bilinear, so smooth between cells) with
   all beams and a Cauchy loss; beams whose end is farther than ``outlier_distance`` from any
   wall count for nothing, so people and furniture that are not on the map drop out. A beam
   must also end on a surface that faces the laser, and in the search ``free_before`` back
   along it must be free: otherwise beams through a thin wall's near face fit its far face as
   well, 20 cm off (the museum's gallery partition did exactly that).
4. **Checks**: enough beams (``min_points``), most of them on mapped walls (``min_inliers``:
   a scan mostly blocked by people is rejected, not trusted), a small residual (``max_rms``),
   a well-constrained fit (the fit's covariance along its weakest direction: a corridor or an
   empty hall leaves the pose free along it, and such a match is refused rather than reported
   with a made-up certainty), and a jump consistent with the EKF's covariance (the squared
   Mahalanobis distance under the chi² gate).

The covariance returned is the fit's ``rms² (JᵀJ)⁻¹``, multiplied by ``covariance_scale``
(neighbouring beams' errors are correlated: the map is drawn in 5 cm cells) plus a floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from weakref import finalize, ref

import numpy as np

from botstage.robots.gridmap import FREE, GridMap
from botstage.robots.interfaces import LaserScan, Pose2D
from botstage.skills.nav.ekf import pose_residual, wrap

FAR = 1.0  # m: the field is clipped here; a beam this far from any wall matches nothing


@dataclass(frozen=True)
class MatchParams:
    coarse_points: int = 90  # beams used in the correlative search (every k-th)
    search_xy: tuple[float, float] = (0.1, 0.3)  # m: half-width of the window, clamped
    search_theta: tuple[float, float] = (math.radians(2), math.radians(6))
    theta_step: float = math.radians(1)
    sigma: float = 0.05  # m: the score's kernel
    outlier_distance: float = 0.2  # m: beams ending farther than this from a wall are left out
    free_before: float = 0.1  # m: this far back along a beam must be free space (not the far face of a wall)
    facing: float = 0.3  # a beam may end on a surface only if it faces the laser (cos of the angle, at most)
    cauchy: float = 0.03  # m: the robust loss's scale
    iterations: int = 10
    min_points: int = 30
    min_inliers: float = 0.5  # of the beams with a return
    max_rms: float = 0.06  # m over the inliers
    max_std_xy: float = 0.08  # m: along the fit's weakest direction, else ambiguous
    max_std_theta: float = math.radians(2.0)
    gate: float = 16.27  # chi² with 3 degrees of freedom at 99.9%
    covariance_scale: float = 10.0
    covariance_floor: tuple[float, float, float] = (0.01**2, 0.01**2, math.radians(0.3) ** 2)
    laser_noise: float = 0.01  # m: the residual is never taken as better than this


@dataclass(frozen=True)
class MatchResult:
    accepted: bool
    pose: Pose2D
    covariance: np.ndarray
    reason: str  # "ok", or why it was rejected: few_points, few_inliers, high_residual, ambiguous, jump
    points: int = 0
    inliers: int = 0
    rms: float = math.nan
    score: float = 0.0  # mean score of the coarse search's best cell, 0..1
    mahalanobis2: float = math.nan


@dataclass
class LikelihoodField:
    """A map's signed distance field and score table in the map's own frame, padded."""

    resolution: float
    origin: tuple[float, float, float]
    pad: int
    sdf: np.ndarray  # metres, clipped to +-FAR, padded with +FAR (off the map matches nothing)
    score: np.ndarray  # float32 exp(-sdf² / 2 sigma²), padded with 0
    free: np.ndarray  # float32 1 in free space, else 0

    @classmethod
    def build(cls, grid: GridMap, sigma: float = 0.05, pad: int = 16) -> LikelihoodField:
        from scipy.ndimage import distance_transform_edt  # on first use: scipy's import costs every command

        free = grid.data == FREE
        res = grid.resolution
        outside = distance_transform_edt(free) * res - res / 2  # free cell centre to the nearest blocked cell's face
        inside = distance_transform_edt(~free) * res - res / 2  # blocked cell centre to the nearest free cell's face
        sdf = np.where(free, outside, -inside)
        sdf = np.clip(sdf, -FAR, FAR)
        sdf = np.pad(sdf, pad, constant_values=FAR)
        score = np.exp(-(sdf**2) / (2 * sigma**2)).astype(np.float32)
        return cls(res, tuple(grid.origin), pad, sdf, score, (sdf > 0).astype(np.float32))  # type: ignore[arg-type]

    @classmethod
    def for_grid(cls, grid: GridMap, sigma: float = 0.05) -> LikelihoodField:
        """The field of a map, built once per map object (robots on one map share it)."""
        key = (id(grid), sigma)
        cached = _FIELDS.get(key)
        if cached is not None and cached[0]() is grid:
            return cached[1]
        built = cls.build(grid, sigma)
        _FIELDS[key] = (ref(grid), built)
        finalize(grid, _FIELDS.pop, key, None)  # forgotten with its map
        return built

    def to_map(self, pose: Pose2D) -> tuple[float, float, float]:
        """A world pose in the map's frame (its origin at the lower-left corner, axis-aligned)."""
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = pose.x - ox, pose.y - oy
        return c * dx + s * dy, -s * dx + c * dy, pose.theta - yaw

    def to_world(self, x: float, y: float, theta: float) -> Pose2D:
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        return Pose2D(ox + c * x - s * y, oy + s * x + c * y, wrap(theta + yaw))

    def rotate_covariance(self, covariance: np.ndarray, to_map: bool = False) -> np.ndarray:
        """A covariance from the map's frame to the world's (or the other way)."""
        yaw = -self.origin[2] if to_map else self.origin[2]
        if not yaw:
            return covariance
        c, s = math.cos(yaw), math.sin(yaw)
        r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return r @ covariance @ r.T

    def sample(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bilinear signed distance and its gradient at map-frame points."""
        u = xs / self.resolution - 0.5 + self.pad
        v = ys / self.resolution - 0.5 + self.pad
        rows, cols = self.sdf.shape
        u = np.clip(u, 0.0, cols - 1.001)
        v = np.clip(v, 0.0, rows - 1.001)
        c0, r0 = u.astype(np.intp), v.astype(np.intp)
        fu, fv = u - c0, v - r0
        f = self.sdf
        a, b, c, d = f[r0, c0], f[r0, c0 + 1], f[r0 + 1, c0], f[r0 + 1, c0 + 1]
        value = (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv
        gx = ((b - a) * (1 - fv) + (d - c) * fv) / self.resolution
        gy = ((c - a) * (1 - fu) + (d - b) * fu) / self.resolution
        return value, gx, gy


_FIELDS: dict[tuple[int, float], tuple[ref[GridMap], LikelihoodField]] = {}


class ScanMatcher:
    """Matches laser scans against one map; see the module's docstring for how and why."""

    def __init__(
        self, grid: GridMap, laser_pose: tuple[float, float, float] = (0.0, 0.0, 0.0), params: MatchParams | None = None
    ) -> None:
        self.params = params or MatchParams()
        self.field = LikelihoodField.for_grid(grid, self.params.sigma)
        self.laser_pose = laser_pose

    def scan_points(self, scan: LaserScan) -> np.ndarray:
        """The scan's returns as (x, y) points in the robot's base frame."""
        points = scan.points()
        lx, ly, lt = self.laser_pose
        if lt:
            c, s = math.cos(lt), math.sin(lt)
            points = points @ np.array([[c, s], [-s, c]])
        return points + np.array([lx, ly])

    def match(self, scan: LaserScan, prior: Pose2D, prior_covariance: np.ndarray) -> MatchResult:
        """The pose that fits ``scan`` to the map best near ``prior``, checked (see ``accepted``)."""
        return self.match_points(self.scan_points(scan), prior, prior_covariance)

    def match_points(self, points: np.ndarray, prior: Pose2D, prior_covariance: np.ndarray) -> MatchResult:
        p = self.params
        prior_covariance = np.asarray(prior_covariance, dtype=float)
        n = len(points)
        if n < p.min_points:
            return MatchResult(False, prior, prior_covariance, "few_points", n)
        fld = self.field
        x0, y0, t0 = fld.to_map(prior)
        local_cov = fld.rotate_covariance(prior_covariance, to_map=True)
        std_xy = math.sqrt(max(local_cov[0, 0], local_cov[1, 1], 0.0))
        std_t = math.sqrt(max(local_cov[2, 2], 0.0))
        half_xy = min(max(3 * std_xy, p.search_xy[0]), p.search_xy[1])
        half_t = min(max(3 * std_t, p.search_theta[0]), p.search_theta[1])
        rays = points - np.array(self.laser_pose[:2])
        rays /= np.maximum(np.hypot(rays[:, 0], rays[:, 1]), 1e-9)[:, None]
        x, y, theta, score = self._search(points, rays, x0, y0, t0, half_xy, half_t)
        x, y, theta, info, residuals, inlier = self._refine(points, rays, x, y, theta)
        inliers = int(inlier.sum())
        rms = float(np.sqrt(np.mean(residuals[inlier] ** 2))) if inliers else math.inf
        pose = fld.to_world(x, y, theta)
        covariance = self._covariance(info, rms)
        result = dict(points=n, inliers=inliers, rms=rms, score=score)
        if inliers < max(p.min_points, p.min_inliers * n):
            return MatchResult(False, pose, covariance, "few_inliers", **result)  # type: ignore[arg-type]
        if rms > p.max_rms:
            return MatchResult(False, pose, covariance, "high_residual", **result)  # type: ignore[arg-type]
        xy_std = math.sqrt(float(np.linalg.eigvalsh(covariance[:2, :2])[-1]))
        if xy_std > p.max_std_xy or math.sqrt(covariance[2, 2]) > p.max_std_theta:
            return MatchResult(False, pose, covariance, "ambiguous", **result)  # type: ignore[arg-type]
        y = pose_residual(np.array([[pose.x], [pose.y], [pose.theta]]), np.array([[prior.x], [prior.y], [prior.theta]]))
        distance2 = float((y.T @ np.linalg.solve(prior_covariance + covariance, y))[0, 0])
        if distance2 > p.gate:
            return MatchResult(False, pose, covariance, "jump", mahalanobis2=distance2, **result)  # type: ignore[arg-type]
        return MatchResult(True, pose, covariance, "ok", mahalanobis2=distance2, **result)  # type: ignore[arg-type]

    def _search(
        self, points: np.ndarray, rays: np.ndarray, x0: float, y0: float, t0: float, half_xy: float, half_t: float
    ) -> tuple[float, float, float, float]:
        """Correlative search: every angle step and whole-cell shift in the window, one gather.

        A beam scores where it ends near a wall and ``free_before`` back along it is free: a
        beam ending on the far face of a thin wall (through it) scores nothing."""
        p, fld = self.params, self.field
        step = max(1, math.ceil(len(points) / p.coarse_points))
        pts, rays = points[::step], rays[::step]
        res = fld.resolution
        k = min(math.ceil(half_xy / res), fld.pad - 2)
        m = max(1, math.ceil(half_t / p.theta_step))
        angles = t0 + p.theta_step * np.arange(-m, m + 1)
        c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
        rows, cols = fld.score.shape
        shifts = np.arange(-k, k + 1)
        offsets = (shifts[:, None] * cols + shifts[None, :]).ravel()  # (dr, dc) row-major

        def cells(local: np.ndarray) -> np.ndarray:  # (angles, 1, points) flat indices
            xs = x0 + c * local[:, 0] - s * local[:, 1]
            ys = y0 + s * local[:, 0] + c * local[:, 1]
            col = np.clip(np.floor(xs / res).astype(np.intp) + fld.pad, k, cols - 1 - k)
            row = np.clip(np.floor(ys / res).astype(np.intp) + fld.pad, k, rows - 1 - k)
            return (row * cols + col)[:, None, :] + offsets[None, :, None]

        ends = fld.score.ravel()[cells(pts)]
        before = fld.free.ravel()[cells(pts - p.free_before * rays)]
        total = (ends * before).sum(axis=2)  # (angles, shifts)
        # prefer the window's centre on ties (a flat score must not drift the pose to a corner)
        dr, dc = np.divmod(np.arange(len(offsets)), 2 * k + 1)
        centre = (dr - k) ** 2 + (dc - k) ** 2 + ((np.arange(2 * m + 1) - m) ** 2)[:, None]
        best = np.lexsort((centre.ravel(), -total.ravel()))[0]
        a, o = divmod(int(best), len(offsets))
        r_shift, c_shift = divmod(o, 2 * k + 1)
        return (
            x0 + (c_shift - k) * res,
            y0 + (r_shift - k) * res,
            float(angles[a]),
            float(total[a, o]) / len(pts),
        )

    def _refine(
        self, points: np.ndarray, rays: np.ndarray, x: float, y: float, theta: float
    ) -> tuple[float, float, float, np.ndarray, np.ndarray, np.ndarray]:
        """Gauss-Newton on the signed distances with a Cauchy loss; far beams, and beams on
        surfaces facing away from the laser (the far face of a thin wall), left out."""
        p, fld = self.params, self.field
        px, py = points[:, 0], points[:, 1]
        ux, uy = rays[:, 0], rays[:, 1]
        converged = False
        for iteration in range(p.iterations + 1):
            c, s = math.cos(theta), math.sin(theta)
            rx, ry = c * px - s * py, s * px + c * py
            residuals, gx, gy = fld.sample(x + rx, y + ry)
            facing = gx * (c * ux - s * uy) + gy * (s * ux + c * uy)  # the surface's normal along the beam
            inlier = (np.abs(residuals) < p.outlier_distance) & (facing < p.facing)
            jac = np.column_stack((gx, gy, -gx * ry + gy * rx))[inlier]
            r = residuals[inlier]
            info = jac.T @ jac
            if converged or iteration == p.iterations or len(r) < 3:
                break
            weight = 1.0 / (1.0 + (r / p.cauchy) ** 2)
            weighted = jac * weight[:, None]
            delta = -np.linalg.solve(weighted.T @ jac + 1e-9 * np.eye(3), weighted.T @ r)
            delta[:2] = np.clip(delta[:2], -0.1, 0.1)  # within the field's reach per step
            delta[2] = np.clip(delta[2], -0.05, 0.05)
            x, y, theta = x + float(delta[0]), y + float(delta[1]), theta + float(delta[2])
            converged = abs(delta[0]) + abs(delta[1]) < 1e-4 and abs(delta[2]) < 1e-4
        return x, y, theta, info, residuals, inlier

    def _covariance(self, info: np.ndarray, rms: float) -> np.ndarray:
        """rms² (JᵀJ)⁻¹, scaled for correlated beams, plus a floor; in the world's frame."""
        p = self.params
        variance = max(rms if math.isfinite(rms) else 0.0, p.laser_noise) ** 2
        try:
            covariance = variance * np.linalg.inv(info + 1e-12 * np.eye(3)) * p.covariance_scale
        except np.linalg.LinAlgError:
            covariance = np.diag([1e6, 1e6, 1e6])
        covariance = (covariance + covariance.T) / 2 + np.diag(p.covariance_floor)
        return self.field.rotate_covariance(covariance)
