"""botstage's interface readings as ROS 2's standard messages, and back.

A robot process publishes what its devices read as the messages every ROS 2 tool knows
(REP 103 axes and units, REP 105 frames, REP 117 for out-of-range readings) and a mission
process reads them back into the same immutable readings the skills see locally, so a skill
cannot tell a remote laser from a local one. Conversions are exact where the message holds the
value (a double stays a double) and documented where it does not: LaserScan's and BatteryState's
fields are float32, BatteryState's percentage is a fraction and its current is negative when
discharging.

Messages are the classes of a rosbags type store; ``from_*`` functions refuse a message whose
values a reading cannot hold (NaN poses, a scan of no ranges) with a ValueError naming the field,
never a half-built reading.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from botstage.robots.interfaces import (
    BatteryState,
    ImuReading,
    LaserScan,
    OdometryReading,
    Pose2D,
    SonarReading,
    Twist2D,
)

ODOM_FRAME = "odom"  # REP 105
BASE_FRAME = "base_link"
# nav_msgs/Odometry's 6x6 covariances are (x, y, z, roll, pitch, yaw), row-major; a reading's
# 3x3 is (x, y, theta): these are its rows and columns in the 6x6.
_PLANAR = (0, 1, 5)


@cache
def standard_types() -> Any:
    """The ROS 2 Jazzy message definitions (rosbags' store; loaded once)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _type(name: str) -> Any:
    return standard_types().types[name]


# -- time and frames -----------------------------------------------------------------------------


def ros_time(seconds: float) -> Any:
    """builtin_interfaces/Time of a clock reading in seconds (nanoseconds rounded)."""
    if not math.isfinite(seconds) or seconds < 0:
        raise ValueError(f"a stamp must be a finite time at or after 0, got {seconds!r}")
    total = round(seconds * 1e9)
    return _type("builtin_interfaces/msg/Time")(sec=total // 1_000_000_000, nanosec=total % 1_000_000_000)


def seconds_of(stamp: Any) -> float:
    """Seconds of a builtin_interfaces/Time."""
    return stamp.sec + stamp.nanosec * 1e-9


def header(stamp: float, frame_id: str) -> Any:
    return _type("std_msgs/msg/Header")(stamp=ros_time(stamp), frame_id=frame_id)


def clock_message(seconds: float) -> Any:
    """rosgraph_msgs/Clock: what a process publishing the mission's time sends on /clock."""
    return _type("rosgraph_msgs/msg/Clock")(clock=ros_time(seconds))


def yaw_quaternion(yaw: float) -> Any:
    """geometry_msgs/Quaternion of a rotation about z."""
    return _type("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def yaw_of(q: Any) -> float:
    """The rotation about z of a quaternion (its tilt, if any, ignored: a planar robot)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return _type("geometry_msgs/msg/Vector3")(x=float(x), y=float(y), z=float(z))


def _finite(field: str, *values: float) -> None:
    for value in values:
        if not math.isfinite(value):
            raise ValueError(f"{field} must be finite, got {value!r}")


# -- drive -----------------------------------------------------------------------------------------


def twist_message(twist: Twist2D) -> Any:
    """geometry_msgs/Twist: forward speed on linear.x, turn rate on angular.z (REP 103)."""
    return _type("geometry_msgs/msg/Twist")(linear=_vector(twist.v), angular=_vector(z=twist.w))


def twist_of(message: Any) -> Twist2D:
    """The planar part of a Twist; the rest (sideways, vertical, roll, pitch) a base cannot do."""
    _finite("twist linear.x and angular.z", message.linear.x, message.angular.z)
    return Twist2D(float(message.linear.x), float(message.angular.z))


# -- odometry --------------------------------------------------------------------------------------


def odometry_message(reading: OdometryReading, frame_id: str = ODOM_FRAME, child: str = BASE_FRAME) -> Any:
    """nav_msgs/Odometry: the pose in ``frame_id``, the twist in ``child``, covariances placed."""
    pose_cov = np.zeros((6, 6))
    pose_cov[np.ix_(_PLANAR, _PLANAR)] = reading.covariance
    pose = reading.pose
    point = _type("geometry_msgs/msg/Point")(x=pose.x, y=pose.y, z=0.0)
    return _type("nav_msgs/msg/Odometry")(
        header=header(reading.stamp, frame_id),
        child_frame_id=child,
        pose=_type("geometry_msgs/msg/PoseWithCovariance")(
            pose=_type("geometry_msgs/msg/Pose")(position=point, orientation=yaw_quaternion(pose.theta)),
            covariance=pose_cov.reshape(36),
        ),
        twist=_type("geometry_msgs/msg/TwistWithCovariance")(
            twist=twist_message(reading.twist), covariance=np.zeros(36)
        ),
    )


def odometry_of(message: Any) -> OdometryReading:
    position, orientation = message.pose.pose.position, message.pose.pose.orientation
    _finite("odometry position", position.x, position.y)
    _finite("odometry orientation", orientation.x, orientation.y, orientation.z, orientation.w)
    covariance = np.asarray(message.pose.covariance, dtype=float)
    if covariance.shape != (36,):
        raise ValueError(f"odometry pose covariance must have 36 values, got {covariance.size}")
    planar = covariance.reshape(6, 6)[np.ix_(_PLANAR, _PLANAR)].copy()
    return OdometryReading(
        stamp=seconds_of(message.header.stamp),
        pose=Pose2D(float(position.x), float(position.y), yaw_of(orientation)),
        twist=twist_of(message.twist.twist),
        covariance=planar,
    )


# -- IMU -------------------------------------------------------------------------------------------


def imu_message(reading: ImuReading, frame_id: str = "imu_link") -> Any:
    """sensor_msgs/Imu; covariances all zero: unknown (the message's convention)."""
    ax, ay = reading.linear_acceleration
    return _type("sensor_msgs/msg/Imu")(
        header=header(reading.stamp, frame_id),
        orientation=yaw_quaternion(reading.yaw),
        orientation_covariance=np.zeros(9),
        angular_velocity=_vector(z=reading.angular_velocity),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=_vector(ax, ay),
        linear_acceleration_covariance=np.zeros(9),
    )


def imu_of(message: Any) -> ImuReading:
    if message.orientation_covariance[0] == -1:
        raise ValueError("the IMU message has no orientation (orientation_covariance[0] is -1)")
    q, w, a = message.orientation, message.angular_velocity, message.linear_acceleration
    _finite("IMU orientation", q.x, q.y, q.z, q.w)
    _finite("IMU angular_velocity.z and linear_acceleration", w.z, a.x, a.y)
    return ImuReading(
        stamp=seconds_of(message.header.stamp),
        yaw=yaw_of(q),
        angular_velocity=float(w.z),
        linear_acceleration=(float(a.x), float(a.y)),
    )


# -- laser and sonar -------------------------------------------------------------------------------


def scan_message(scan: LaserScan, frame_id: str = "laser") -> Any:
    """sensor_msgs/LaserScan; ranges as float32, +inf where nothing was hit (REP 117)."""
    ranges = np.asarray(scan.ranges, dtype=np.float32)
    return _type("sensor_msgs/msg/LaserScan")(
        header=header(scan.stamp, frame_id),
        angle_min=float(scan.angle_min),
        angle_max=float(scan.angle_min + scan.angle_increment * (len(ranges) - 1)),
        angle_increment=float(scan.angle_increment),
        time_increment=0.0,
        scan_time=0.0,
        range_min=float(scan.range_min),
        range_max=float(scan.range_max),
        ranges=ranges,
        intensities=np.zeros(0, dtype=np.float32),
    )


def scan_of(message: Any) -> LaserScan:
    """A LaserScan reading; a range beyond range_max or NaN (some drivers' "no return") is +inf."""
    ranges = np.asarray(message.ranges, dtype=float)
    _finite("scan angle_min, angle_increment, range_min, range_max", message.angle_min, message.angle_increment)
    _finite("scan range_min and range_max", message.range_min, message.range_max)
    ranges = np.where(np.isnan(ranges) | (ranges > message.range_max), np.inf, ranges)
    return LaserScan(
        stamp=seconds_of(message.header.stamp),
        angle_min=float(message.angle_min),
        angle_increment=float(message.angle_increment),
        range_min=float(message.range_min),
        range_max=float(message.range_max),
        ranges=ranges,
    )


def range_message(reading: SonarReading, frame_id: str = "sonar") -> Any:
    """sensor_msgs/Range (ultrasound); +inf when nothing is within max_range (REP 117)."""
    kind = _type("sensor_msgs/msg/Range")
    return kind(
        header=header(reading.stamp, frame_id),
        radiation_type=kind.ULTRASOUND,
        field_of_view=float(reading.field_of_view),
        min_range=0.0,
        max_range=float(reading.max_range),
        range=float(reading.range),
        variance=0.0,
    )


def sonar_of(message: Any) -> SonarReading:
    _finite("range field_of_view and max_range", message.field_of_view, message.max_range)
    distance = float(message.range)
    if math.isnan(distance) or distance > message.max_range:
        distance = math.inf
    return SonarReading(
        stamp=seconds_of(message.header.stamp),
        range=distance,
        field_of_view=float(message.field_of_view),
        max_range=float(message.max_range),
    )


# -- battery ---------------------------------------------------------------------------------------


def battery_message(reading: BatteryState, frame_id: str = "") -> Any:
    """sensor_msgs/BatteryState: percentage as 0..1 and current negative when discharging
    (the message's conventions; a reading's are 0..100 and positive)."""
    kind = _type("sensor_msgs/msg/BatteryState")
    status = kind.POWER_SUPPLY_STATUS_DISCHARGING if reading.current > 0 else kind.POWER_SUPPLY_STATUS_UNKNOWN
    nan = float("nan")  # the message's "not measured"
    return kind(
        header=header(reading.stamp, frame_id),
        voltage=float(reading.voltage),
        temperature=nan,
        current=-float(reading.current),
        charge=nan,
        capacity=nan,
        design_capacity=nan,
        percentage=float(reading.percent) / 100.0,
        power_supply_status=status,
        power_supply_health=kind.POWER_SUPPLY_HEALTH_UNKNOWN,
        power_supply_technology=kind.POWER_SUPPLY_TECHNOLOGY_UNKNOWN,
        present=True,
        cell_voltage=np.zeros(0, dtype=np.float32),
        cell_temperature=np.zeros(0, dtype=np.float32),
        location="",
        serial_number="",
    )


def battery_of(message: Any) -> BatteryState:
    _finite("battery voltage and percentage", message.voltage, message.percentage)
    current = 0.0 if math.isnan(message.current) else -float(message.current)
    return BatteryState(
        stamp=seconds_of(message.header.stamp),
        voltage=float(message.voltage),
        percent=float(message.percentage) * 100.0,
        current=current,
    )


# -- a pan joint -----------------------------------------------------------------------------------


def command_message(value: float) -> Any:
    """std_msgs/Float64: a joint's goal angle in rad (the book's ``pan_controller/command``)."""
    _finite("a joint command", value)
    return _type("std_msgs/msg/Float64")(data=float(value))


def command_of(message: Any) -> float:
    _finite("a joint command's data", message.data)
    return float(message.data)


def joint_state_message(name: str, position: float, stamp: float) -> Any:
    """sensor_msgs/JointState of one joint's position (rad); velocity and effort left empty, as a
    position-only joint_state_broadcaster leaves them."""
    _finite("a joint position", position)
    return _type("sensor_msgs/msg/JointState")(
        header=header(stamp, ""),
        name=[name],
        position=np.array([float(position)], dtype=np.float64),
        velocity=np.zeros(0, dtype=np.float64),
        effort=np.zeros(0, dtype=np.float64),
    )


def joint_position_of(message: Any, name: str) -> float:
    """The position of joint ``name`` in a JointState (which may list other joints too)."""
    names = list(message.name)
    if name not in names:
        raise ValueError(f"joint state without {name!r} (joints: {', '.join(names) or 'none'})")
    index = names.index(name)
    if index >= len(message.position):
        raise ValueError(f"joint state names {name!r} but gives no position for it")
    position = float(message.position[index])
    _finite(f"joint {name!r}'s position", position)
    return position


# -- camera ----------------------------------------------------------------------------------------


def image_message(frame: np.ndarray, stamp: float, frame_id: str = "camera") -> Any:
    """sensor_msgs/Image of a BGR frame (OpenCV's order: encoding ``bgr8``) or a grey one (``mono8``)."""
    if frame.dtype != np.uint8 or frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] != 3):
        raise ValueError(f"an image is an HxW or HxWx3 array of uint8, got {frame.dtype} {frame.shape}")
    height, width = frame.shape[:2]
    channels = 1 if frame.ndim == 2 else 3
    return _type("sensor_msgs/msg/Image")(
        header=header(stamp, frame_id),
        height=height,
        width=width,
        encoding="mono8" if channels == 1 else "bgr8",
        is_bigendian=0,
        step=width * channels,
        data=np.ascontiguousarray(frame).reshape(-1),
    )


_CHANNELS = {"bgr8": 3, "rgb8": 3, "mono8": 1}


def frame_of(message: Any) -> np.ndarray:
    """The BGR (or grey) frame of an Image; ``rgb8`` is turned to BGR; rows may be padded (``step``)."""
    channels = _CHANNELS.get(message.encoding)
    if channels is None:
        raise ValueError(f"image encoding {message.encoding!r} is not one of {', '.join(_CHANNELS)}")
    height, width, step = int(message.height), int(message.width), int(message.step)
    data = np.asarray(message.data, dtype=np.uint8)
    if step < width * channels or data.size < step * height:
        raise ValueError(f"image data of {data.size} bytes cannot hold {height} rows of step {step}")
    rows = data[: step * height].reshape(height, step)[:, : width * channels]
    frame = rows.reshape(height, width, channels) if channels == 3 else rows.reshape(height, width)
    if message.encoding == "rgb8":
        frame = frame[:, :, ::-1]
    return np.ascontiguousarray(frame)
