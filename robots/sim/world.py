"""The simulated world: one differential-drive robot on an occupancy grid, stepped by the clock.

Seeded and deterministic: every random draw comes from one numpy Generator made from the seed.
What it models, and why:

- **Kinematics** with the instantaneous centre of curvature (the book's ICC model), wheel
  speeds limited by the profile's top speed and accelerations, so commands are shaped as the
  real base would shape them.
- **Wheel slip**: each wheel covers the ground its turning says times (1 + noise). The encoders
  count whole ticks (quantisation) of the wheel's *turning*, not the ground it covered, as on a
  real floor: odometry drifts, and the localiser (EKF + map correction) has something to correct.
  In a bump the wheels stop with the body: they turned as far as it moved.
- **Collisions**: the robot's footprint may not overlap an occupied or unknown cell; a move
  that would is cut short where it was still clear, the wheels stop and a bump is reported.
  The robot never passes through a wall. A bump is a contact *event*: it begins with the first
  step cut short and lasts, however long the robot pushes or creeps on, until it is
  ``CONTACT_CLEAR`` from where it last touched; each
  is logged with its time, place and what was hit (a wall, which includes anything on the map,
  or a person). ``contact_steps`` counts the steps spent pushing.
- **Watchdog**: with no velocity command for ``watchdog_s`` the robot stops, as a real base's
  firmware does.
- **Battery** drains with the current drawn (idle plus a share of the drive current); a robot on
  mains power (no ``battery:`` in its profile) never runs down.
- **A fixed base** (the face tracker on its desk) stands where it was put: no wheels turn, the
  body stays, and only time (and what rides on it, such as a pan, which its own device moves)
  goes on.
- **IMU** integrates the true turn rate with a gyro bias and noise.
- **Laser** ranges by ray casting on the grid, all beams at once with numpy; people (round
  ``movers`` the backend attaches) return beams too.
- **People are obstacles**: the robot may not drive into one. A person who walks into a robot
  standing still is not the robot's bump (people keep clear of the robot themselves).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from botstage.robots.gridmap import FREE, GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Device, Profile

RAY_STEP = 0.7  # in cells: under the half-diagonal (1/sqrt 2), so a thin diagonal wall is not stepped over
RAY_CHUNK = 48  # steps a ray marches before the rays that hit drop out
_RAY_PAD = math.ceil(RAY_CHUNK * RAY_STEP) + 2  # cells of "hit" around the map: a chunk never leaves the array
CONTACT_CLEAR = 0.05  # m: a contact lasts until the robot is this far from where it last touched


def close_corners(hits: np.ndarray) -> np.ndarray:
    """Fill the gap where two blocked cells touch only at a corner (a one-cell staircase wall),
    so a ray cannot slip between them: their chords there can be arbitrarily short."""
    closed = hits.copy()
    down = hits[:-1, :-1] & hits[1:, 1:] & ~hits[:-1, 1:] & ~hits[1:, :-1]
    up = hits[:-1, 1:] & hits[1:, :-1] & ~hits[:-1, :-1] & ~hits[1:, 1:]
    closed[:-1, 1:] |= down
    closed[:-1, :-1] |= up
    return closed


def inflate(blocked: np.ndarray, radius_cells: int) -> np.ndarray:
    """Cells within ``radius_cells`` of a blocked cell (a disk, by shifting: no scipy needed)."""
    grown = blocked.copy()
    rows, cols = blocked.shape
    for dr in range(-radius_cells, radius_cells + 1):
        for dc in range(-radius_cells, radius_cells + 1):
            if dr * dr + dc * dc > radius_cells * radius_cells or (dr == 0 and dc == 0):
                continue
            grown[max(dr, 0) : rows + min(dr, 0), max(dc, 0) : cols + min(dc, 0)] |= blocked[
                max(-dr, 0) : rows + min(-dr, 0), max(-dc, 0) : cols + min(-dc, 0)
            ]
    return grown


@dataclass
class WheelState:
    speed: float = 0.0  # m/s, actual
    distance: float = 0.0  # m of ground covered since start (signed, slip included)
    turned: float = 0.0  # m the wheel turned since start (what the encoder counts)
    ticks: int = 0


@dataclass(frozen=True)
class Bump:
    """One contact event: when it began, where the robot's centre was, and what it hit."""

    t: float
    x: float
    y: float
    what: str  # "wall" (anything on the map) or "person"


@dataclass
class Body:
    """The robot's true state in the world."""

    pose: Pose2D
    left: WheelState = field(default_factory=WheelState)
    right: WheelState = field(default_factory=WheelState)
    bumped: bool = False  # the last step was cut short
    bumps: int = 0  # contact events: entering contact, not the steps spent pushing
    person_bumps: int = 0  # of the bumps, those into a person
    contact_steps: int = 0  # steps cut short, pushing included
    contact: str = ""  # what the robot touches now ("wall" or "person"); "" once it got away
    bump_log: list[Bump] = field(default_factory=list)
    yaw_rate: float = 0.0  # true rad/s
    linear: float = 0.0  # true m/s

    @property
    def wall_bumps(self) -> int:
        return self.bumps - self.person_bumps


class World:
    def __init__(
        self,
        grid: GridMap,
        profile: Profile,
        start: Pose2D,
        seed: int = 0,
        *,
        slip_std: float = 0.02,
        gyro_bias: float = 0.002,
        watchdog_s: float = 0.5,
    ) -> None:
        self.grid = grid
        self.profile = profile
        self.base = profile.base
        self.seed = seed
        self.rng = np.random.default_rng(seed)  # wheel slip and the IMU
        self._noise: dict[str, np.random.Generator] = {}
        self.slip_std = slip_std
        self.gyro_bias = gyro_bias
        self.watchdog_s = watchdog_s
        self.time = 0.0
        self.body = Body(start)
        radius = math.ceil(self.base.footprint_radius / grid.resolution)
        self.blocked = inflate(grid.data != FREE, radius)  # where the robot's centre may not be
        self.hits = grid.data != FREE  # what a beam stops at
        closed = close_corners(self.hits)
        self._padded = np.pad(closed, 1, constant_values=True)  # off the map counts as a hit
        self._ray_grid = np.pad(closed, _RAY_PAD, constant_values=True)
        self._ray_flat = self._ray_grid.ravel()
        if self.collides(start.x, start.y):
            raise ValueError(f"the robot cannot start at ({start.x:g}, {start.y:g}): it would overlap an obstacle")
        self._command = (0.0, 0.0)
        self._command_time = -math.inf
        self.battery_charge_ah = profile.battery.capacity_ah if profile.battery is not None else 0.0
        self.imu_yaw = start.theta
        # moving round obstacles (people): their centres as an (n, 2) array, and their radius
        self.movers: Callable[[], np.ndarray] | None = None
        self.mover_radius = 0.25
        self._touched = start  # where the robot last touched something

    # -- commands -----------------------------------------------------------------------------

    def cmd_vel(self, v: float, w: float) -> None:
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"a velocity command must be finite, got ({v}, {w})")
        self._command = (v, w)
        self._command_time = self.time

    def stop(self) -> None:
        self.cmd_vel(0.0, 0.0)

    def wheel_targets(self) -> tuple[float, float]:
        """Commanded (v, w) to wheel speeds, within the profile's limits (the driver's job on hardware)."""
        v, w = self._command
        if self.time - self._command_time > self.watchdog_s:
            v, w = 0.0, 0.0
        base = self.base
        v = max(-base.max_linear, min(base.max_linear, v))
        w = max(-base.max_angular, min(base.max_angular, w))
        half = base.wheel_separation / 2
        left, right = v - w * half, v + w * half
        top = base.wheel_top_speed
        scale = max(abs(left), abs(right), top) / top  # keep the turn's shape when a wheel saturates
        return left / scale, right / scale

    # -- stepping -----------------------------------------------------------------------------

    def collides(self, x: float, y: float) -> bool:
        row, col = self.grid.cell(x, y)
        return not self.grid.inside(row, col) or bool(self.blocked[row, col])

    def step(self, dt: float) -> None:
        body, base = self.body, self.base
        if not base.moves:  # a fixed base: nothing to drive, the body stays where it stands
            body.bumped = False
            body.yaw_rate = body.linear = 0.0
            self._drain(dt)
            self.time += dt
            return
        target_left, target_right = self.wheel_targets()
        for wheel, target in ((body.left, target_left), (body.right, target_right)):
            slowing = abs(target) < abs(wheel.speed) and target * wheel.speed >= 0
            limit = (base.braking if slowing else base.max_linear_accel) * dt
            wheel.speed += max(-limit, min(limit, target - wheel.speed))
        slip = 1.0 + self.rng.normal(0.0, self.slip_std, 2)
        d_left, d_right = float(body.left.speed * dt * slip[0]), float(body.right.speed * dt * slip[1])
        pose = self._icc(body.pose, d_left, d_right)
        body.bumped = False
        if d_left or d_right:
            movers = self._movers_near(body.pose)
            pose, clear, into_person = self._clear_part(body.pose, pose, d_left, d_right, movers)
            if clear:
                if body.contact and math.hypot(pose.x - self._touched.x, pose.y - self._touched.y) >= CONTACT_CLEAR:
                    body.contact = ""  # it got away from what it touched
            else:
                self._touch(pose, "person" if into_person else "wall", dt)
                body.left.speed = body.right.speed = 0.0
                self._command = (0.0, 0.0)
        if body.bumped:
            covered = self._travelled(body.pose, pose, d_left, d_right)
            turned = covered  # the wheels stopped with the body
        else:
            covered = (d_left, d_right)
            turned = (body.left.speed * dt, body.right.speed * dt)
        per_metre = base.encoder_ticks_per_rev / (math.pi * base.wheel_diameter)
        for wheel, ground, turning in zip((body.left, body.right), covered, turned, strict=True):
            wheel.distance += ground
            wheel.turned += turning
            wheel.ticks = math.floor(wheel.turned * per_metre)
        body.yaw_rate = _angle(pose.theta - body.pose.theta) / dt
        body.linear = math.hypot(pose.x - body.pose.x, pose.y - body.pose.y) / dt
        body.pose = pose
        gyro = body.yaw_rate + self.gyro_bias + self.rng.normal(0.0, 0.005)
        self.imu_yaw = _angle(self.imu_yaw + gyro * dt)
        self._drain(dt)
        self.time += dt

    def _drain(self, dt: float) -> None:
        """The battery gives the idle current and a share of the drive current; mains never runs down."""
        battery = self.profile.battery
        if battery is None:
            return
        load = abs(self.body.linear) / self.base.max_linear if self.base.max_linear else 0.0
        current = battery.idle_current + battery.drive_current * min(load, 1.0)
        self.battery_charge_ah = max(0.0, self.battery_charge_ah - current * dt / 3600)

    def _touch(self, pose: Pose2D, what: str, dt: float) -> None:
        """A step cut short: a new bump when the robot was not touching this kind of thing yet."""
        body = self.body
        body.bumped = True
        body.contact_steps += 1
        self._touched = pose
        if body.contact != what:
            body.contact = what
            body.bumps += 1
            body.person_bumps += what == "person"
            body.bump_log.append(Bump(round(self.time + dt, 6), pose.x, pose.y, what))

    def _icc(self, pose: Pose2D, d_left: float, d_right: float) -> Pose2D:
        """The book's ICC model: both wheels turn about one centre (or go straight)."""
        separation = self.base.wheel_separation
        d_theta = (d_right - d_left) / separation
        distance = (d_left + d_right) / 2
        if abs(d_theta) < 1e-9:
            return Pose2D(
                float(pose.x + distance * math.cos(pose.theta)),
                float(pose.y + distance * math.sin(pose.theta)),
                pose.theta,
            )
        radius = distance / d_theta
        icc_x = pose.x - radius * math.sin(pose.theta)
        icc_y = pose.y + radius * math.cos(pose.theta)
        c, s = math.cos(d_theta), math.sin(d_theta)
        dx, dy = pose.x - icc_x, pose.y - icc_y
        return Pose2D(
            float(icc_x + c * dx - s * dy), float(icc_y + s * dx + c * dy), float(_angle(pose.theta + d_theta))
        )

    def _movers_near(self, pose: Pose2D) -> np.ndarray:
        """People close enough to touch the robot within this step."""
        if self.movers is None:
            return np.empty((0, 2))
        centres = np.asarray(self.movers(), dtype=float).reshape(-1, 2)
        reach = self.base.footprint_radius + self.mover_radius + 0.1
        return centres[np.hypot(centres[:, 0] - pose.x, centres[:, 1] - pose.y) < reach]

    def _clear_part(
        self, start: Pose2D, end: Pose2D, d_left: float, d_right: float, movers: np.ndarray
    ) -> tuple[Pose2D, bool, bool]:
        """The last clear pose along the move, sampled finer than a cell; whether all of it was
        clear; and whether what stopped it was a person."""
        steps = max(1, math.ceil(max(abs(d_left), abs(d_right)) / (self.grid.resolution / 2)))
        touch = self.base.footprint_radius + self.mover_radius
        last = start
        before = np.hypot(movers[:, 0] - start.x, movers[:, 1] - start.y) if len(movers) else None
        for k in range(1, steps + 1):
            pose = self._icc(start, d_left * k / steps, d_right * k / steps)
            if self.collides(pose.x, pose.y):
                return last, False, False
            if before is not None:
                now = np.hypot(movers[:, 0] - pose.x, movers[:, 1] - pose.y)
                if bool(np.any((now < touch) & (now < before))):  # moving into someone
                    return last, False, True
            last = pose
        return end, True, False

    def _travelled(self, start: Pose2D, end: Pose2D, d_left: float, d_right: float) -> tuple[float, float]:
        full = max(abs(d_left), abs(d_right))
        if full == 0:
            return 0.0, 0.0
        done = (
            math.hypot(end.x - start.x, end.y - start.y)
            + abs(_angle(end.theta - start.theta)) * self.base.wheel_separation / 2
        )
        share = min(1.0, done / full)
        return d_left * share, d_right * share

    # -- sensors ------------------------------------------------------------------------------

    def laser(self, device: Device) -> np.ndarray:
        """Ranges of one scan, every beam cast at once; inf for no return."""
        beams = device.beams or 181
        fov = device.field_of_view or math.pi
        range_min, range_max = device.range_min or 0.0, device.range_max or 10.0
        mx, my, mtheta = device.pose
        pose = self.body.pose
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        ox, oy = pose.x + c * mx - s * my, pose.y + s * mx + c * my
        angles = pose.theta + mtheta - fov / 2 + fov * np.arange(beams) / max(beams - 1, 1)
        ranges = self.cast(ox, oy, angles, range_max)
        if self.movers is not None:
            ranges = np.minimum(ranges, self._mover_ranges(ox, oy, np.cos(angles), np.sin(angles), range_max))
        if device.noise:
            ranges = ranges + self.noise("laser").normal(0.0, device.noise, beams)
        ranges[(ranges > range_max) | (ranges < range_min)] = np.inf
        return ranges

    def cast(
        self, x: float, y: float, angles: np.ndarray, range_max: float = math.inf, halvings: int = 2
    ) -> np.ndarray:
        """How far each ray from (x, y) runs before it meets the map (inf: not within ``range_max``).

        Rays march in steps of ``RAY_STEP`` cells, a chunk of steps at a time, and drop out once
        they hit, so open views cost only the rays still open; off the map counts as a hit. The
        surface lies within the last step: each halving refines it twofold (two: a quarter step)."""
        resolution = self.grid.resolution
        gx, gy, yaw = self.grid.origin
        dx, dy = x - gx, y - gy
        if yaw:
            c, s = math.cos(-yaw), math.sin(-yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        # in cells of the ray grid; a ray still open is on the map, so its chunk stays in the array
        cx, cy = dx / resolution + _RAY_PAD, dy / resolution + _RAY_PAD
        width = self._ray_grid.shape[1]
        flat = self._ray_flat
        angles = np.asarray(angles, dtype=float) - yaw
        ux, uy = np.cos(angles), np.sin(angles)
        rows_total, cols_total = self.grid.data.shape
        reach = min(range_max / resolution, math.hypot(rows_total, cols_total) + 2) + RAY_STEP
        total = math.ceil(reach / RAY_STEP)
        far = np.full(angles.shape, np.inf)
        active = np.arange(angles.size)
        for start in range(0, total, RAY_CHUNK):
            if not active.size:
                break
            steps = np.arange(start + 1, min(start + RAY_CHUNK, total) + 1) * RAY_STEP
            cols = (cx + ux[active, None] * steps).astype(np.intp)
            rows = (cy + uy[active, None] * steps).astype(np.intp)
            hit = flat[rows * width + cols]
            done = hit.any(axis=1)
            far[active[done]] = steps[hit[done].argmax(axis=1)]
            active = active[~done]
        found = np.isfinite(far)
        high = np.where(found, far, 0.0)
        low = np.maximum(high - RAY_STEP, 0.0)
        for _ in range(halvings):
            middle = (low + high) / 2
            inside = flat[(cy + uy * middle).astype(np.intp) * width + (cx + ux * middle).astype(np.intp)]
            high = np.where(inside, middle, high)
            low = np.where(inside, low, middle)
        return np.where(found, high * resolution, np.inf)

    def _mover_ranges(self, ox: float, oy: float, cos: np.ndarray, sin: np.ndarray, range_max: float) -> np.ndarray:
        """Where each beam first meets a person's circle (inf where it meets none)."""
        assert self.movers is not None
        centres = np.asarray(self.movers(), dtype=float).reshape(-1, 2)
        dx, dy = centres[:, 0] - ox, centres[:, 1] - oy
        centres = centres[np.hypot(dx, dy) < range_max + self.mover_radius]
        if not len(centres):
            return np.full(len(cos), np.inf)
        dx, dy = centres[:, 0] - ox, centres[:, 1] - oy
        along = np.outer(cos, dx) + np.outer(sin, dy)  # beams x people
        off_sq = (dx * dx + dy * dy)[None, :] - along * along
        r_sq = self.mover_radius * self.mover_radius
        hit = (off_sq <= r_sq) & (along > 0)
        entry = along - np.sqrt(np.maximum(r_sq - off_sq, 0.0))
        entry = np.where(hit & (entry > 0), entry, np.inf)
        return entry.min(axis=1)

    def padded_cells(self, xs: np.ndarray | float, ys: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Cells of the padded hit grid for world points, the map's origin yaw included; points
        off the map land on its blocked border."""
        ox, oy, yaw = self.grid.origin
        dx, dy = np.asarray(xs) - ox, np.asarray(ys) - oy
        if yaw:
            c, s = math.cos(-yaw), math.sin(-yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        rows = np.clip(np.floor(dy / self.grid.resolution).astype(np.int32) + 1, 0, self._padded.shape[0] - 1)
        cols = np.clip(np.floor(dx / self.grid.resolution).astype(np.int32) + 1, 0, self._padded.shape[1] - 1)
        return rows, cols

    def noise(self, sensor: str) -> np.random.Generator:
        """Each sensor draws from its own generator, so reading one never changes the others
        (or the wheel slip): adding a skill that reads a sensor leaves the robot's path alone."""
        generator = self._noise.get(sensor)
        if generator is None:
            generator = self._noise[sensor] = np.random.default_rng([self.seed, zlib.crc32(sensor.encode())])
        return generator

    @property
    def battery_percent(self) -> float:
        """The charge left; always 100 on mains power (no battery to run down)."""
        battery = self.profile.battery
        return 100.0 * self.battery_charge_ah / battery.capacity_ah if battery is not None else 100.0

    @property
    def battery_voltage(self) -> float:
        battery = self.profile.battery
        if battery is None:
            raise ValueError(f"robot {self.profile.name!r} has no battery (it runs on mains power)")
        return battery.empty_voltage + (battery.full_voltage - battery.empty_voltage) * self.battery_percent / 100


def _angle(theta: float) -> float:
    return (theta + math.pi) % (2 * math.pi) - math.pi
