import math

import numpy as np
import pytest

from botstage.robots.interfaces import (
    BatteryState,
    CameraInfo,
    LaserScan,
    OdometryReading,
    Pose2D,
    TrackedPerson,
    Twist2D,
    check_interfaces,
)


def test_laser_points_leave_out_misses_and_sit_in_the_sensor_frame() -> None:
    scan = LaserScan(0.0, -math.pi / 2, math.pi / 2, 0.1, 10.0, np.array([2.0, np.inf, 1.0, 0.05]))
    assert np.allclose(scan.angles, [-math.pi / 2, 0, math.pi / 2, math.pi])
    assert np.allclose(scan.points(), [[0.0, -2.0], [0.0, 1.0]], atol=1e-12)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Pose2D(0, float("nan"), 0), "a pose must be finite"),
        (lambda: Twist2D(float("inf"), 0), "a twist must be finite"),
        (lambda: LaserScan(0, 0, 0.1, 0, 5, np.array([])), "non-empty 1-D"),
        (lambda: LaserScan(0, 0, 0.1, 5, 1, np.ones(3)), "range_min < range_max"),
        (lambda: BatteryState(0, 12.0, 120), "within 0..100"),
        (lambda: OdometryReading(0, Pose2D(0, 0, 0), Twist2D(0, 0), np.zeros((2, 2))), "must be 3x3"),
        (lambda: TrackedPerson(1, 0.0, float("nan")), "must be finite"),
    ],
)
def test_readings_refuse_bad_values(make, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_camera_focal_length_from_field_of_view() -> None:
    assert CameraInfo(640, 480, math.radians(90)).focal_px == pytest.approx(320.0)


def test_backends_are_checked_against_the_protocols() -> None:
    class Motors:
        def cmd_vel(self, v: float, w: float) -> None: ...

        def stop(self) -> None: ...

    class Deaf:
        pass

    assert check_interfaces({"drive": Motors()}) == []
    assert check_interfaces({"microphone": Deaf(), "jetpack": Motors()}) == [
        "interface 'microphone': Deaf does not provide Microphone",
        "unknown interface 'jetpack' (known: drive, odometry, imu, laser, sonar, battery, people, camera, "
        "microphone, speaker, display, pan)",
    ]
