"""The chapter's face detector and pan controller, with its quirks fixed."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from botstage.robots.places import robot_place
from botstage.robots.profile import Device
from botstage.robots.sim.camera import CameraView
from botstage.robots.sim.world import World
from botstage.skills.perception.face_tracking import FaceDetector, PanController


@pytest.mark.parametrize(
    ("face_x", "moves"), [(100, 0.01), (269.9, 0.01), (270, 0.0), (320, 0.0), (370, 0.0), (371, -0.01)]
)
def test_the_dead_band_is_closed_and_a_face_on_the_left_turns_left(face_x: float, moves: float) -> None:
    controller = PanController()
    assert controller.update(face_x) == pytest.approx(moves)


def test_at_the_limit_the_position_is_held_and_sent_not_wound_up() -> None:
    controller = PanController()
    for _ in range(80):  # 0.8 rad of steps against a 0.5 rad limit
        position = controller.update(0)
    assert position == 0.5
    # the chapter's position had gone on to 0.8, unsent: the first step back would not move the servo
    assert controller.update(640) == pytest.approx(0.49)


def test_the_proportional_step_is_bigger_far_from_the_centre_and_bounded() -> None:
    near, far = PanController(gain=0.0005), PanController(gain=0.0005)
    assert near.update(380) == pytest.approx(-0.03)  # 60 px off the centre, 10 px past the band
    assert far.update(640) == pytest.approx(-0.1)  # 320 px off: 0.16, bounded to 0.1
    assert PanController(gain=0.0005).update(None) == 0.0  # no face: stay


def test_the_detector_finds_the_simulated_face_and_its_side() -> None:
    profile, grid, pose = robot_place("peoplebot", "museum", "hall_centre")
    world = World(grid, profile, pose, 0)
    view = CameraView(Device(width=640, height=480, field_of_view=1.085, mount_height=1.5))
    detector = FaceDetector()
    ahead = (pose.x + 2.0 * math.cos(pose.theta), pose.y + 2.0 * math.sin(pose.theta))
    left = (ahead[0] - 0.5 * math.sin(pose.theta), ahead[1] + 0.5 * math.cos(pose.theta))
    centre = detector.centre(view.render(world, [SimpleNamespace(id=1, x=ahead[0], y=ahead[1])]))
    assert centre is not None and abs(centre[0] - 320) < 20
    on_left = detector.centre(view.render(world, [SimpleNamespace(id=1, x=left[0], y=left[1])]))
    assert on_left is not None and on_left[0] < 270  # a face on the left of the image
    empty = view.render(world, [])
    assert detector.centre(empty) is None
