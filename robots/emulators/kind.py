"""The emulated board as a registered backend kind: the real driver over a pty, the simulated robot behind.

For a robot whose only moving part is a Dynamixel pan (the face tracker) the board is its AX-12A
(robots/emulators/pan_head.py); for the others, the board that drives the base."""

from __future__ import annotations

from pydantic import Field

from botstage.robots.backend import Backend, BackendKind, BackendOptions, OpenRequest


class EmulatorOptions(BackendOptions):
    counter_start: int = Field(
        default=0, ge=0, lt=2**32, description="the encoders' first count (near 2147483647 to test wrap-around)"
    )
    loop_hz: float = Field(
        default=50.0, gt=0, description="the firmware loop's rate: encoder lines a second (the servo's motion steps)"
    )


class EmulatorKind(BackendKind):
    name = "emulator"
    description = "the simulated robot through its emulated board on a pty, in real time"
    simulated = False
    Options = EmulatorOptions

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from botstage.robots.drivers.pan_head import pan_only  # pyserial and ptys load only when used
        from botstage.robots.emulators.backend import EmulatorBackend

        assert isinstance(options, EmulatorOptions)
        if request.grid is None:
            raise ValueError("the emulator's simulated robot needs a map to stand on")
        if pan_only(request.profile):  # the face tracker: its AX-12A emulated, its camera simulated
            from botstage.robots.emulators.pan_head import PanHeadEmulatorBackend

            return PanHeadEmulatorBackend(
                request.profile,
                request.grid,
                request.start,
                request.seed,
                request.clock,
                people=request.people,
                gatherings=list(request.gatherings),
                walks=list(request.walks),
                counter_start=options.counter_start,
                loop_hz=options.loop_hz,
            )
        return EmulatorBackend(
            request.profile,
            request.grid,
            request.start,
            request.seed,
            request.clock,
            people=request.people,
            gatherings=list(request.gatherings),
            walks=list(request.walks),
            counter_start=options.counter_start,
            loop_hz=options.loop_hz,
        )
