"""Robot profiles (`robots/profiles/*.yaml`): what a robot is, checked with located errors.

A profile gives the base's geometry and limits, the battery, which interfaces the robot has
(and which hardware driver provides each; the simulator provides them all), each device's
parameters (a pan's servo ``joint:``; ``mounted_on: pan`` for a camera that turns with it),
default parameters for skills, options per backend (``backends:``, checked against that
backend's options when a run opens it, errors at their line), and the robot's ROS 2 topics
(``ros2:``: names and publish rates by channel, robots/ros2/topics.py). Limits written here are
enforced by the backends, never trusted to callers.

A base is ``differential`` (wheels), ``legged`` (gaits) or ``fixed`` (it stands where it is put,
as the face tracker on its desk: no wheels, speeds of 0, no drive or odometry interface). A
moving base runs on its ``battery:``; a fixed one may run on mains power and give none.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from botstage.robots import PROFILES_DIR
from botstage.robots.gaits import Gaits
from botstage.robots.interfaces import INTERFACES
from botstage.robots.located_yaml import Loaded, Problem, find_yaml, load_document

MOTION_LIMITS = ("max_linear_accel", "max_angular_accel", "max_linear_decel")  # what a fixed base may not give
LEGGED_STAND_IN = (0.05, 1000)  # a legged base's wheel diameter (m) and ticks per turn, in the simulator only


class _Strict(BaseModel):
    """Unknown keys are errors, and so are NaN and infinities (a NaN limit turns its check off)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Base(_Strict):
    """The base. A ``legged`` one (Bittle) walks in gaits (profile ``gaits:``); the simulator moves it
    like a differential base whose wheels are its feet's track (``wheel_separation``), so it has no
    wheel size, RPM or encoders to give: stand-ins fill them (``LEGGED_STAND_IN``).

    A ``fixed`` base does not move (the face tracker's desk): a footprint and a mass, nothing that
    drives. Its top speeds are 0, it has no wheels or track, and the simulator leaves its body where
    it stands. A separate kind, rather than a differential base nobody drives, so that a profile
    cannot list a drive for it and no backend invents one (``load_profile`` refuses both)."""

    kind: Literal["differential", "legged", "fixed"] = "differential"
    footprint_radius: float = Field(gt=0, description="m; a circle holding the whole robot")
    wheel_diameter: float | None = Field(default=None, gt=0, description="m")
    wheel_separation: float | None = Field(
        default=None, gt=0, description="m, between the wheels' contact points (a legged base's track)"
    )
    max_wheel_rpm: float | None = Field(default=None, gt=0)
    max_linear: float = Field(default=0.0, ge=0, description="m/s (above 0 but for a fixed base)")
    max_angular: float = Field(default=0.0, ge=0, description="rad/s (above 0 but for a fixed base)")
    max_linear_accel: float = Field(default=0.5, gt=0, description="m/s²")
    max_angular_accel: float = Field(default=2.0, gt=0, description="rad/s²")
    max_linear_decel: float | None = Field(
        default=None, gt=0, description="m/s² when slowing down (motor braking); default: max_linear_accel"
    )
    encoder_ticks_per_rev: int | None = Field(default=None, gt=0, description="encoder counts per wheel revolution")
    mass: float = Field(gt=0, description="kg, without payload")
    payload: float = Field(default=0.0, ge=0, description="kg, the most it carries")

    @model_validator(mode="after")
    def _wheels(self) -> Base:
        wheels = ("wheel_diameter", "max_wheel_rpm", "encoder_ticks_per_rev")
        if self.kind == "fixed":
            motion = (*wheels, "wheel_separation", "max_linear", "max_angular", *MOTION_LIMITS)
            given = [name for name in motion if name in self.model_fields_set]
            if given:
                raise ValueError(f"a fixed base does not move: remove {', '.join(given)}")
            return self
        moving = [name for name in ("wheel_separation", "max_linear", "max_angular") if not getattr(self, name)]
        if moving:
            raise ValueError(f"a {self.kind} base needs {', '.join(moving)} (above 0)")
        if self.kind == "differential":
            missing = [name for name in wheels if getattr(self, name) is None]
            if missing:
                raise ValueError(f"a differential base needs {', '.join(missing)}")
        else:
            given = [name for name in wheels if getattr(self, name) is not None]
            if given:
                raise ValueError(f"a legged base has no wheels: remove {', '.join(given)}")
            assert self.wheel_separation is not None
            diameter, ticks = LEGGED_STAND_IN
            top = self.max_linear + self.max_angular * self.wheel_separation / 2
            self.wheel_diameter, self.encoder_ticks_per_rev = diameter, ticks
            self.max_wheel_rpm = top * 60 / (math.pi * diameter)
        return self

    @property
    def moves(self) -> bool:
        """False for a fixed base: nothing drives it, the simulator leaves it where it stands."""
        return self.kind != "fixed"

    @property
    def braking(self) -> float:
        return self.max_linear_decel or self.max_linear_accel

    @property
    def ticks_per_metre(self) -> float:
        assert self.encoder_ticks_per_rev is not None and self.wheel_diameter is not None
        return self.encoder_ticks_per_rev / (math.pi * self.wheel_diameter)

    @property
    def wheel_top_speed(self) -> float:
        assert self.max_wheel_rpm is not None and self.wheel_diameter is not None
        return self.max_wheel_rpm * math.pi * self.wheel_diameter / 60


class BatterySpec(_Strict):
    nominal_voltage: float = Field(gt=0)
    capacity_ah: float = Field(gt=0)
    full_voltage: float = Field(gt=0)
    empty_voltage: float = Field(gt=0)
    idle_current: float = Field(default=0.5, ge=0, description="A drawn standing still")
    drive_current: float = Field(default=2.0, ge=0, description="A drawn at full speed")


class ServoJoint(_Strict):
    """A joint a position servo turns, in the book's ``pan.yaml`` terms (dynamixel_controllers'
    JointPositionController): the joint's name and speed, and the motor's ID and its initial,
    minimum and maximum positions in the servo's own units (0-1023 on an AX-12A). ``min`` above
    ``max`` is dynamixel_controllers' "flipped" joint (positive angles turn the other way)."""

    name: str = Field(default="pan_joint", min_length=1, description="the joint's name (ROS joint_states)")
    id: int = Field(ge=0, le=253, description="the servo's ID on its bus (254 is the broadcast ID)")
    init: int = Field(ge=0, le=1023, description="position units: the joint's zero angle")
    min: int = Field(ge=0, le=1023, description="position units: one limit")
    max: int = Field(ge=0, le=1023, description="position units: the other limit")
    joint_speed: float = Field(gt=0, le=12.0, description="rad/s the joint turns at")

    @model_validator(mode="after")
    def _limits(self) -> ServoJoint:
        low, high = sorted((self.min, self.max))
        if low == high:
            raise ValueError("min and max must differ: the joint would not turn")
        if not low <= self.init <= high:
            raise ValueError(f"init {self.init} must lie between min and max ({low}-{high})")
        return self


class Device(_Strict):
    """An interface's device. `hardware` names the driver that provides it on a real robot."""

    hardware: str | None = None
    model: str = ""
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y, theta on the base
    rate_hz: float | None = Field(default=None, gt=0)
    range_min: float | None = Field(default=None, ge=0)
    range_max: float | None = Field(default=None, gt=0)
    field_of_view: float | None = Field(default=None, gt=0, le=2 * math.pi, description="rad")
    beams: int | None = Field(default=None, ge=1)
    width: int | None = Field(default=None, ge=1)
    height: int | None = Field(default=None, ge=1)
    noise: float | None = Field(default=None, ge=0, description="std of the measurement noise")
    mount_height: float | None = Field(default=None, gt=0, description="m above the floor (a camera)")
    look_up: float | None = Field(
        default=None,
        ge=0,
        lt=1.2,
        description="rad a camera's view is raised by (a lens shift: the horizon sits below the image centre)",
    )
    mounted_on: Literal["pan"] | None = Field(
        default=None, description="the joint the device rides on (a camera on the pan turns with it); None: the base"
    )
    joint: ServoJoint | None = Field(default=None, description="the servo joint of a pan")


class WheelPid(_Strict):
    """The serial drivers' wheel velocity loop (the book's pid_velocity.py): a motor output
    (PWM, -255..255) per wheel from its target and measured speed. Tunable per robot."""

    kp: float = Field(default=400.0, ge=0, description="PWM per m/s of speed error")
    ki: float = Field(default=4000.0, ge=0, description="PWM per m of accumulated speed error")
    kd: float = Field(default=0.0, ge=0, description="PWM per m/s² of change in the error")
    kf: float | None = Field(
        default=None, ge=0, description="feedforward PWM per m/s of target; default: full output at the top speed"
    )
    integral_zone: float = Field(
        default=0.05, gt=0, description="m/s: the integral accumulates only while the error is smaller"
    )
    output_limit: float = Field(default=255.0, gt=0, le=255, description="the largest motor output sent")
    smoothing: int = Field(default=2, ge=1, le=20, description="encoder speed samples averaged (rolling_pts)")


class Control(_Strict):
    """How a hardware driver drives the base; optional in a profile (these are the defaults)."""

    pid: WheelPid = Field(default_factory=WheelPid)
    watchdog_s: float = Field(default=0.5, gt=0, description="s without a velocity command before the motors stop")


class Ros2Section(_Strict):
    """How the robot appears on a ROS 2 graph: topic names and publish rates by channel
    (robots/ros2/topics.py lists the channels and ROS's defaults: cmd_vel, odom, scan, ...). The
    ``ros2`` backend checks this section (``BackendKind.check_profile``), not the core."""

    topics: dict[str, str] = Field(default_factory=dict, description="topic name by channel, e.g. {laser: base_scan}")
    rates_hz: dict[str, Annotated[float, Field(gt=0)]] = Field(
        default_factory=dict, description="how often a robot process publishes a reading, by channel"
    )


class Profile(_Strict):
    name: str
    description: str = ""
    base: Base
    battery: BatterySpec | None = Field(
        default=None, description="a robot on batteries; none for one on mains power (only a fixed base may be)"
    )
    interfaces: dict[str, Device]
    skills: dict[str, dict[str, Any]] = Field(default_factory=dict, description="default skill parameters")
    control: Control = Field(default_factory=Control)
    backends: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="options per backend, e.g. {hardware: {port: /dev/ttyACM0}}; checked by the backend opened",
    )
    ros2: Ros2Section = Field(default_factory=Ros2Section)
    gaits: Gaits | None = Field(default=None, description="a legged base's gaits (robots/gaits.py)")


def _check_wheels(base: Base, at: Callable[[tuple[str | int, ...], str], None]) -> None:
    """A moving base's limits against what its wheels can do."""
    assert base.wheel_separation is not None
    if base.max_linear > base.wheel_top_speed + 1e-9:
        at(
            ("base", "max_linear"),
            f"{base.max_linear} m/s is faster than the wheels can turn: "
            f"{base.max_wheel_rpm:g} RPM on {base.wheel_diameter:g} m wheels give {base.wheel_top_speed:.3f} m/s",
        )
    wheel_turn = 2 * base.wheel_top_speed / base.wheel_separation
    if base.max_angular > wheel_turn + 1e-9:
        at(
            ("base", "max_angular"),
            f"{base.max_angular} rad/s is faster than the wheels allow ({wheel_turn:.2f} rad/s turning on the spot)",
        )


def _check_joints(
    name: str, device: Device, profile: Profile, at: Callable[[tuple[str | int, ...], str], None]
) -> None:
    """A pan has its servo joint; only a pan has one; a device rides on the pan only if there is one.
    Only cameras ride on it: the simulator turns a camera's view, not a laser's or a tracker's."""
    if name == "pan" and device.joint is None:
        at(("interfaces", name), "a pan needs its joint: {id, init, min, max, joint_speed} (the book's pan.yaml)")
    if name != "pan" and device.joint is not None:
        at(("interfaces", name, "joint"), "only a pan has a servo joint")
    if device.mounted_on is not None:
        if name != "camera":
            at(("interfaces", name, "mounted_on"), "only a camera rides on the pan")
        elif device.mounted_on not in profile.interfaces:
            at(
                ("interfaces", name, "mounted_on"),
                f"a camera mounted on the {device.mounted_on} needs a {device.mounted_on!r} interface",
            )


def known_profiles() -> list[str]:
    return sorted(p.stem for p in PROFILES_DIR.glob("*.yaml"))


def profile_path(name_or_path: str, relative_to: Path | None = None) -> Path | None:
    """The file of a profile named in a mission: a shipped profile's name, or a path to a YAML."""
    return find_yaml(name_or_path, PROFILES_DIR, known_profiles(), relative_to)


def load_profile(path: str | Path) -> tuple[Profile | None, list[Problem], Loaded]:
    loaded = load_document(path)
    problems = list(loaded.problems)
    if loaded.data is None:
        return None, problems, loaded

    def at(where: tuple[str | int, ...], message: str) -> None:
        problems.append(Problem(loaded.locations.find(where), message))

    try:
        profile = Profile.model_validate(loaded.data)
    except ValidationError as exc:
        for error in exc.errors():
            loc = tuple(error["loc"])
            if error["type"] == "extra_forbidden":
                at(loc, f"unknown key {loc[-1]!r}")
            else:
                at(loc, f"{'.'.join(map(str, loc))}: {error['msg'].removeprefix('Value error, ')}")
        return None, problems, loaded
    base = profile.base
    if base.moves:
        _check_wheels(base, at)
    else:
        for name in ("drive", "odometry"):
            if name in profile.interfaces:
                at(("interfaces", name), f"a fixed base does not move: it has no {name}")
    if base.kind == "legged" and profile.gaits is None:
        at(("base", "kind"), "a legged base needs gaits: (which skill walks how fast: robots/gaits.py)")
    if base.kind != "legged" and profile.gaits is not None:
        at(("gaits",), f"only a legged base walks in gaits; this one is {base.kind}")
    battery = profile.battery
    if battery is None:
        if base.moves:
            at(("base",), f"a {base.kind} base runs on batteries: give battery:")
        if "battery" in profile.interfaces:
            at(("interfaces", "battery"), "a battery interface needs the battery: it reports")
    elif battery.empty_voltage >= battery.full_voltage:
        at(("battery", "empty_voltage"), "must be below full_voltage")
    for name, device in profile.interfaces.items():
        if name not in INTERFACES:
            at(("interfaces", name), f"unknown interface {name!r} (known: {', '.join(INTERFACES)})")
        if device.range_min is not None and device.range_max is not None and device.range_min >= device.range_max:
            at(("interfaces", name, "range_min"), "must be below range_max")
        _check_joints(name, device, profile, at)
    if profile.name != Path(path).stem and Path(path).parent == PROFILES_DIR:
        at(("name",), f"a shipped profile's name is its file's name ({Path(path).stem!r})")
    return (profile if not problems else None), problems, loaded
