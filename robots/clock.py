"""Mission clocks: the only source of time for skills and the engine.

Everything that needs time receives a clock, so the same code runs paced in real time on a robot
and faster than real time (deterministically) in simulation and tests.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable


@runtime_checkable
class Clock(Protocol):
    """What the engine and skills need from a clock."""

    @property
    def period(self) -> float:
        """Seconds between two ticks."""
        ...

    ticks: int
    """Ticks completed so far."""

    @property
    def simulated(self) -> bool:
        """True when time only moves when the runner steps it."""
        ...

    def now(self) -> float:
        """Seconds since the clock started."""
        ...

    def next_tick(self) -> None:
        """Move to the next tick: step simulated time, or wait for the next real deadline."""
        ...


def _check_rate(rate_hz: float) -> float:
    if not rate_hz > 0:
        raise ValueError(f"tick rate must be a positive number of Hz, got {rate_hz!r}")
    return 1.0 / rate_hz


class SimClock:
    """Simulated time: advances by one period per tick and never sleeps.

    The time is computed as ``ticks * period`` rather than accumulated, so it carries no
    floating-point drift and two runs print identical timestamps.
    """

    simulated = True

    def __init__(self, rate_hz: float = 10.0, start: float = 0.0) -> None:
        self._period = _check_rate(rate_hz)
        self._start = float(start)
        self.ticks = 0  # a plain attribute: read on every trace event; only next_tick() changes it

    @property
    def period(self) -> float:
        return self._period

    def now(self) -> float:
        return self._start + self.ticks * self._period

    def next_tick(self) -> None:
        self.ticks += 1

    def __repr__(self) -> str:
        return f"SimClock(t={self.now():.3f}s, period={self._period}s)"


@dataclass
class Overruns:
    """Ticks that finished after their deadline: how many, the worst and the latest lateness."""

    count: int = 0
    worst_s: float = 0.0
    last_s: float = 0.0
    history: list[tuple[int, float]] = field(default_factory=list)
    history_limit: int = 100

    def record(self, tick: int, late_s: float) -> None:
        self.count += 1
        self.last_s = late_s
        self.worst_s = max(self.worst_s, late_s)
        if len(self.history) < self.history_limit:
            self.history.append((tick, late_s))


class WallClock:
    """Real time, paced at a fixed rate.

    ``next_tick`` sleeps until the next deadline. A tick that ends after its deadline is an
    overrun: it is recorded and the schedule restarts from now instead of bursting to catch up
    (a robot must not run several control steps back to back to "make up" lost time).
    """

    simulated = False

    def __init__(
        self,
        rate_hz: float = 10.0,
        *,
        monotonic=time.monotonic,  # injectable so tests need not sleep
        sleep=time.sleep,
    ) -> None:
        self._period = _check_rate(rate_hz)
        self._monotonic = monotonic
        self._sleep = sleep
        self._origin = monotonic()
        self._deadline = self._origin + self._period
        self._held_at: float | None = None
        self.ticks = 0  # only next_tick() changes it
        self.overruns = Overruns()

    @property
    def period(self) -> float:
        return self._period

    def restart(self) -> None:
        """Mission time starts again from 0 now (a run made its clock before connecting to the
        robot; what was built on this clock keeps it). Only before the first tick."""
        if self.ticks:
            raise RuntimeError("a clock that has ticked cannot start again")
        self._origin = self._monotonic()
        self._deadline = self._origin + self._period
        self._held_at = None

    def now(self) -> float:
        at = self._held_at if self._held_at is not None else self._monotonic()
        return at - self._origin

    def hold(self) -> None:
        """Stop mission time (an operator paused a simulation paced in real time): what is held
        does not count, and the schedule goes on from the release as if no time had passed."""
        if self._held_at is None:
            self._held_at = self._monotonic()

    def release(self) -> None:
        if self._held_at is not None:
            held = self._monotonic() - self._held_at
            self._origin += held
            self._deadline += held
            self._held_at = None

    def next_tick(self) -> None:
        self.ticks += 1
        remaining = self._deadline - self._monotonic()
        if remaining >= 0:
            self._sleep(remaining)
            self._deadline += self._period
        else:
            self.overruns.record(self.ticks, -remaining)
            self._deadline = self._monotonic() + self._period

    def __repr__(self) -> str:
        return f"WallClock(t={self.now():.3f}s, period={self._period}s, overruns={self.overruns.count})"
