"""The pan-servo driver (dynamixel-sdk, protocol 1.0) against the emulated AX-12A through a real pty.

Every wait is for a condition with a failsafe deadline; where motion is judged, the emulator runs
on a clock the test steps. The packet timeout is widened (``LATENCY_MS``) so a loaded machine does
not turn into timeouts the tests did not ask for; dropped replies cost one timeout each.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from botstage.robots.ax12 import RAD_PER_UNIT, RAD_S_PER_SPEED_UNIT, angle_to_raw, raw_to_angle, speed_to_raw
from botstage.robots.drivers.dynamixel_servo import (
    ADDR_CCW_LIMIT,
    ADDR_CW_LIMIT,
    ADDR_SPEED,
    ADDR_TORQUE_LIMIT,
    DynamixelError,
    DynamixelServo,
    WrongModelError,
    decode_error,
)
from botstage.robots.emulators.ax12 import Ax12Emulator
from tests.launchpad_helpers import wait_until

LATENCY_MS = 50.0  # the SDK's packet timeout becomes about 100 ms
BACKOFF = (0.01, 0.05)


def make_servo(path: str, **options: object) -> DynamixelServo:
    settings: dict[str, object] = {"latency_ms": LATENCY_MS, "backoff": BACKOFF} | options
    return DynamixelServo(path, **settings)  # type: ignore[arg-type]


class Clock:
    """The emulator's ``monotonic``: it stands still until the test moves it."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def step(emulator: Ax12Emulator, clock: Clock, dt: float = 0.1) -> None:
    """Move the emulator's clock by ``dt`` and wait for the loop pass that follows."""
    loops = emulator.loops
    clock.now += dt
    assert wait_until(lambda: emulator.loops > loops)


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[tuple[Ax12Emulator, DynamixelServo]]:
    with Ax12Emulator(link_dir=tmp_path) as emulator:
        servo = make_servo(emulator.path)
        assert servo.open()
        yield emulator, servo
        servo.close()


@pytest.fixture
def stepped(tmp_path: Path) -> Iterator[tuple[Ax12Emulator, DynamixelServo, Clock]]:
    clock = Clock()
    with Ax12Emulator(link_dir=tmp_path, monotonic=clock) as emulator:
        servo = make_servo(emulator.path)
        assert servo.open()
        yield emulator, servo, clock
        servo.close()


# -- units ------------------------------------------------------------------------------------


def test_the_chapters_numbers_in_servo_units() -> None:
    assert speed_to_raw(1.17) == 101  # RoboPlus' "Moving Speed: 100" in the chapter, within a unit
    assert math.isclose(101 * RAD_S_PER_SPEED_UNIT, 1.174, abs_tol=1e-3)
    assert speed_to_raw(0.001) == 1 and speed_to_raw(50.0) == 1023  # never 0: that is "flat out"
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            speed_to_raw(bad)
    assert math.isclose(RAD_PER_UNIT, math.radians(300) / 1024)
    assert angle_to_raw(0.0) == 512 and angle_to_raw(0.3) == 571 and angle_to_raw(-0.3) == 453
    assert raw_to_angle(708) == pytest.approx(1.0022, abs=1e-4)
    assert raw_to_angle(316) == pytest.approx(-1.0022, abs=1e-4)
    assert angle_to_raw(0.3, flipped=True) == 453  # dynamixel_controllers' flipped joint (min > max)
    servo = DynamixelServo("/nonexistent/ttyUSB0")  # nothing is opened before open()
    assert servo.min_angle == pytest.approx(-1.0022, abs=1e-4) and servo.max_angle == pytest.approx(1.0022, abs=1e-4)
    assert servo.goal_raw(0.5) == 610 and servo.goal_raw(2.0) == 708 and servo.goal_raw(-9.0) == 316
    flipped = DynamixelServo("/nonexistent/ttyUSB0", limits=(708, 316))
    assert flipped.goal_raw(0.3) == 453 and flipped.goal_raw(2.0) == 316
    assert decode_error(0x24) == {"overload", "overheating"}  # the e-manual's example: 0x24


def test_bad_configuration_is_refused() -> None:
    for options in [
        {"dxl_id": 254},
        {"baud": 12345},
        {"limits": (708, 708)},
        {"limits": (0, 1024)},
        {"centre": 800},
        {"joint_speed": 0.0},
        {"retries": 11},
        {"latency_ms": 0.0},
        {"backoff": (0.0, 1.0)},
    ]:
        with pytest.raises(ValueError):
            DynamixelServo("/nonexistent/ttyUSB0", **options)  # type: ignore[arg-type]


# -- the round trip -----------------------------------------------------------------------------


def test_open_sets_the_limits_and_speed_and_holds_where_the_servo_is(tmp_path: Path) -> None:
    with Ax12Emulator(link_dir=tmp_path, position=530) as emulator:
        servo = make_servo(emulator.path)
        assert not emulator.torque_enabled
        assert servo.open() and servo.connected
        assert emulator.word(ADDR_CW_LIMIT) == 316 and emulator.word(ADDR_CCW_LIMIT) == 708
        assert emulator.word(ADDR_SPEED) == 101
        assert emulator.torque_enabled and emulator.goal == 530 and emulator.position == 530  # held, not moved
        assert emulator.first_instructions == ["ping"]
        assert servo.counters["connects"] == 1 and servo.counters["limits_written"] == 1
        assert servo.open()  # already open
        servo.close()
        assert servo.closed and servo.held_on_close
        with pytest.raises(DynamixelError):
            servo.open()


def test_move_to_and_position_round_trip(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    assert servo.move_to(0.3)
    assert emulator.goal == 571
    assert wait_until(lambda: emulator.position == 571 and not emulator.moving)  # in real time, at 1.17 rad/s
    assert servo.position() == pytest.approx(59 * RAD_PER_UNIT)
    assert emulator.angle == pytest.approx(59 * RAD_PER_UNIT)  # counter-clockwise: positive on both sides
    state = servo.read_state()
    assert state is not None and not state.moving and state.speed == 0.0
    assert state.position == pytest.approx(0.3017, abs=1e-4) and state.voltage == 12.0 and state.temperature == 32
    assert state.error == frozenset()
    assert servo.move_to(-0.3) and emulator.goal == 453
    assert wait_until(lambda: emulator.position == 453 and not emulator.moving)
    assert servo.position() == pytest.approx(-59 * RAD_PER_UNIT)
    assert servo.counters["disconnects"] == 0 and emulator.counters["checksum_errors"] == 0


def test_speed_and_direction_on_the_emulators_clock(stepped: tuple[Ax12Emulator, DynamixelServo, Clock]) -> None:
    emulator, servo, clock = stepped
    assert servo.move_to(-0.3)
    step(emulator, clock)
    state = servo.read_state()
    assert state is not None and state.moving
    assert state.speed == pytest.approx(-101 * RAD_S_PER_SPEED_UNIT)  # clockwise at the joint speed
    assert emulator.position == 512 - 23  # 11.2 rpm for 0.1 s
    for _ in range(3):
        step(emulator, clock)
    assert emulator.position == 453 and servo.position() == pytest.approx(-0.3017, abs=1e-4)


def test_limits_are_enforced_in_the_driver(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    assert servo.move_to(2.0) and emulator.goal == 708
    assert servo.move_to(-5.0) and emulator.goal == 316
    assert servo.move_to(servo.max_angle) and emulator.goal == 708
    assert servo.counters["clamped"] == 2 and emulator.counters["angle_limit_errors"] == 0
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError):
            servo.move_to(bad)
    assert emulator.goal == 708


def test_status_errors_are_decoded_and_counted(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    emulator.overload(True)
    assert servo.position() == pytest.approx(0.0)  # answered, with the error bit
    assert servo.last_error == {"overload"} and servo.errors["overload"] == 1
    state = servo.read_state()
    assert state is not None and state.error == {"overload"} and state.load == pytest.approx(1.0)
    assert emulator.word(ADDR_TORQUE_LIMIT) == 0  # the servo's own shutdown
    emulator.overload(False)
    emulator.set_temperature(80)
    assert servo.move_to(0.1)  # overheating is news, not a refusal
    assert servo.last_error == {"overheating"} and servo.errors["overload"] == 2
    emulator.set_temperature(30)
    assert servo.position() is not None and servo.last_error == frozenset()
    assert servo.counters["status_errors"] == 3 and servo.stats()["errors"] == {"overheating": 1, "overload": 2}


# -- faults -----------------------------------------------------------------------------------


def test_garbage_dropped_corrupted_and_cut_replies_are_survived(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    assert servo.move_to(0.2)
    assert wait_until(lambda: emulator.position == emulator.goal and not emulator.moving)
    expected = raw_to_angle(emulator.goal)
    emulator.inject_garbage(2000)
    assert servo.position() == pytest.approx(expected)
    emulator.drop_replies(2)
    assert servo.position() == pytest.approx(expected)
    assert servo.counters["timeouts"] >= 2
    emulator.corrupt_replies(1)
    assert servo.position() == pytest.approx(expected)
    emulator.cut_replies(1)
    assert servo.position() == pytest.approx(expected)
    assert servo.counters["corrupt_replies"] + servo.counters["timeouts"] >= 4
    assert servo.counters["retries"] >= 4 and servo.counters["disconnects"] == 0
    emulator.drop_replies(4)  # every try of one transaction: the link is dropped and reopened
    assert servo.position() is None and servo.counters["disconnects"] == 1 and not servo.connected
    assert wait_until(lambda: servo.position() is not None)
    assert servo.counters["reconnects"] == 1 and servo.connected
    assert servo.position() == pytest.approx(expected)


def test_unplug_and_replug_are_survived_and_counted(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    assert servo.move_to(0.2)
    emulator.unplug()
    assert not servo.move_to(0.4)  # the port is gone: False, never an exception
    assert servo.position() is None and servo.read_state() is None and not servo.hold()
    assert servo.counters["disconnects"] == 1 and servo.counters["port_errors"] == 1
    emulator.replug()
    assert wait_until(lambda: servo.position() is not None)
    assert servo.counters["reconnects"] == 1 and emulator.first_instructions[-1] == "ping"
    assert servo.counters["limits_written"] == 1  # the EEPROM already held them
    assert emulator.torque_enabled and emulator.goal == emulator.position  # held on reconnection
    emulator.disconnect(0.2)
    assert wait_until(lambda: servo.move_to(0.4))  # False while unplugged, then the goal goes out
    assert emulator.goal == angle_to_raw(0.4)
    assert servo.counters["disconnects"] == 2 and servo.counters["reconnects"] == 2
    assert servo.counters["open_failures"] >= 1 and servo.counters["calls_while_down"] >= 1


def test_close_holds_torque_at_the_present_position(stepped: tuple[Ax12Emulator, DynamixelServo, Clock]) -> None:
    emulator, servo, clock = stepped
    assert servo.move_to(1.0)
    step(emulator, clock)
    assert emulator.moving and emulator.position == 535
    servo.close()
    assert servo.held_on_close and servo.closed and not servo.connected
    assert emulator.goal == 535 and emulator.torque_enabled
    step(emulator, clock)
    assert emulator.position == 535 and not emulator.moving  # stopped, and holding
    assert not servo.move_to(0.0) and servo.position() is None
    assert servo.counters["calls_after_close"] == 2
    servo.close()  # twice is fine
    emulator.push(560)  # a hand on the camera: the servo pushes back
    step(emulator, clock)
    assert emulator.position == 537  # 23 units back in 0.1 s
    step(emulator, clock)
    assert emulator.position == 535


def test_close_while_unplugged_returns(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    emulator.unplug()
    servo.close()
    assert servo.closed and servo.held_on_close is False


def test_used_without_open_it_connects_and_still_holds_on_close(tmp_path: Path) -> None:
    with Ax12Emulator(link_dir=tmp_path) as emulator:
        unused = make_servo(emulator.path)
        unused.close()  # never opened: nothing sent
        assert unused.closed and unused.held_on_close is None and emulator.counters["bytes_received"] == 0
        servo = make_servo(emulator.path)
        assert servo.move_to(0.1)  # connects on first use
        assert servo.counters["connects"] == 1 and emulator.goal == angle_to_raw(0.1)
        servo.close()
        assert servo.held_on_close and emulator.torque_enabled


def test_another_model_is_refused(tmp_path: Path) -> None:
    with Ax12Emulator(link_dir=tmp_path, model=18) as emulator:  # an AX-18A
        servo = make_servo(emulator.path)
        with pytest.raises(WrongModelError, match="model 18"):
            servo.open()
        assert servo.counters["wrong_model"] == 1 and not servo.connected
        assert not emulator.torque_enabled  # nothing was written
        servo.close()


def test_the_wrong_baud_rate_finds_nobody(tmp_path: Path) -> None:
    with Ax12Emulator(link_dir=tmp_path) as emulator:
        servo = make_servo(emulator.path, baud=57600, retries=1)
        assert not servo.open()
        assert servo.counters["ping_failures"] == 1 and emulator.counters["bytes_misframed"] > 0
        servo.close()


def test_one_lock_around_the_port(rig: tuple[Ax12Emulator, DynamixelServo]) -> None:
    emulator, servo = rig
    failures: list[str] = []

    def mover() -> None:
        for i in range(40):
            if not servo.move_to(0.01 * (i % 5)):
                failures.append("move")

    def reader() -> None:
        for _ in range(40):
            if servo.position() is None:
                failures.append("position")

    threads = [threading.Thread(target=target) for target in (mover, reader, reader)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert failures == [] and not any(thread.is_alive() for thread in threads)
    assert emulator.counters["checksum_errors"] == 0 and servo.counters["refused_writes"] == 0
    assert emulator.counters["instruction_write"] >= 40
