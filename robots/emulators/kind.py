"""The emulated board as a registered backend kind: the real driver over a pty, the simulated robot behind."""

from __future__ import annotations

from pydantic import Field

from robots.backend import Backend, BackendKind, BackendOptions, OpenRequest


class EmulatorOptions(BackendOptions):
    counter_start: int = Field(
        default=0, ge=0, lt=2**32, description="the encoders' first count (near 2147483647 to test wrap-around)"
    )
    loop_hz: float = Field(default=50.0, gt=0, description="the firmware loop's rate: encoder lines a second")


class EmulatorKind(BackendKind):
    name = "emulator"
    description = "the simulated robot through its emulated board on a pty, in real time"
    simulated = False
    Options = EmulatorOptions

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from robots.emulators.backend import EmulatorBackend  # pyserial and ptys load only when used

        assert isinstance(options, EmulatorOptions)
        if request.grid is None:
            raise ValueError("the emulator's simulated robot needs a map to stand on")
        return EmulatorBackend(
            request.profile,
            request.grid,
            request.start,
            request.seed,
            request.clock,
            people=request.people,
            gatherings=list(request.gatherings),
            counter_start=options.counter_start,
            loop_hz=options.loop_hz,
        )
