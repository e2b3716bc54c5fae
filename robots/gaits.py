"""A legged robot's gaits: which one a velocity command asks for, and how fast the body goes in it.

Bittle's firmware (OpenCat) walks in whole gaits, not at any speed: the host sends a skill name
(``kwkF``) and the board loops that gait until told otherwise. The Bittle article's driver maps
``cmd_vel`` to a direction class, *linear first* (x > 0 forward, x < 0 back, else z > 0 turn
left, z < 0 turn right, else balance), and sends a token only when the class changes. Beyond the
article, decided here:

- the forward gait is chosen from |v|: the profile's forward gaits (crawl, walk, trot) with the
  speed each makes, and the one whose speed is nearest |v| wins (the slower one on a tie);
- a command component under the profile's dead band counts as zero (a controller's 1 mm/s of
  noise should not set the robot walking);
- a turn is the turning gait's left (``…L``) variant for z > 0 and its right one (``…R``, which
  OpenCat 2 mirrors from the left) for z < 0: counter-clockwise is left in ROS (REP 103). The
  article's repository sends ``kcrR`` for z > 0 (both turns inverted) and ``kwk`` for forward,
  which OpenCat 2's name matching resolves to ``wkL`` (walk left) and OpenCat 1 refuses;
- the body's speed in each gait is a profile table (no source gives Bittle's speeds), so
  odometry can be estimated from the gaits the robot was in and for how long.

Nothing here knows about serial ports or the simulator: the driver, the emulator and the
simulated drive all choose with ``choose``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from botstage.robots.interfaces import Pose2D, Twist2D

SKILL_NAME = r"^[A-Za-z][A-Za-z0-9]{0,15}$"  # OpenCat's skill names: letters and digits


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class GaitSpec(_Strict):
    """One gait: the firmware's skill name and what the body does in it on a flat floor."""

    skill: str = Field(pattern=SKILL_NAME, description="the OpenCat skill, sent as k<skill>")
    speed: float = Field(ge=0, description="m/s, forward (backward for the back gait)")
    turn_rate: float = Field(default=0.0, ge=0, description="rad/s, for a turning gait")


class Gaits(_Strict):
    """A legged base's gait table (profile ``gaits:``)."""

    forward: list[GaitSpec] = Field(min_length=1, description="straight gaits, chosen by the speed asked")
    back: GaitSpec
    turn: GaitSpec = Field(description="the left-turning gait (its skill ends in L); right is its mirror, …R")
    stop: str = Field(default="balance", pattern=SKILL_NAME, description="the posture standing still")
    rest: str = Field(default="rest", pattern=SKILL_NAME, description="the posture at the end (servos off)")
    deadband_linear: float = Field(default=0.01, ge=0, description="m/s under which v counts as 0")
    deadband_angular: float = Field(default=0.05, ge=0, description="rad/s under which w counts as 0")

    @model_validator(mode="after")
    def _left_turn(self) -> Gaits:
        if not self.turn.skill.endswith("L"):
            raise ValueError(f"the turning gait is its left variant (ending in L), got {self.turn.skill!r}")
        if self.turn.turn_rate <= 0:
            raise ValueError("the turning gait needs a turn_rate above 0")
        return self

    @property
    def fastest(self) -> float:
        return max(g.speed for g in self.forward)


class Direction(enum.Enum):
    """The article's direction classes."""

    FORWARD = 1
    BACK = -1
    LEFT = 2
    RIGHT = 3
    STOP = 0


@dataclass(frozen=True, slots=True)
class GaitChoice:
    """What to send (``skill``) and what the body then does (``v`` m/s, ``w`` rad/s)."""

    skill: str
    v: float
    w: float
    direction: Direction


def choose(gaits: Gaits, v: float, w: float) -> GaitChoice:
    """The gait for a velocity command (see the module: linear first, forward gait by |v|)."""
    if abs(v) < gaits.deadband_linear:
        v = 0.0
    if abs(w) < gaits.deadband_angular:
        w = 0.0
    if v > 0:
        best = min(gaits.forward, key=lambda g: (abs(g.speed - v), g.speed))
        return GaitChoice(best.skill, best.speed, 0.0, Direction.FORWARD)
    if v < 0:
        return GaitChoice(gaits.back.skill, -gaits.back.speed, 0.0, Direction.BACK)
    turn = gaits.turn
    if w > 0:
        return GaitChoice(turn.skill, turn.speed, turn.turn_rate, Direction.LEFT)
    if w < 0:
        return GaitChoice(turn.skill[:-1] + "R", turn.speed, -turn.turn_rate, Direction.RIGHT)
    return GaitChoice(gaits.stop, 0.0, 0.0, Direction.STOP)


def motion_of(gaits: Gaits, skill: str) -> tuple[float, float]:
    """What the body does in ``skill`` (a gait of the table, or a posture: standing still)."""
    for gait in gaits.forward:
        if gait.skill == skill:
            return gait.speed, 0.0
    if skill == gaits.back.skill:
        return -gaits.back.speed, 0.0
    turn = gaits.turn
    if skill == turn.skill:
        return turn.speed, turn.turn_rate
    if skill == turn.skill[:-1] + "R":
        return turn.speed, -turn.turn_rate
    return 0.0, 0.0


class GaitOdometry:
    """Dead reckoning from the gaits the robot was in and for how long (a legged robot has no encoders).

    ``advance(dt, v, w)`` moves the estimate along the arc a gait of (v, w) makes in dt seconds.
    The speeds are the profile's table, not measured, and a walking robot veers: the covariance
    is propagated through each arc (its Jacobian) with, as standard deviations, 20 % of the
    distance along the way and 5 % across it (feet slide), 20 % of the turn, and 0.18 rad per
    square root of a metre walked in heading (decision: a gait's speed changes with the floor and
    the battery by about that much, and a legged robot's heading wanders by about 10 degrees over
    its first metre, more than the simulated Bittle's, which slips 5 % a step on each side).
    """

    SPEED_SHARE = 0.2
    SIDE_SHARE = 0.05
    TURN_SHARE = 0.2
    HEADING_PER_ROOT_METRE = 0.18

    def __init__(self, start: Pose2D | None = None) -> None:
        start = start or Pose2D(0.0, 0.0, 0.0)
        self.x, self.y, self.theta = start.x, start.y, start.theta
        self.v = self.w = 0.0
        self.covariance = np.zeros((3, 3))
        self.distance = 0.0

    def advance(self, dt: float, v: float, w: float) -> None:
        self.v, self.w = v, w
        if dt <= 0:
            return
        distance, d_theta = v * dt, w * dt
        middle = self.theta + d_theta / 2
        # the straight line from the arc's start to its end
        chord = distance if abs(d_theta) < 1e-9 else 2 * distance / d_theta * math.sin(d_theta / 2)
        c, s = math.cos(middle), math.sin(middle)
        self.x += chord * c
        self.y += chord * s
        self.theta = math.atan2(math.sin(self.theta + d_theta), math.cos(self.theta + d_theta))
        jacobian = np.array([[1.0, 0.0, -chord * s], [0.0, 1.0, chord * c], [0.0, 0.0, 1.0]])
        along, across = (self.SPEED_SHARE * distance) ** 2, (self.SIDE_SHARE * distance) ** 2
        heading = (self.TURN_SHARE * d_theta) ** 2 + self.HEADING_PER_ROOT_METRE**2 * abs(distance)
        rotation = np.array([[c, -s], [s, c]])
        noise = np.zeros((3, 3))
        noise[:2, :2] = rotation @ np.diag([along, across]) @ rotation.T
        noise[2, 2] = heading
        self.covariance = jacobian @ self.covariance @ jacobian.T + noise
        self.distance += abs(distance)

    @property
    def pose(self) -> Pose2D:
        return Pose2D(self.x, self.y, self.theta)

    @property
    def twist(self) -> Twist2D:
        return Twist2D(self.v, self.w)
