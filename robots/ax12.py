"""The AX-12A servo's units and the angle and speed conversions of the book's ``dynamixel_controllers``
(the e-manual; dynamixel_motor's ``dynamixel_const`` and serial proxy). One place for the driver
(robots/drivers/dynamixel_servo.py), its emulator and the simulator's pan joint, which must agree
to the unit; the protocol itself stays with the driver."""

from __future__ import annotations

import math

POSITION_MAX = 1023
POSITION_RESOLUTION = 1024  # dynamixel_const's encoder_resolution for the AX-12
RANGE_RAD = math.radians(300.0)
RAD_PER_UNIT = RANGE_RAD / POSITION_RESOLUTION  # about 0.00511 rad (0.29°)
RPM_PER_SPEED_UNIT = 0.111
RPM_TO_RAD_S = 2 * math.pi / 60
RAD_S_PER_SPEED_UNIT = RPM_PER_SPEED_UNIT * RPM_TO_RAD_S  # about 0.01162 rad/s
SPEED_MAX = 1023
DIRECTION_BIT = 0x400  # Present Speed / Present Load: set when turning (loaded) clockwise

# the book's pan.yaml
CENTRE = 512
LIMITS = (316, 708)
JOINT_SPEED = 1.17  # rad/s
BAUD = 1_000_000


def speed_to_raw(rad_s: float) -> int:
    """A joint speed (rad/s) to Moving Speed units, 1..1023: 0 would mean the motor's maximum."""
    if not (math.isfinite(rad_s) and rad_s > 0):
        raise ValueError(f"joint speed {rad_s} rad/s: a finite speed above 0")
    return max(1, min(SPEED_MAX, round(rad_s / RAD_S_PER_SPEED_UNIT)))


def angle_to_raw(angle: float, centre: int = CENTRE, flipped: bool = False) -> int:
    """Radians from the centre (counter-clockwise positive) to position units, not clamped."""
    ticks = angle / RAD_PER_UNIT
    return round(centre - ticks if flipped else centre + ticks)


def raw_to_angle(raw: float, centre: int = CENTRE, flipped: bool = False) -> float:
    """Position units to radians from the centre (counter-clockwise positive)."""
    return (centre - raw if flipped else raw - centre) * RAD_PER_UNIT
