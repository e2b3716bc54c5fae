"""The book's gesture controller: the chapter's converter with its quirks fixed, scaled to each
robot, and a hand on the emulated Arduino driving Chefbot and Bittle through rosserial."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import pytest

from botstage.robots.clock import SimClock
from botstage.robots.drivers.rosserial import RosserialDriver
from botstage.robots.emulators.imu_arduino import HandScript, ImuArduino
from botstage.robots.places import robot_place
from botstage.robots.sim.backend import SimBackend
from botstage.robots.teleop import drive_loop
from botstage.skills.gesture import GestureCommands, GestureConfig, GestureConverter, load_config
from tests.launchpad_helpers import wait_until


def test_pitch_changes_move_the_speed_and_yaw_changes_the_turn() -> None:
    converter = GestureConverter()
    assert converter.update(0.0, 0.0) == (0.0, 0.0)  # the first sample sets where the hand is
    assert converter.update(0.0, 10.0) == pytest.approx((0.2, 0.0))  # 10 degrees forward: 0.02 per degree
    assert converter.update(0.0, 10.0) == pytest.approx((0.2, 0.0))  # held: the speed holds
    assert converter.update(25.0, 10.0) == pytest.approx((0.2, 0.5))  # turned the hand left
    assert converter.update(25.0, 3.0) == pytest.approx((0.06, 0.5))  # the yaw held, the hand tilted back
    assert converter.update(25.0, 1.0) == (0.0, 0.0)  # level and still: home stops the robot


def test_the_speed_and_the_turn_are_clamped_each_on_its_own() -> None:
    converter = GestureConverter(GestureConfig(step_size=0.05))
    converter.update(0.0, 0.0)
    # both beyond their limits at once: the chapter's if/elif clamped the speed and left the turn at 8.95
    assert converter.update(179.0, 89.0) == (4.0, 2.0)
    converter.update(179.0, 60.0)
    assert converter.speed == pytest.approx(4.0 - 0.05 * 29)  # back from the clamp at once (no wind-up)


def test_the_yaw_wraps_the_short_way_round() -> None:
    converter = GestureConverter()
    converter.update(175.0, 10.0)
    converter.update(-175.0, 10.0)  # ten degrees further left, across the DMP's wrap
    assert converter.turn == pytest.approx(0.2)  # the chapter's change was -350 degrees: full right


def test_small_motions_count_and_the_home_band_is_symmetric() -> None:
    converter = GestureConverter()
    converter.update(0.0, 5.0)  # the reference: a hand already tilted
    for pitch in (5.9, 6.8, 7.7):  # under a degree a sample: the chapter's int() lost all of them
        converter.update(0.0, pitch)
    assert converter.speed == pytest.approx(0.02 * 2.7)
    for pitch in (-2.9, 2.9):  # int() made both "level"; the band is |pitch| < 2 either way here
        converter.update(0.0, pitch)
        assert converter.speed != 0.0


def test_the_range_maps_onto_the_robot_s_limits() -> None:
    converter = GestureConverter(GestureConfig(low_speed=-2, high_speed=4))
    converter.speed, converter.turn = 4.0, -1.0
    assert converter.command(0.35, 2.0) == pytest.approx((0.35, -1.0))  # Chefbot's top speed at full tilt
    converter.speed = -1.0
    assert converter.command(0.2, 0.5)[0] == pytest.approx(-0.1)  # half of the backward range


def test_the_chapter_s_config_file_loads_and_a_bad_one_says_why(tmp_path: Path) -> None:
    good = tmp_path / "teleop_config.yaml"
    good.write_text(
        'imu_topic: "/imu_data"\nlow_speed: -4\nhigh_speed: 4\nlow_turn: -2\nhigh_turn: 2\nstep_size: 0.02\n'
    )
    assert load_config(good) == GestureConfig()
    bad = tmp_path / "bad.yaml"
    bad.write_text("step_size: -1\nspeed: 3\n")
    with pytest.raises(ValueError, match=r"bad\.yaml: step_size: Input should be greater than 0; speed: unknown key$"):
        load_config(bad)


@dataclass
class Sample:
    yaw: float
    pitch: float
    roll: float
    received: float


class Hand:
    def __init__(self) -> None:
        self.sample: Sample | None = None

    def orientation(self) -> Sample | None:
        return self.sample


def test_a_hand_that_goes_quiet_stops_the_robot_and_starts_afresh() -> None:
    now = [0.0]
    hand = Hand()
    commands = GestureCommands(hand, 0.35, 2.0, monotonic=lambda: now[0])
    assert commands() == (0.0, 0.0)  # nothing yet
    hand.sample = Sample(0.0, 0.0, 0.0, 0.0)
    commands()
    hand.sample = Sample(0.0, 40.0, 0.0, 0.4)
    now[0] = 0.4
    assert commands()[0] == pytest.approx(0.8 / 4 * 0.35)
    now[0] = 1.5  # no sample for over a second: the IMU is gone
    assert commands() == (0.0, 0.0) and commands.stale
    hand.sample = Sample(0.0, 40.0, 0.0, 1.6)  # back, still tilted: a new reference, not a jump
    now[0] = 1.6
    assert commands() == (0.0, 0.0)


FORWARD = HandScript([(0.0, 0.0, 0.0, 0.0), (0.4, 0.0, 0.0, 0.0), (2.0, 0.0, 40.0, 0.0)], loop=False)
# a hand held a little tilted (not home: a level, still hand stops the robot), turned 45 degrees left
LEFT = HandScript([(0.0, 0.0, 5.0, 0.0), (0.4, 0.0, 5.0, 0.0), (2.0, 45.0, 5.0, 0.0)], loop=False)


@pytest.mark.parametrize("robot", ["chefbot", "bittle"])
@pytest.mark.parametrize(("script", "moves"), [(FORWARD, "forward"), (LEFT, "left")])
def test_the_emulated_hand_drives_the_robot_through_rosserial(robot: str, script: HandScript, moves: str) -> None:
    profile, grid, start = robot_place(robot, "restaurant", "10,7,0")
    clock = SimClock(10.0)
    backend = SimBackend(profile, grid, start, 1, clock)
    with ImuArduino(script, publish_hz=20.0) as glove, RosserialDriver(glove.path) as driver:
        commands = GestureCommands(driver, profile.base.max_linear, profile.base.max_angular)
        # the hand's motion arrives over the pty: wait until it has (in real time), then drive
        assert wait_until(lambda: commands() != (0.0, 0.0) and glove.samples[-1].t >= 2.0 if glove.samples else False)
        v, w = commands()
        drive_loop(backend.devices["drive"], commands, clock, step=backend.step, until=3.0)  # under half a turn
    pose = backend.true_pose()
    if moves == "forward":
        # about 38 degrees forward from where the hand left home (2 degrees): 0.02 a degree, of 4 at full speed
        assert v == pytest.approx(profile.base.max_linear * 0.02 * 38 / 4, rel=0.05)
        assert pose.x - start.x > 0.1 and abs(math.remainder(pose.theta - start.theta, math.tau)) < 0.3
    else:
        assert v == 0.0 and w == pytest.approx(profile.base.max_angular * 0.02 * 45 / 2, rel=0.05)
        assert math.remainder(pose.theta - start.theta, math.tau) > 0.3  # counter-clockwise: left
