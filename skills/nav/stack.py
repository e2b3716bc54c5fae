"""One robot's navigation stack: its map, costmaps, planner, range sensors and pose estimate.

The navigation skills (navigate, wander, approach, back_to_point and the recoveries) share one
stack per robot, so what one of them saw (an obstacle that is not on the map) the next one
plans around, and `clear_costmap` clears it for all. The stack holds:

- the **static costmap**: the map's obstacles inflated by the robot's radius (computed once per
  map and radius, and cached);
- an **obstacle layer**: cells where the laser or the sonar saw something, stamped with the
  time; they count as obstacles for ``obstacle_memory`` seconds (people walk away);
- what the sensors saw in the last ``recent_s`` seconds near the robot: the laser looks ahead,
  so a person the robot is passing is beside it, out of the beam, but still in the way;
- the **pose** from the localiser (or raw odometry on a robot without one);
- the robot's limits from its profile, for the path follower.
"""

from __future__ import annotations

import hashlib
import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from botstage.robots.clock import Clock
from botstage.robots.gridmap import FREE, GridMap
from botstage.robots.interfaces import LaserScan, Pose2D, SonarReading
from botstage.robots.profile import Profile
from botstage.skills.nav.controller import FollowerParams
from botstage.skills.nav.costmap import LETHAL, inflated_costs
from botstage.skills.nav.planner import Plan, Planner

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

_COSTS: dict[tuple[bytes, float, float], np.ndarray] = {}
_BLOCKED: dict[bytes, cKDTree] = {}
CLEARANCE_REACH = 3.0  # m: clearances farther than this are inf (nothing near enough to matter)
HALF_DIAGONAL = math.sqrt(2) / 2  # in cells: what is in a cell may lie this far from its centre


def _map_key(grid: GridMap) -> bytes:
    return hashlib.sha1(grid.data.tobytes() + repr(grid.data.shape).encode()).digest()


def static_costs(grid: GridMap, robot_radius: float) -> np.ndarray:
    """The inflated costmap of a map for a robot radius, computed once per process."""
    key = (_map_key(grid), grid.resolution, robot_radius)
    costs = _COSTS.get(key)
    if costs is None:
        if len(_COSTS) > 8:
            _COSTS.clear()
        costs = _COSTS[key] = inflated_costs(grid, robot_radius)
        costs.setflags(write=False)
    return costs


def blocked_cells(grid: GridMap) -> cKDTree:
    """The centres of the map's cells that are not free (obstacles, unknown space), in cell units
    (row, col), for nearest-neighbour queries; built once per map."""
    key = _map_key(grid)
    tree = _BLOCKED.get(key)
    if tree is None:
        if len(_BLOCKED) > 8:
            _BLOCKED.clear()
        from scipy.spatial import cKDTree  # on first use: scipy's import costs every command

        tree = _BLOCKED[key] = cKDTree(np.argwhere(grid.data != FREE) + 0.5)
    return tree


@dataclass(frozen=True)
class Limits:
    max_linear: float
    max_angular: float
    max_accel: float


def _to_base(points: np.ndarray, mount: tuple[float, float, float]) -> np.ndarray:
    mx, my, mtheta = mount
    c, s = math.cos(mtheta), math.sin(mtheta)
    return np.column_stack((mx + c * points[:, 0] - s * points[:, 1], my + s * points[:, 0] + c * points[:, 1]))


def _field_of_view(device: Any, default: float) -> float:
    return float(getattr(device, "field_of_view", None) or default)


def sonar_points(reading: SonarReading, rays: int = 5) -> np.ndarray:
    """An echo as a short arc across the cone at its range: the sonar cannot tell where in it."""
    if not math.isfinite(reading.range) or reading.range >= reading.max_range:
        return np.empty((0, 2))
    angles = np.linspace(-reading.field_of_view / 2, reading.field_of_view / 2, rays)
    return np.column_stack((reading.range * np.cos(angles), reading.range * np.sin(angles)))


class NavStack:
    def __init__(
        self,
        grid: GridMap,
        robot_radius: float,
        pose: Callable[[], Pose2D],
        clock: Clock,
        limits: Limits,
        *,
        laser: Any = None,
        laser_mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
        sonar: Any = None,
        sonar_mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
        obstacle_memory: float = 8.0,
        recent_s: float = 2.0,
        odometry: Any = None,
        laser_fov: float = math.pi,
        sonar_fov: float = 0.26,
    ) -> None:
        self.grid = grid
        self.places: Mapping[str, tuple[float, float, float]] = grid.places
        self.robot_radius = robot_radius
        self.clock = clock
        self.limits = limits
        self._pose = pose
        self.odometry = odometry  # the wheels' own account, for telling contact (skills/nav/contact.py)
        self.laser, self.laser_mount = laser, laser_mount
        self.sonar, self.sonar_mount = sonar, sonar_mount
        # where the range sensors look: (mount heading, field of view), base frame
        self.views = [(m[2], f) for d, m, f in ((laser, laser_mount, laser_fov), (sonar, sonar_mount, sonar_fov)) if d]
        self.obstacle_memory = obstacle_memory
        from scipy.ndimage import binary_dilation  # on first use: scipy's import costs every command

        self.static = static_costs(grid, robot_radius)
        self.planner = Planner(grid, self.static)
        # cells within 15 cm of the map's obstacles: a return there is the map, not a person
        self._near_mapped = binary_dilation(grid.data != FREE, iterations=max(1, round(0.15 / grid.resolution)))
        self._seen_at = np.full(grid.data.shape, -np.inf)
        radius_cells = math.ceil(robot_radius / grid.resolution)
        yy, xx = np.mgrid[-radius_cells : radius_cells + 1, -radius_cells : radius_cells + 1]
        self._disk = xx * xx + yy * yy <= radius_cells * radius_cells
        self._obstacles_at = -1
        self._obstacles = np.empty((0, 2))
        self.recent_s = recent_s
        self._recent: deque[tuple[float, np.ndarray]] = deque()  # (time, world points near the robot)
        self.plans = 0
        # -- the monitor's map (issue 21): the path being driven now, start to goal (None: none);
        # set and cleared by whoever follows it (navigator.drive_to), read by viewers
        self.path: list[tuple[float, float]] | None = None

    @classmethod
    def for_robot(
        cls, profile: Profile, devices: Mapping[str, Any], grid: GridMap, clock: Clock, pose: Callable[[], Pose2D]
    ) -> NavStack:
        base, interfaces = profile.base, profile.interfaces
        return cls(
            grid,
            base.footprint_radius,
            pose,
            clock,
            Limits(base.max_linear, base.max_angular, base.braking),
            laser=devices.get("laser"),
            laser_mount=interfaces["laser"].pose if "laser" in interfaces else (0.0, 0.0, 0.0),
            sonar=devices.get("sonar"),
            sonar_mount=interfaces["sonar"].pose if "sonar" in interfaces else (0.0, 0.0, 0.0),
            odometry=devices.get("odometry"),
            laser_fov=_field_of_view(interfaces.get("laser"), math.pi),
            sonar_fov=_field_of_view(interfaces.get("sonar"), 0.26),
        )

    # -- where the robot is, what it sees ---------------------------------------------------

    def pose(self) -> Pose2D:
        return self._pose()

    def obstacles(self) -> np.ndarray:
        """What the range sensors see now and saw close by in the last ``recent_s`` seconds, as
        points in the base frame (x ahead, y left); read once per tick however many ask."""
        tick = getattr(self.clock, "ticks", None)
        if tick is not None and tick == self._obstacles_at:
            return self._obstacles
        parts = []
        if self.laser is not None:
            scan: LaserScan = self.laser.scan()
            parts.append(_to_base(scan.points(), self.laser_mount))
        if self.sonar is not None:
            parts.append(_to_base(sonar_points(self.sonar.read()), self.sonar_mount))
        now_points = np.concatenate(parts) if parts else np.empty((0, 2))
        pose, now = self.pose(), self.clock.now()
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        near = now_points[np.hypot(now_points[:, 0], now_points[:, 1]) < 1.2]
        recent = self._recent
        while recent and recent[0][0] < now - self.recent_s:
            recent.popleft()
        remembered = [points for _, points in recent]
        if len(near):
            recent.append(
                (
                    now,
                    np.column_stack(
                        (pose.x + c * near[:, 0] - s * near[:, 1], pose.y + s * near[:, 0] + c * near[:, 1])
                    ),
                )
            )
        if remembered:
            world = np.concatenate(remembered)
            dx, dy = world[:, 0] - pose.x, world[:, 1] - pose.y
            now_points = np.concatenate((now_points, np.column_stack((c * dx + s * dy, -s * dx + c * dy))))
        self._obstacles = now_points
        self._obstacles_at = tick if tick is not None else -1
        return self._obstacles

    def unmapped_distance(self, points: np.ndarray, reach: float = 2.5) -> float:
        """Distance to the nearest sensed point (base frame, not behind the robot) that is not on
        the map: people, bags, a door left open. The follower slows near them."""
        if not len(points):
            return math.inf
        distance = np.hypot(points[:, 0], points[:, 1])
        keep = (distance < reach) & (points[:, 0] > -self.robot_radius)
        if not keep.any():
            return math.inf
        rows, cols = self._cells_of(self.pose(), points[keep])
        shape = self._near_mapped.shape
        on_map = self._near_mapped[np.clip(rows, 0, shape[0] - 1), np.clip(cols, 0, shape[1] - 1)]
        return float(distance[keep][~on_map].min()) if (~on_map).any() else math.inf

    def map_clearance(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Metres from each world point to the nearest cell the robot's map has as an obstacle or
        unknown (off the map is 0), or its obstacle layer holds: to the cell's nearest corner at
        worst, as the thing in it may be anywhere in it. Inf beyond ``CLEARANCE_REACH``."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        rows, cols = self.grid.cells(xs, ys)
        shape = self.grid.data.shape
        inside = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
        clearance = np.zeros(xs.shape)
        if not inside.any():
            return clearance
        # in cell units, so that the map's origin and yaw are the grid's concern
        at = np.column_stack(self._fractional_cells(xs[inside], ys[inside]))
        resolution = self.grid.resolution
        reach = CLEARANCE_REACH / resolution
        distance, _ = blocked_cells(self.grid).query(at, distance_upper_bound=reach)
        r0, c0 = max(int(rows[inside].min() - reach), 0), max(int(cols[inside].min() - reach), 0)
        r1, c1 = int(rows[inside].max() + reach) + 1, int(cols[inside].max() + reach) + 1
        seen_rows, seen_cols = np.nonzero(self.seen()[r0:r1, c0:c1])
        if len(seen_rows):
            centres = np.column_stack((seen_rows + r0 + 0.5, seen_cols + c0 + 0.5))
            gaps = np.hypot(at[:, None, 0] - centres[None, :, 0], at[:, None, 1] - centres[None, :, 1])
            distance = np.minimum(distance, gaps.min(axis=1))
        clearance[inside] = np.maximum(distance - HALF_DIAGONAL, 0.0) * resolution
        return clearance

    def _fractional_cells(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of world points in cell units, unrounded (a cell's centre is at +0.5)."""
        ox, oy, yaw = self.grid.origin
        dx, dy = xs - ox, ys - oy
        if yaw:
            c, s = math.cos(-yaw), math.sin(-yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        return dy / self.grid.resolution, dx / self.grid.resolution

    def sees(self, direction: float) -> bool:
        """Whether a range sensor looks that way (rad, base frame): behind a robot whose sensors
        all look ahead, what they saw near it of late is all it knows."""
        return any(abs(math.remainder(direction - heading, math.tau)) <= fov / 2 for heading, fov in self.views)

    def remembered(self) -> np.ndarray:
        """What the sensors saw near the robot in the last ``recent_s`` seconds, as world points,
        without reading them again."""
        now = self.clock.now()
        points = [p for t, p in self._recent if t >= now - self.recent_s]
        return np.concatenate(points) if points else np.empty((0, 2))

    def sensed_clearance(self, xs: np.ndarray, ys: np.ndarray, fresh: bool = True) -> np.ndarray:
        """Metres from each world point to the nearest thing the range sensors see now (or saw
        close by of late) that the map does not have: people, a bag, a door left open. With
        ``fresh`` false only what they saw of late counts (they do not look that way)."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        if fresh:
            pose, points = self.pose(), self.obstacles()
            c, s = math.cos(pose.theta), math.sin(pose.theta)
            world = np.column_stack(
                (pose.x + c * points[:, 0] - s * points[:, 1], pose.y + s * points[:, 0] + c * points[:, 1])
            )
        else:
            world = self.remembered()
        if len(world):
            rows, cols = self.grid.cells(world[:, 0], world[:, 1])
            shape = self._near_mapped.shape
            world = world[~self._near_mapped[np.clip(rows, 0, shape[0] - 1), np.clip(cols, 0, shape[1] - 1)]]
        if not len(world):
            return np.full(xs.shape, np.inf)
        return np.hypot(xs[:, None] - world[None, :, 0], ys[:, None] - world[None, :, 1]).min(axis=1)

    def follower_params(self, tolerance: float, heading_tolerance: float, max_speed: float | None) -> FollowerParams:
        limits = self.limits
        return FollowerParams(
            max_linear=min(limits.max_linear, max_speed) if max_speed else limits.max_linear,
            max_angular=min(limits.max_angular, 1.5),
            goal_tolerance=tolerance,
            heading_tolerance=heading_tolerance,
            robot_radius=self.robot_radius,
            max_decel=limits.max_accel,
            evade=self.laser is not None,  # a sonar's narrow cone cannot tell whether the side is clear
        )

    # -- the obstacle layer -----------------------------------------------------------------

    def mark(self, pose: Pose2D, points: np.ndarray, within: float = 3.0) -> int:
        """Stamp what the sensors see near the robot into the obstacle layer; returns the cells."""
        if not len(points):
            return 0
        points = points[np.hypot(points[:, 0], points[:, 1]) <= within]
        rows, cols = self._cells_of(pose, points)
        inside = (rows >= 0) & (rows < self._seen_at.shape[0]) & (cols >= 0) & (cols < self._seen_at.shape[1])
        self._seen_at[rows[inside], cols[inside]] = self.clock.now()
        return int(inside.sum())

    def _cells_of(self, pose: Pose2D, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grid cells of points given in the base frame of a robot at ``pose``."""
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        return self.grid.cells(
            pose.x + c * points[:, 0] - s * points[:, 1], pose.y + s * points[:, 0] + c * points[:, 1]
        )

    def clear(self) -> None:
        """Forget every obstacle seen (the `clear_costmap` recovery)."""
        self._seen_at[:] = -np.inf

    def forget(self, cells: np.ndarray) -> None:
        """Forget what was seen in ``cells`` (a mask of the map's shape): clearing part of the
        obstacle layer, around the robot, a pose or outside a region."""
        self._seen_at[cells] = -np.inf

    def seen(self) -> np.ndarray:
        """Cells that hold an obstacle seen within the memory."""
        return self._seen_at >= self.clock.now() - self.obstacle_memory

    def costs(self, seen: np.ndarray | None = None) -> np.ndarray:
        seen = self.seen() if seen is None else seen
        if not seen.any():
            return self.static
        from scipy.ndimage import binary_dilation

        costs = self.static.copy()
        costs[binary_dilation(seen, structure=self._disk)] = LETHAL
        return costs

    def plan(self, start: tuple[float, float], goal: tuple[float, float]) -> Plan:
        """A path on the static map plus what was seen (raises Unreachable)."""
        self.plans += 1
        seen = self.seen()
        if not seen.any():
            return self.planner.plan(start, goal)
        costs = self.costs(seen)
        row, col = self.grid.cell(*start)
        if self.grid.inside(row, col) and not math.isfinite(costs[row, col]):
            # the robot stands in what it saw (a person right beside it): free its own cell's disk
            r0, c0 = max(row - 2, 0), max(col - 2, 0)
            costs[r0 : row + 3, c0 : col + 3] = self.static[r0 : row + 3, c0 : col + 3]
        return Planner(self.grid, costs).plan(start, goal)

    def free(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether the robot's centre may stand here (static map and what was seen), with
        ``margin`` metres to spare all round."""
        if margin > 0:
            return all(
                self.free(x + margin * math.cos(a), y + margin * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 9)
            ) and self.free(x, y)
        row, col = self.grid.cell(x, y)
        if not self.grid.inside(row, col) or not math.isfinite(self.static[row, col]):
            return False
        half = self._disk.shape[0] // 2
        window = self._seen_at[max(row - half, 0) : row + half + 1, max(col - half, 0) : col + half + 1]
        return not (window >= self.clock.now() - self.obstacle_memory).any()

    def resolve(self, goal: str | list[float] | tuple[float, ...]) -> tuple[float, float, float | None]:
        """A place name or [x, y] / [x, y, theta] as a goal; raises ValueError with what is known."""
        if isinstance(goal, str):
            if goal not in self.places:
                known = ", ".join(sorted(self.places)) or "none on this map"
                raise ValueError(f"unknown place {goal!r} (places: {known})")
            x, y, theta = self.places[goal]
            return x, y, theta
        values = [float(v) for v in goal]
        if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
            raise ValueError(f"a goal is a place name, [x, y] or [x, y, theta], got {goal!r}")
        return values[0], values[1], values[2] if len(values) == 3 else None
