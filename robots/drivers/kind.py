"""Real hardware as a registered backend kind: the robot's drivers on its serial port."""

from __future__ import annotations

from pydantic import Field

from robots.backend import Backend, BackendKind, BackendOptions, OpenRequest
from robots.drivers.launchpad_protocol import BAUD


class HardwareOptions(BackendOptions):
    port: str = Field(description="the robot's serial port, e.g. /dev/ttyACM0")
    ready_timeout: float = Field(default=5.0, gt=0, description="seconds to wait for the board's first readings")
    baud: int = Field(default=BAUD, gt=0, description="the serial line's speed")


class HardwareKind(BackendKind):
    name = "hardware"
    description = "the real robot on its serial port, given with --port, in real time"
    simulated = False
    Options = HardwareOptions

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from robots.drivers.backend import SerialBackend  # pyserial loads only when used

        assert isinstance(options, HardwareOptions)
        return SerialBackend(
            request.profile,
            request.clock,
            options.port,
            request.start,
            grid=request.grid,
            ready_timeout=options.ready_timeout,
            baud=options.baud,
        )
