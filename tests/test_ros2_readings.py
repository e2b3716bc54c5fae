"""Interface readings through ROS 2's standard messages and their CDR bytes, and back."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from botstage.robots.interfaces import (
    BatteryState,
    ImuReading,
    LaserScan,
    OdometryReading,
    Pose2D,
    SonarReading,
    Twist2D,
)
from botstage.robots.ros2 import readings
from botstage.robots.ros2.readings import standard_types

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
angle = st.floats(min_value=-math.pi + 1e-9, max_value=math.pi - 1e-9)
stamp = st.floats(min_value=0, max_value=1e8, allow_nan=False)


def over_the_wire(message: object, name: str) -> object:
    """The message as another process gets it: serialised to CDR and read back."""
    store = standard_types()
    return store.deserialize_cdr(bytes(store.serialize_cdr(message, name)), name)


@given(v=finite, w=finite)
def test_twist_keeps_speed_and_turn_rate_on_the_rep_103_axes(v: float, w: float) -> None:
    message = over_the_wire(readings.twist_message(Twist2D(v, w)), "geometry_msgs/msg/Twist")
    assert (message.linear.x, message.linear.y, message.angular.z) == (v, 0.0, w)
    assert readings.twist_of(message) == Twist2D(v, w)


def test_a_twist_of_nan_is_refused_naming_the_fields() -> None:
    message = readings.twist_message(Twist2D(0.1, 0.0))
    message.angular.z = float("nan")
    with pytest.raises(ValueError, match=r"twist linear\.x and angular\.z must be finite"):
        readings.twist_of(message)


@given(x=finite, y=finite, theta=angle, t=stamp)
def test_odometry_round_trips_pose_twist_stamp_and_planar_covariance(
    x: float, y: float, theta: float, t: float
) -> None:
    covariance = np.array([[0.01, 0.002, 0.0], [0.002, 0.02, 0.001], [0.0, 0.001, 0.03]])
    reading = OdometryReading(t, Pose2D(x, y, theta), Twist2D(0.3, -0.2), covariance)
    message = over_the_wire(readings.odometry_message(reading), "nav_msgs/msg/Odometry")
    assert (message.header.frame_id, message.child_frame_id) == ("odom", "base_link")
    assert message.pose.covariance[35] == 0.03 and message.pose.covariance[1] == 0.002  # yaw-yaw, x-y
    back = readings.odometry_of(message)
    assert back.pose.x == x and back.pose.y == y and math.isclose(back.pose.theta, theta, abs_tol=1e-12)
    assert back.twist == reading.twist and np.array_equal(back.covariance, covariance)
    assert abs(back.stamp - t) <= 1e-9 * max(1.0, t)


def test_stamps_are_whole_nanoseconds_and_never_negative() -> None:
    time = readings.ros_time(12.3456789012)
    assert (time.sec, time.nanosec) == (12, 345678901)
    assert readings.ros_time(0.9999999999).sec == 1  # rounds up into the next second, not 1e9 ns
    with pytest.raises(ValueError, match="finite time at or after 0"):
        readings.ros_time(-1.0)


def test_imu_yaw_rate_and_acceleration_round_trip_and_a_missing_orientation_is_refused() -> None:
    reading = ImuReading(5.0, yaw=-2.5, angular_velocity=0.4, linear_acceleration=(0.1, -0.2))
    message = over_the_wire(readings.imu_message(reading), "sensor_msgs/msg/Imu")
    back = readings.imu_of(message)
    assert math.isclose(back.yaw, -2.5) and back.angular_velocity == 0.4 and back.linear_acceleration == (0.1, -0.2)
    message.orientation_covariance = np.array([-1.0, *[0.0] * 8])  # "no orientation estimate"
    with pytest.raises(ValueError, match="no orientation"):
        readings.imu_of(message)


def test_a_scan_keeps_its_geometry_and_misses_stay_infinite() -> None:
    ranges = np.array([1.5, np.inf, 0.25, 7.75])
    scan = LaserScan(
        3.0, angle_min=-math.pi / 2, angle_increment=math.pi / 3, range_min=0.1, range_max=8.0, ranges=ranges
    )
    message = over_the_wire(readings.scan_message(scan), "sensor_msgs/msg/LaserScan")
    assert math.isclose(message.angle_max, math.pi / 2, abs_tol=1e-6)
    back = readings.scan_of(message)
    assert np.array_equal(back.ranges, ranges)  # these values are exact in float32
    assert back.range_max == 8.0 and math.isclose(back.range_min, 0.1, rel_tol=1e-7)  # float32 fields
    assert math.isclose(back.angle_min, scan.angle_min, rel_tol=1e-7)


def test_a_scan_from_another_driver_maps_nan_and_beyond_max_to_no_return() -> None:
    scan = LaserScan(0.0, 0.0, 0.1, 0.1, 4.0, np.array([1.0, 2.0, 3.0]))
    message = readings.scan_message(scan)
    message.ranges = np.array([np.nan, 9.0, 2.0], dtype=np.float32)
    assert np.array_equal(readings.scan_of(message).ranges, [np.inf, np.inf, 2.0])


def test_sonar_nothing_in_range_is_plus_infinity_as_rep_117_says() -> None:
    reading = SonarReading(1.0, range=math.inf, field_of_view=0.5, max_range=4.0)
    message = over_the_wire(readings.range_message(reading), "sensor_msgs/msg/Range")
    assert message.radiation_type == 0 and message.range == math.inf
    assert readings.sonar_of(message) == reading
    message.range = 5.0
    assert readings.sonar_of(message).range == math.inf


def test_battery_percentage_is_a_fraction_and_discharging_current_is_negative_on_the_wire() -> None:
    reading = BatteryState(2.0, voltage=12.4, percent=80.0, current=1.5)
    message = over_the_wire(readings.battery_message(reading), "sensor_msgs/msg/BatteryState")
    assert math.isclose(message.percentage, 0.8, rel_tol=1e-7) and message.current == -1.5 and message.present
    assert message.power_supply_status == 2  # DISCHARGING
    back = readings.battery_of(message)  # float32 fields: the values to float32's precision
    assert math.isclose(back.percent, 80.0, rel_tol=1e-7) and math.isclose(back.voltage, 12.4, rel_tol=1e-7)
    assert back.current == 1.5 and back.stamp == 2.0


@pytest.mark.parametrize("shape", [(48, 64, 3), (48, 64)])
def test_frames_round_trip_as_bgr8_or_mono8(shape: tuple[int, ...]) -> None:
    frame = np.random.default_rng(1).integers(0, 256, size=shape, dtype=np.uint8)
    message = over_the_wire(readings.image_message(frame, 1.0), "sensor_msgs/msg/Image")
    assert message.encoding == ("bgr8" if len(shape) == 3 else "mono8")
    assert np.array_equal(readings.frame_of(message), frame)


def test_rgb8_and_padded_rows_from_other_cameras_are_read_as_bgr() -> None:
    bgr = np.random.default_rng(2).integers(0, 256, size=(4, 5, 3), dtype=np.uint8)
    padded = np.zeros((4, 5 * 3 + 1), dtype=np.uint8)
    padded[:, :15] = bgr[:, :, ::-1].reshape(4, 15)
    message = readings.image_message(bgr, 0.0)
    message.encoding, message.step, message.data = "rgb8", 16, padded.reshape(-1)
    assert np.array_equal(readings.frame_of(message), bgr)
    message.encoding = "yuv422"
    with pytest.raises(ValueError, match="encoding 'yuv422'"):
        readings.frame_of(message)
    message.encoding, message.data = "rgb8", np.zeros(10, dtype=np.uint8)
    with pytest.raises(ValueError, match="cannot hold 4 rows"):
        readings.frame_of(message)


def test_the_clock_message_carries_the_mission_time() -> None:
    message = over_the_wire(readings.clock_message(61.5), "rosgraph_msgs/msg/Clock")
    assert readings.seconds_of(message.clock) == 61.5
