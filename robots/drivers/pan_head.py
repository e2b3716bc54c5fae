"""The face tracker on real hardware: its AX-12A pan on a USB2Dynamixel, its webcam on the PC.

The book's chapter 2 runs ``dynamixel_controllers`` on ``/dev/ttyUSB0`` at 1 Mbps and ``usb_cam``
on ``/dev/video0``; here the same two devices are the ``DynamixelServo`` driver (the profile's
``pan`` with ``hardware: dynamixel``: its joint gives the ID, the centre, the limits and the
speed; the port and baud are the hardware backend's ``port`` and ``baud`` options, which the
profile sets) and OpenCV's ``VideoCapture`` (the camera with ``hardware: usb_cam``, opened from the
backend's ``camera`` option: a V4L device path or an index). Opening waits up to ``ready_timeout``
for the servo to answer a ping (the driver retries with backoff meanwhile) and fails naming the
port; closing holds the servo at its present position with torque on, then releases the camera.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from botstage.robots.ax12 import BAUD
from botstage.robots.backend import Fault
from botstage.robots.clock import Clock
from botstage.robots.drivers.dynamixel_servo import DynamixelError, DynamixelServo
from botstage.robots.gridmap import GridMap
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, ServoJoint

DYNAMIXEL = "dynamixel"  # a profile's pan on this hardware is a Dynamixel the SDK speaks to
USB_CAM = "usb_cam"  # a profile's camera on this hardware is a webcam OpenCV opens on the PC
RETRY_S = 0.1  # between attempts to reach the servo while opening


def pan_joint(profile: Profile) -> ServoJoint | None:
    """The profile's pan joint when a Dynamixel turns it, else None."""
    pan = profile.interfaces.get("pan")
    return pan.joint if pan is not None and pan.hardware == DYNAMIXEL else None


def pan_only(profile: Profile) -> bool:
    """True for a robot whose moving part is a Dynamixel pan and nothing drives (the face tracker)."""
    return pan_joint(profile) is not None and "drive" not in profile.interfaces


def servo_for(profile: Profile, port: str, baud: int = BAUD, **options: Any) -> DynamixelServo:
    """The driver for the profile's pan on ``port``, from its joint (ID, init, limits, speed)."""
    joint = pan_joint(profile)
    if joint is None:
        raise ValueError(f"robot {profile.name!r} has no pan on a Dynamixel servo")
    return DynamixelServo(
        port,
        dxl_id=joint.id,
        baud=baud,
        limits=(joint.min, joint.max),
        centre=joint.init,
        joint_speed=joint.joint_speed,
        name=joint.name,
        **options,
    )


def open_servo(servo: DynamixelServo, ready_timeout: float) -> None:
    """Reach the servo within ``ready_timeout`` s of wall time (opening, before any tick), or
    ``ConnectionError`` naming the port; another model on the ID is a ``ConnectionError`` too."""
    deadline = time.monotonic() + ready_timeout
    try:
        while not servo.open():
            if time.monotonic() >= deadline:
                stats = servo.stats()
                raise ConnectionError(
                    f"no AX-12A answers as ID {servo.dxl_id} on {servo.port} at {servo.baud} bps within "
                    f"{ready_timeout:g} s (open failures: {stats.get('open_failures', 0)}, "
                    f"unanswered pings: {stats.get('ping_failures', 0)}): is it powered, and set to that ID and baud?"
                )
            time.sleep(RETRY_S)
    except DynamixelError as exc:
        servo.close()
        raise ConnectionError(str(exc)) from None
    except BaseException:
        servo.close()
        raise


class PanHeadBackend:
    """The ``hardware`` backend for a robot whose only moving part is a Dynamixel pan (see the module)."""

    def __init__(
        self,
        profile: Profile,
        clock: Clock,
        port: str,
        start: Pose2D,
        *,
        grid: GridMap | None = None,
        ready_timeout: float = 5.0,
        baud: int = BAUD,
        camera: str | None = None,
        servo_options: Mapping[str, Any] | None = None,
    ) -> None:
        self.profile = profile
        self.grid = grid
        self.clock = clock
        self.start = start
        self.servo = servo_for(profile, port, baud, **dict(servo_options or {}))
        open_servo(self.servo, ready_timeout)
        self.devices: dict[str, Any] = {"pan": self.servo}
        self.camera: Any = None
        spec = profile.interfaces.get("camera")
        if spec is not None and spec.hardware == USB_CAM and camera is not None:
            from botstage.robots.drivers.video_camera import VideoCaptureCamera  # OpenCV loads only with a camera

            source: int | str = int(camera) if camera.isdigit() else camera
            try:
                self.camera = VideoCaptureCamera(
                    source, horizontal_fov=spec.field_of_view or 1.085, width=spec.width, height=spec.height
                )
            except BaseException:
                self.servo.close()
                raise
            self.devices["camera"] = self.camera
        self.not_connected = sorted(set(profile.interfaces) - set(self.devices))

    @property
    def faults(self) -> Mapping[str, Fault]:
        """None: faults are not injected into a real robot."""
        return MappingProxyType({})

    def true_pose(self) -> None:
        """A real robot's true pose is unknown (this one stands where it was put)."""
        return None

    def use_clock(self, clock: Clock) -> None:
        """Nothing here is stamped: the servo answers now, the camera keeps its latest frame."""
        self.clock = clock

    def step(self) -> None:
        """Nothing to move: the servo turns itself; frames arrive on the camera's thread."""

    def close(self) -> None:
        try:
            self.servo.close()  # held at its present position, torque on, then the port
        finally:
            if self.camera is not None:
                self.camera.close()

    def write_results(self, folder: Path) -> None:
        """No true path on a real robot."""

    def summary(self) -> dict[str, Any]:
        camera = self.camera
        return {
            "servo": self.servo.stats(),
            "held_on_close": self.servo.held_on_close,
            "camera": {"frames_read": camera.frames_read, "reopened": camera.reopened} if camera is not None else None,
            "not_connected": self.not_connected,
        }
