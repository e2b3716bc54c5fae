import time

import pytest

from botstage.robots.clock import SimClock, WallClock


def test_sim_clock_moves_only_when_stepped() -> None:
    clock = SimClock(rate_hz=20)
    assert clock.now() == 0.0
    assert clock.now() == 0.0
    for _ in range(3):
        clock.next_tick()
    assert clock.ticks == 3
    assert clock.now() == pytest.approx(0.15)


def test_sim_clock_has_no_drift_over_long_runs() -> None:
    clock = SimClock(rate_hz=10)
    for _ in range(1_000_000):
        clock.next_tick()
    # computed as ticks * period, not accumulated: exactly 100000 s
    assert clock.now() == 100_000.0


def test_sim_clock_never_sleeps(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_sleep(_: float) -> None:
        raise AssertionError("SimClock slept")

    monkeypatch.setattr(time, "sleep", no_sleep)
    clock = SimClock(rate_hz=1)
    for _ in range(100):
        clock.next_tick()
    assert clock.now() == 100.0


@pytest.mark.parametrize("rate", [0, -5])
def test_clocks_reject_bad_rates(rate: float) -> None:
    with pytest.raises(ValueError, match="positive"):
        SimClock(rate)
    with pytest.raises(ValueError, match="positive"):
        WallClock(rate)


class FakeTime:
    """Monotonic time that moves only when the clock sleeps or the test says work took time."""

    def __init__(self) -> None:
        self.t = 100.0
        self.slept: list[float] = []

    def monotonic(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.t += seconds


def test_wall_clock_paces_to_the_rate() -> None:
    fake = FakeTime()
    clock = WallClock(10, monotonic=fake.monotonic, sleep=fake.sleep)
    fake.t += 0.03  # the tick's work took 30 ms
    clock.next_tick()
    assert fake.slept[-1] == pytest.approx(0.07)
    fake.t += 0.01
    clock.next_tick()
    assert fake.slept[-1] == pytest.approx(0.09)
    assert clock.now() == pytest.approx(0.2)
    assert clock.overruns.count == 0


def test_wall_clock_reports_overruns_and_does_not_burst() -> None:
    fake = FakeTime()
    clock = WallClock(10, monotonic=fake.monotonic, sleep=fake.sleep)
    fake.t += 0.25  # a tick that took 250 ms: 150 ms late
    clock.next_tick()
    assert clock.overruns.count == 1
    assert clock.overruns.last_s == pytest.approx(0.15)
    assert clock.overruns.history == [(1, pytest.approx(0.15))]
    # the schedule restarts from now: the next tick gets a full period, not a catch-up burst
    fake.t += 0.01
    clock.next_tick()
    assert fake.slept[-1] == pytest.approx(0.09)
    assert clock.overruns.count == 1


def test_a_held_wall_clock_does_not_count_the_hold_as_mission_time() -> None:
    """A simulation paced in real time, paused from the monitor: held time is not mission time,
    and the tick after the release is neither late nor a catch-up burst."""
    fake = FakeTime()
    clock = WallClock(10, monotonic=fake.monotonic, sleep=fake.sleep)
    fake.t += 0.02
    clock.hold()
    fake.t += 5.0  # five seconds paused
    assert clock.now() == pytest.approx(0.02)
    clock.hold()  # holding twice is one hold
    clock.release()
    assert clock.now() == pytest.approx(0.02)
    clock.next_tick()
    assert fake.slept[-1] == pytest.approx(0.08) and clock.overruns.count == 0
    assert clock.now() == pytest.approx(0.1)
    clock.release()  # releasing a clock not held changes nothing
    assert clock.now() == pytest.approx(0.1)
