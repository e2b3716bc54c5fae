"""The simulator's devices: the robot interfaces, provided by a World.

Odometry is computed from the encoder ticks exactly as a driver computes it from a real board
(diff_tf's model), so it drifts with the simulated wheel slip; the world's true pose stays
hidden from skills. A legged base (Bittle) walks in gaits and estimates its odometry from them,
as its NyBoard driver does (``SimGaitDrive``, ``SimGaitOdometry``). A pan servo (``SimPan``) turns
on the world's time as the AX-12A does, and a camera mounted on it looks where it points.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from botstage.robots.clock import Clock
from botstage.robots.gaits import GaitOdometry, Gaits, choose
from botstage.robots.interfaces import (
    AUDIO_BUFFER_S,
    BatteryState,
    CameraInfo,
    ImuReading,
    LaserScan,
    OdometryReading,
    Pose2D,
    SonarReading,
    TrackedPerson,
    Twist2D,
)
from botstage.robots.profile import Device, ServoJoint
from botstage.robots.sim.people import Crowd
from botstage.robots.sim.world import World

if TYPE_CHECKING:
    from botstage.robots.sim.camera import CameraView


class SimDrive:
    def __init__(self, world: World) -> None:
        self.world = world

    def cmd_vel(self, v: float, w: float) -> None:
        self.world.cmd_vel(v, w)

    def stop(self) -> None:
        self.world.stop()


class SimOdometry:
    """Dead reckoning from encoder ticks, with a covariance that grows with distance and turning."""

    def __init__(self, world: World, clock: Clock) -> None:
        self.world = world
        self.clock = clock
        start = world.body.pose
        self.x, self.y, self.theta = start.x, start.y, start.theta
        self._ticks = (world.body.left.ticks, world.body.right.ticks)
        self._twist = Twist2D(0.0, 0.0)
        self._variance = np.zeros(3)
        self._at = clock.ticks  # the encoders' counts at this tick are the reference

    def _update(self) -> None:
        if self._at == self.clock.ticks:
            return
        elapsed = (self.clock.ticks - self._at) * self.clock.period
        self._at = self.clock.ticks
        base = self.world.base
        left, right = self.world.body.left.ticks, self.world.body.right.ticks
        per_tick = 1.0 / base.ticks_per_metre
        d_left, d_right = (left - self._ticks[0]) * per_tick, (right - self._ticks[1]) * per_tick
        self._ticks = (left, right)
        distance, d_theta = (d_left + d_right) / 2, (d_right - d_left) / base.wheel_separation
        self.x += distance * math.cos(self.theta + d_theta / 2)
        self.y += distance * math.sin(self.theta + d_theta / 2)
        self.theta = math.atan2(math.sin(self.theta + d_theta), math.cos(self.theta + d_theta))
        self._twist = Twist2D(distance / elapsed, d_theta / elapsed)  # over the time since the last read
        # 2% of distance and 5% of turning as standard deviations, accumulated
        self._variance += np.array([(0.02 * distance) ** 2, (0.02 * distance) ** 2, (0.05 * d_theta) ** 2])

    def read(self) -> OdometryReading:
        self._update()
        return OdometryReading(
            self.clock.now(), Pose2D(self.x, self.y, self.theta), self._twist, np.diag(self._variance)
        )


class SimImu:
    def __init__(self, world: World, clock: Clock) -> None:
        self.world = world
        self.clock = clock

    def read(self) -> ImuReading:
        body = self.world.body
        return ImuReading(self.clock.now(), self.world.imu_yaw, body.yaw_rate + self.world.gyro_bias, (0.0, 0.0))


class SimLaser:
    """A scanner that turns at ``rate_hz``: reads within one revolution get the same scan, as a
    driver's latest-scan buffer would give them (and the world casts the rays once)."""

    def __init__(self, world: World, device: Device, clock: Clock) -> None:
        self.world = world
        self.device = device
        self.clock = clock
        self.period = 1.0 / device.rate_hz if device.rate_hz else 0.0
        self._last: LaserScan | None = None
        self._slot: int | None = None

    @property
    def latest(self) -> LaserScan | None:
        """The last scan read, without turning the scanner again (what a viewer shows)."""
        return self._last

    def scan(self) -> LaserScan:
        now = self.clock.now()
        # the world's own time decides when the scanner turned: a scan never shows a world that moved on
        slot = math.floor(self.world.time / self.period + 1e-9) if self.period else None
        if self._last is not None and slot is not None and slot == self._slot:
            return self._last
        device = self.device
        beams = device.beams or 181
        fov = device.field_of_view or math.pi
        self._last = LaserScan(
            now,
            -fov / 2,
            fov / max(beams - 1, 1),
            device.range_min or 0.0,
            device.range_max or 10.0,
            self.world.laser(device),
        )
        self._slot = slot
        return self._last


class SimSonar:
    """An ultrasonic cone: the nearest of a few rays across its field of view."""

    RAYS = 7

    def __init__(self, world: World, device: Device, clock: Clock) -> None:
        self.world = world
        self.device = device.model_copy(update={"beams": self.RAYS, "field_of_view": device.field_of_view or 0.26})
        self.clock = clock

    def read(self) -> SonarReading:
        ranges = self.world.laser(self.device)
        nearest = float(np.min(ranges))
        return SonarReading(self.clock.now(), nearest, self.device.field_of_view or 0.26, self.device.range_max or 4.0)


class SimBattery:
    def __init__(self, world: World, clock: Clock) -> None:
        self.world = world
        self.clock = clock

    def read(self) -> BatteryState:
        world = self.world
        load = min(abs(world.body.linear) / world.base.max_linear, 1.0)
        battery = world.profile.battery
        return BatteryState(
            self.clock.now(),
            world.battery_voltage,
            world.battery_percent,
            battery.idle_current + battery.drive_current * load,
        )


class SimSpeaker:
    """Records what was said and played; busy for as long as it would sound on the mission clock.

    Text alone lasts about 0.4 s a word; played audio lasts its samples' duration. ``said`` holds
    the text of both, ``played`` the audio (time, text, int16 samples, rate)."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self.said: list[tuple[float, str]] = []
        self.played: list[tuple[float, str, np.ndarray, int]] = []
        self._until = 0.0

    def say(self, text: str) -> None:
        now = self.clock.now()
        self.said.append((now, text))
        self._until = max(self._until, now) + 0.4 * max(1, len(text.split()))

    def play(self, samples: np.ndarray, rate_hz: int, text: str = "") -> None:
        samples = np.asarray(samples)
        if samples.ndim != 1 or samples.dtype != np.int16:
            raise ValueError(f"audio must be one-dimensional int16 samples, got {samples.dtype} {samples.shape}")
        if not rate_hz > 0:
            raise ValueError(f"a sample rate must be positive, got {rate_hz}")
        now = self.clock.now()
        self.said.append((now, text))
        self.played.append((now, text, samples, rate_hz))
        self._until = max(self._until, now) + samples.size / rate_hz

    def stop(self) -> None:
        self._until = min(self._until, self.clock.now())

    def busy(self) -> bool:
        return self.clock.now() < self._until


class SimDisplay:
    """Records which layout was shown when."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self.shown: list[tuple[float, str, dict[str, str]]] = []

    def show(self, layout: str, **content: str) -> None:
        self.shown.append((self.clock.now(), layout, dict(content)))


class SimPeopleTracker:
    """People as a Kinect skeleton tracker reports them: in its frame (x right, z forward), within
    its range and field of view, not behind walls, with noise; ids stay with their person."""

    def __init__(self, world: World, crowd: Crowd, device: Device, clock: Clock) -> None:
        self.world = world
        self.crowd = crowd
        self.device = device
        self.clock = clock
        self.range_min = device.range_min or 0.8
        self.range_max = device.range_max or 4.0

    def people(self) -> list[TrackedPerson]:
        device, pose = self.device, self.world.body.pose
        mx, my, mtheta = device.pose
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        sx, sy, heading = pose.x + c * mx - s * my, pose.y + s * mx + c * my, pose.theta + mtheta
        half_fov = (device.field_of_view or 1.0) / 2
        in_view = []
        for person in self.crowd.people:
            dx, dy = person.x - sx, person.y - sy
            forward = dx * math.cos(heading) + dy * math.sin(heading)
            right = dx * math.sin(heading) - dy * math.cos(heading)
            if self.range_min <= forward <= self.range_max and abs(math.atan2(right, forward)) <= half_fov:
                in_view.append((person, right, forward, math.atan2(dy, dx), math.hypot(dx, dy)))
        if not in_view:
            return []
        # a wall on the line of sight, up to 0.3 m short of the person, hides them: one ray each
        walls = self.world.cast(sx, sy, np.array([view[3] for view in in_view]), self.range_max)
        seen = []
        for (person, right, forward, _bearing, distance), wall in zip(in_view, walls, strict=True):
            if wall < distance - 0.3:
                continue
            noise = self.world.noise("people").normal(0.0, device.noise, 2) if device.noise else (0.0, 0.0)
            seen.append(TrackedPerson(person.id, right + float(noise[0]), forward + float(noise[1])))
        return seen


class SimCamera:
    """Frames of the world from the camera's pose on the robot (robots/sim/camera.py draws them).

    A frame is rendered at most once a clock tick, when it is first asked for, and every reader
    in that tick gets the same array: so it is read-only (copy it to draw on it)."""

    def __init__(
        self, world: World, crowd: Crowd, device: Device, clock: Clock, pan: Callable[[], float] | None = None
    ) -> None:
        """``pan``: the present angle (rad) of the joint the camera rides on, read at each render."""
        from botstage.robots.sim.camera import CameraView  # OpenCV loads only for robots with a camera

        self.world = world
        self.crowd = crowd
        self.clock = clock
        self.pan = pan
        self.view: CameraView = CameraView(device)
        self.info = CameraInfo(self.view.width, self.view.height, self.view.fov)
        self._frame: np.ndarray | None = None
        self._at = -1  # the tick the cached frame shows
        self.renders = 0

    def frame(self) -> np.ndarray:
        if self._frame is None or self._at != self.clock.ticks:
            frame = self.view.render(self.world, self.crowd.people, self.pan() if self.pan is not None else 0.0)
            frame.setflags(write=False)
            self._frame, self._at = frame, self.clock.ticks
            self.renders += 1
        return self._frame


class SimMicrophone:
    """16 kHz mono int16 audio: faint room noise plus the sounds scheduled with ``play``.

    Sample n is the sound at mission time n / 16000 s. A read returns every sample from the end
    of the previous read up to (not including) the clock's time, so consecutive reads join with
    no gap and no overlap, whatever the tick rate. Recording starts when the microphone is made:
    the first read returns the samples since then (since t = 0 for a backend made at the
    start). The noise is drawn sample by sample from ``world.noise("microphone")``, so the audio is
    the same however it is read.

    Like a sound card's ring buffer, it keeps at most ``BUFFER_S`` seconds between reads: a read
    after a longer pause (a listener that was gone) returns only the latest ``BUFFER_S`` seconds and
    counts the samples dropped before them in ``dropped``."""

    RATE = 16_000  # samples a second
    NOISE_DBFS = -50.0  # the room's hum, as RMS relative to full scale
    BUFFER_S = AUDIO_BUFFER_S  # audio kept between two reads; older samples are dropped
    _SKIP_CHUNK = 16_000  # noise drawn (and thrown away) this many samples at a time for dropped audio

    def __init__(self, world: World, clock: Clock) -> None:
        self.world = world
        self.clock = clock
        self._next = self._samples_until(clock.now())  # index of the next sample to deliver
        self._sounds: list[tuple[int, np.ndarray]] = []  # (first sample index, samples as int32)
        self._noise_std = 32768 * 10 ** (self.NOISE_DBFS / 20)
        self.dropped = 0  # samples lost because nobody read them within BUFFER_S

    def use_clock(self, clock: Clock) -> None:
        """Hear on this clock from now on (a run's clock that starts once the robot is up)."""
        self.clock = clock
        self._next = self._samples_until(clock.now())
        self._sounds = []

    def _samples_until(self, t: float) -> int:
        """How many samples lie before time ``t`` (those at n / RATE < t); the epsilon keeps an
        exact sample time that floating point puts a hair above it from counting early."""
        return max(0, math.ceil(t * self.RATE - 1e-6))

    def play(self, samples: np.ndarray, at: float) -> None:
        """Mix int16 16 kHz ``samples`` into what the microphone hears from mission time ``at``.
        Any part before the samples already read is lost, as it would be for a real microphone;
        playing at the clock's time loses nothing."""
        samples = np.asarray(samples)
        if samples.ndim != 1 or samples.dtype != np.int16:
            raise ValueError(f"a sound must be one-dimensional int16 samples, got {samples.dtype} {samples.shape}")
        if not (math.isfinite(at) and at >= 0):
            raise ValueError(f"a sound must start at a finite mission time >= 0, got {at}")
        if samples.size:
            self._sounds.append((round(at * self.RATE), samples.astype(np.int32)))

    def read(self) -> np.ndarray:
        start, end = self._next, self._samples_until(self.clock.now())
        if end <= start:
            return np.zeros(0, np.int16)
        self._next = end
        noise = self.world.noise("microphone")
        kept = round(self.BUFFER_S * self.RATE)
        if end - start > kept:  # an overrun: the oldest audio is lost, the noise stream goes on as if heard
            self._skip_noise(noise, end - kept - start)
            self.dropped += end - kept - start
            start = end - kept
        mixed = noise.normal(0.0, self._noise_std, end - start)
        playing = []
        for first, sound in self._sounds:
            a, b = max(first, start), min(first + sound.size, end)
            if a < b:
                mixed[a - start : b - start] += sound[a - first : b - first]
            if first + sound.size > end:
                playing.append((first, sound))
        self._sounds = playing
        return np.clip(np.round(mixed), -32768, 32767).astype(np.int16)

    def _skip_noise(self, noise: np.random.Generator, count: int) -> None:
        """Draw ``count`` noise samples and drop them, in bounded chunks, so what follows is unchanged."""
        while count > 0:
            step = min(count, self._SKIP_CHUNK)
            noise.normal(0.0, self._noise_std, step)
            count -= step


class SimGaitDrive:
    """A legged base's drive: the command becomes a gait (robots/gaits.py), and the body walks at
    that gait's table speed, as the NyBoard's robot would, not at the speed asked.

    It also keeps the gait odometry's estimate, moved on over each stretch of world time in the
    gait that held then (up to the world's watchdog, which stops the robot): the estimate a
    driver makes from the gaits it sent, which the body's slip and its starts and stops leave
    behind the truth.
    """

    def __init__(self, world: World, gaits: Gaits) -> None:
        self.world = world
        self.gaits = gaits
        self.choice = choose(gaits, 0.0, 0.0)
        self.commanded_at = -math.inf  # world time of the last command (its watchdog stops the gait)
        self.estimate = GaitOdometry(world.body.pose)
        self._at = world.time  # the estimate is up to this world time

    def cmd_vel(self, v: float, w: float) -> None:
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"a velocity command must be finite, got ({v}, {w})")
        base = self.world.base
        v = max(-base.max_linear, min(base.max_linear, v))
        w = max(-base.max_angular, min(base.max_angular, w))
        self.advance()
        self.choice = choose(self.gaits, v, w)
        self.commanded_at = self.world.time
        self.world.cmd_vel(self.choice.v, self.choice.w)

    def stop(self) -> None:
        self.cmd_vel(0.0, 0.0)

    def advance(self) -> None:
        """Move the estimate on to the world's time in the gait held since the last command."""
        now, walking_until = self.world.time, self.commanded_at + self.world.watchdog_s
        moving = max(0.0, min(now, walking_until) - self._at)
        self.estimate.advance(moving, self.choice.v, self.choice.w)
        if now > walking_until:
            self.estimate.advance(0.0, 0.0, 0.0)  # the watchdog stopped it: standing since
        self._at = now


class SimGaitOdometry:
    """A legged base's odometry: dead reckoning from the gaits it walked in (no encoders)."""

    measured = False  # reckoned from the commands: it cannot tell a blocked robot from a walking one

    def __init__(self, drive: SimGaitDrive, clock: Clock) -> None:
        self.drive = drive
        self.clock = clock

    def read(self) -> OdometryReading:
        self.drive.advance()
        estimate = self.drive.estimate
        return OdometryReading(self.clock.now(), estimate.pose, estimate.twist, estimate.covariance)


class SimPan:
    """A pan servo as the AX-12A of the face tracker turns (``robots/emulators/ax12.py`` plays the
    same servo byte for byte): the goal is the driver's (the angle clamped to the limits, rounded to
    position units of 300°/1024), the shaft turns towards it at the joint speed the servo is given
    (its Moving Speed register holds units of 0.111 rpm, so 1.17 rad/s runs at 101 units, 1.174
    rad/s), and it reads back in whole units, as Present Position does.

    The shaft moves on the world's time, brought up to date whenever it is commanded or read (as
    ``SimGaitDrive.advance`` does): the same between two ticks however often it is asked, and the
    same run after run. ``angle`` is the shaft's exact angle, which a camera on it looks along.
    """

    def __init__(self, world: World, joint: ServoJoint) -> None:
        from botstage.robots import ax12 as ax  # the servo's units and conversions, one place

        self.world = world
        self.joint = joint
        self._ax = ax
        self._flipped = joint.min > joint.max  # dynamixel_controllers' "flipped" joint
        self.low, self.high = sorted((joint.min, joint.max))
        self.units_per_s = ax.speed_to_raw(joint.joint_speed) * ax.RAD_S_PER_SPEED_UNIT / ax.RAD_PER_UNIT
        self._shaft = float(joint.init)  # position units
        self._goal = joint.init
        self._at = world.time
        self.commands = 0
        self.clamped = 0

    @property
    def min_angle(self) -> float:
        return min(self._angle(self.low), self._angle(self.high))

    @property
    def max_angle(self) -> float:
        return max(self._angle(self.low), self._angle(self.high))

    @property
    def speed(self) -> float:
        """rad/s the shaft turns at (the joint speed as the servo's register holds it)."""
        return self.units_per_s * self._ax.RAD_PER_UNIT

    def _angle(self, raw: float) -> float:
        return self._ax.raw_to_angle(raw, self.joint.init, self._flipped)

    def move_to(self, angle: float) -> bool:
        """Turn towards ``angle`` (rad, counter-clockwise positive), clamped to the limits; always sent."""
        if not math.isfinite(angle):
            raise ValueError(f"angle {angle}: a finite number of radians")
        self.advance()
        clamped = min(max(angle, self.min_angle), self.max_angle)
        self.clamped += clamped != angle
        raw = self._ax.angle_to_raw(clamped, self.joint.init, self._flipped)
        self._goal = min(max(raw, self.low), self.high)
        self.commands += 1
        return True

    def position(self) -> float:
        """The present angle as the servo reports it: in whole position units."""
        self.advance()
        return self._angle(round(self._shaft))

    @property
    def angle(self) -> float:
        """The shaft's exact angle now (rad), for what rides on it."""
        self.advance()
        return self._angle(self._shaft)

    @property
    def goal(self) -> float:
        return self._angle(self._goal)

    @property
    def moving(self) -> bool:
        self.advance()
        return self._shaft != self._goal

    def hold(self) -> None:
        """Stop where the shaft is now (the goal becomes the present position), as the driver's close does."""
        self.advance()
        self._goal = min(max(round(self._shaft), self.low), self.high)

    def advance(self) -> None:
        """Turn the shaft over the world time since the last call, towards the goal at the joint speed."""
        dt, self._at = self.world.time - self._at, self.world.time
        if dt <= 0:
            return
        gap = self._goal - self._shaft
        step = self.units_per_s * dt
        self._shaft = float(self._goal) if abs(gap) <= step else self._shaft + math.copysign(step, gap)
