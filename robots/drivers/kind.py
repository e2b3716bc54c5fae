"""Real hardware as a registered backend kind: the robot's drivers on its serial port.

A robot whose only moving part is a Dynamixel pan (the face tracker) opens ``PanHeadBackend``
(robots/drivers/pan_head.py): its servo on ``port`` at ``baud``, its webcam from ``camera``;
every other robot the board that drives its base (``SerialBackend``)."""

from __future__ import annotations

from pydantic import Field

from botstage.robots.backend import Backend, BackendKind, BackendOptions, OpenRequest
from botstage.robots.drivers.launchpad_protocol import BAUD


class HardwareOptions(BackendOptions):
    port: str = Field(description="the robot's serial port, e.g. /dev/ttyACM0")
    ready_timeout: float = Field(default=5.0, gt=0, description="seconds to wait for the board's first readings")
    baud: int = Field(default=BAUD, gt=0, description="the serial line's speed")
    camera: str | None = Field(
        default=None, description="a webcam on the PC (usb_cam): a V4L device path or an index, e.g. /dev/video0"
    )


class HardwareKind(BackendKind):
    name = "hardware"
    description = "the real robot on its serial port, given with --port, in real time"
    simulated = False
    Options = HardwareOptions

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from botstage.robots.drivers.backend import SerialBackend  # pyserial loads only when used
        from botstage.robots.drivers.pan_head import PanHeadBackend, pan_only

        assert isinstance(options, HardwareOptions)
        if pan_only(request.profile):  # the face tracker: its servo on the port, its webcam on the PC
            return PanHeadBackend(
                request.profile,
                request.clock,
                options.port,
                request.start,
                grid=request.grid,
                ready_timeout=options.ready_timeout,
                baud=options.baud,
                camera=options.camera,
            )
        return SerialBackend(
            request.profile,
            request.clock,
            options.port,
            request.start,
            grid=request.grid,
            ready_timeout=options.ready_timeout,
            baud=options.baud,
        )
