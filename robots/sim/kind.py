"""The simulator as a registered backend kind: what ``--backend sim`` (the default) opens."""

from __future__ import annotations

from botstage.robots.backend import Backend, BackendKind, BackendOptions, OpenRequest


class SimKind(BackendKind):
    name = "sim"
    description = "the built-in simulator: a 2-D world with people and voices, faster than real time"
    simulated = True

    class Options(BackendOptions):
        """The simulator takes its settings from the mission (world, people, gatherings, walks, voices)."""

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from botstage.robots.sim.backend import SimBackend

        if request.grid is None:
            raise ValueError("the simulator needs a map to put the robot on")
        return SimBackend(
            request.profile,
            request.grid,
            request.start,
            request.seed,
            request.clock,
            people=request.people,
            gatherings=list(request.gatherings),
            voices=dict(request.voices) if request.voices is not None else None,
            walks=list(request.walks),
        )
