"""The face tracker's robot (book ch. 2): its profile, the simulated pan and camera, people who
walk a path, and the same robot over its emulated AX-12A (a real pty) and on "hardware" (the
driver on a pty, OpenCV on a video file).

Motion is judged on clocks the tests step: the simulator's, and the emulated servo's injected
``monotonic``. Faces are found by the chapter's own detector on rendered frames.
"""

from __future__ import annotations

import itertools
import math
import textwrap
import zlib
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from botstage.missions.check import check
from botstage.missions.runner import run
from botstage.robots.ax12 import RAD_PER_UNIT, RAD_S_PER_SPEED_UNIT, speed_to_raw
from botstage.robots.backend import OpenRequest, ScriptedWalk
from botstage.robots.backend_options import OptionSources
from botstage.robots.backend_registry import BackendError, BackendRegistry
from botstage.robots.clock import SimClock
from botstage.robots.emulators.ax12 import Ax12Emulator
from botstage.robots.emulators.pan_head import PanHeadEmulatorBackend
from botstage.robots.gridmap import load
from botstage.robots.interfaces import Camera, Pan, Pose2D, check_interfaces
from botstage.robots.profile import Profile, load_profile
from botstage.robots.ros2 import readings, types
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.proxies import ClockRef, Latest, PanProxy
from botstage.robots.ros2.robot_server import RobotServer
from botstage.robots.ros2.topics import routes
from botstage.robots.sim.backend import SimBackend
from botstage.robots.sim.devices import SimPan
from botstage.robots.sim.people import Person
from botstage.skills.perception.face_tracking import FaceDetector
from tests.launchpad_helpers import wait_until

PROFILE = Path("robots/profiles/face_tracker.yaml")
MUSEUM = load("robots/maps/museum.yaml")
HALL = Pose2D(11.0, 10.0, 0.0)  # the hall's centre, facing +x
LIMIT = 196 * RAD_PER_UNIT  # 316..708 about 512: ±1.002 rad
DETECTOR = FaceDetector()
ACROSS = ScriptedWalk(((13.0, 11.5), (13.0, 8.5)), speed=0.5, at=1.0)  # 2 m ahead, from left to right


def tracker() -> Profile:
    profile, problems, _ = load_profile(PROFILE)
    assert profile is not None, problems
    return profile


def sim(walks: list[ScriptedWalk] | None = None, people: int = 0, seed: int = 1, **options: object) -> SimBackend:
    return SimBackend(tracker(), MUSEUM, HALL, seed, SimClock(10), people=people, walks=walks, **options)  # type: ignore[arg-type]


def face_x(backend: SimBackend) -> float | None:
    """Where the chapter's detector finds the face in a fresh frame (x in pixels), if it does."""
    backend.clock.next_tick()
    centre = DETECTOR.centre(backend.devices["camera"].frame())
    return None if centre is None else centre[0]


def stand(backend: SimBackend, forward: float, left: float, pid: int = 1) -> None:
    """One person, still, ``forward`` m ahead of the tracker and ``left`` m to its left."""
    x, y = HALL.x + forward, HALL.y + left
    backend.crowd.people = [Person(pid, x, y, 1.0, (x, y), pause_until=math.inf)]


# -- the profile ---------------------------------------------------------------------------------


def test_the_profile_has_the_chapters_servo_and_camera_on_a_fixed_base() -> None:
    profile = tracker()
    base = profile.base
    assert (base.kind, base.moves, base.max_linear, base.max_angular, base.wheel_separation) == (
        "fixed",
        False,
        0.0,
        0.0,
        None,
    )
    assert profile.battery is None  # the chapter's 12 V adapter
    assert set(profile.interfaces) == {"pan", "camera"}
    pan = profile.interfaces["pan"]
    assert pan.hardware == "dynamixel" and pan.joint is not None
    joint = pan.joint
    assert (joint.name, joint.id, joint.init, joint.min, joint.max, joint.joint_speed) == (
        "pan_joint",
        1,
        512,
        316,
        708,
        1.17,
    )
    camera = profile.interfaces["camera"]
    assert (camera.width, camera.height, camera.mounted_on, camera.hardware) == (640, 480, "pan", "usb_cam")
    assert profile.backends["hardware"] == {"port": "/dev/ttyUSB0", "baud": 1_000_000, "camera": "/dev/video0"}


def broken(tmp_path: Path, old: str, new: str) -> list[str]:
    text = PROFILE.read_text()
    assert old in text
    path = tmp_path / "head.yaml"
    path.write_text(text.replace(old, new))
    profile, problems, _ = load_profile(path)
    assert profile is None
    return [str(p).replace(str(tmp_path) + "/", "") for p in problems]


def line_of(text: str) -> int:
    """The line of the shipped profile that holds ``text`` (1-based)."""
    return next(n for n, line in enumerate(PROFILE.read_text().splitlines(), 1) if text in line)


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "  mass: 0.25",
            "  mass: 0.25\n  wheel_diameter: 0.05\n  max_linear: 0.1",
            "base: a fixed base does not move: remove wheel_diameter, max_linear",
        ),
        (
            "interfaces:\n",
            "interfaces:\n  drive: {hardware: dynamixel}\n",
            "head.yaml:{interfaces}:3: error: a fixed base does not move: it has no drive",
        ),
        (
            "  pan: {hardware: dynamixel",
            "  tilt: {hardware: dynamixel",
            "error: unknown interface 'tilt'",
        ),
        (
            "interfaces:\n",
            "interfaces:\n  laser: {mounted_on: pan}\n",
            "head.yaml:{interfaces}:11: error: only a camera rides on the pan",
        ),
        (
            "joint: {name: pan_joint, id: 1, init: 512, min: 316, max: 708, joint_speed: 1.17}",
            "model: AX-12A",
            "head.yaml:{pan}:3: error: a pan needs its joint: {id, init, min, max, joint_speed} (the book's pan.yaml)",
        ),
        ("init: 512", "init: 900", "interfaces.pan.joint: init 900 must lie between min and max (316-708)"),
        ("min: 316", "min: 708", "interfaces.pan.joint: min and max must differ"),
        ("id: 1,", "id: 254,", "interfaces.pan.joint.id: Input should be less than or equal to 253"),
        ("mounted_on: pan", "mounted_on: tilt", "interfaces.camera.mounted_on: Input should be 'pan'"),
        (
            "interfaces:\n",
            "interfaces:\n  battery: {hardware: dynamixel}\n",
            "a battery interface needs the battery: it reports",
        ),
    ],
)
def test_broken_face_tracker_profiles_give_located_errors(tmp_path: Path, old: str, new: str, expected: str) -> None:
    lines = {"interfaces": line_of("interfaces:") + 1, "pan": line_of("  pan: {")}
    found = broken(tmp_path, old, new)
    for name, line in lines.items():
        expected = expected.replace(f"{{{name}}}", str(line))
    assert any(expected in problem for problem in found), found


def test_a_camera_on_the_pan_needs_a_pan(tmp_path: Path) -> None:
    text = PROFILE.read_text()
    start, end = text.index("  pan: {hardware"), text.index("  # the chapter's webcam")
    path = tmp_path / "head.yaml"
    path.write_text(text[:start] + text[end:])
    _, problems, _ = load_profile(path)
    lines = path.read_text().splitlines()
    camera = next(n for n, line in enumerate(lines, 1) if line.startswith("  camera:"))
    assert [str(p).replace(str(tmp_path) + "/", "") for p in problems] == [
        f"head.yaml:{camera}:53: error: a camera mounted on the pan needs a 'pan' interface",
    ]
    # the profile's ros2: section is the ros2 backend's to check (when a mission on this robot is)
    kind = BackendRegistry.default().get("ros2")
    profile = Profile.model_validate(yaml.safe_load(path.read_text()))
    assert kind.check_profile(profile) == [
        (("ros2", "rates_hz", "pan_state"), "ros2: the robot has no 'pan' interface", "list it under interfaces:")
    ]


def test_a_moving_base_still_needs_wheels_speeds_and_a_battery(tmp_path: Path) -> None:
    text = Path("robots/profiles/chefbot.yaml").read_text()
    path = tmp_path / "bot.yaml"
    battery = text[text.index("battery:\n") : text.index("interfaces:")]
    path.write_text(text.replace(battery, "").replace("  max_linear: 0.35", "  max_linear: 0"))
    _, problems, _ = load_profile(path)
    assert any("base: a differential base needs max_linear (above 0)" in str(p) for p in problems), problems
    path.write_text(text.replace(battery, "").replace("  battery: {hardware: launchpad}\n", ""))
    _, problems, _ = load_profile(path)
    assert [str(p).split("error: ")[1] for p in problems] == ["a differential base runs on batteries: give battery:"]


# -- the simulated pan ---------------------------------------------------------------------------


def test_the_pan_turns_at_its_joint_speed_on_the_sim_clock_and_stops_on_the_goal() -> None:
    backend = sim()
    pan = backend.devices["pan"]
    assert isinstance(pan, SimPan) and isinstance(pan, Pan) and check_interfaces(backend.devices) == []
    speed = speed_to_raw(1.17) * RAD_S_PER_SPEED_UNIT  # 101 units of 0.111 rpm: 1.174 rad/s
    assert pan.speed == pytest.approx(speed) and pan.speed == pytest.approx(1.17, rel=0.005)
    assert (pan.min_angle, pan.max_angle) == (pytest.approx(-LIMIT), pytest.approx(LIMIT))
    assert pan.position() == 0.0  # held at init (512)
    assert pan.move_to(0.8)
    angles = []
    for _ in range(10):  # 1 s of sim time
        backend.step()
        angles.append(pan.angle)
        assert pan.angle == angles[-1]  # between ticks it stands still: no wall time in it
    assert angles[:6] == pytest.approx([speed * 0.1 * k for k in range(1, 7)])
    goal = round(0.8 / RAD_PER_UNIT) * RAD_PER_UNIT  # the goal in whole position units, as the driver sends it
    assert angles[6:] == pytest.approx([goal] * 4) and not pan.moving
    assert pan.position() == pytest.approx(goal)


@pytest.mark.parametrize(("asked", "limit"), [(2.0, LIMIT), (-5.0, -LIMIT)])
def test_the_pan_stops_at_the_servos_limits(asked: float, limit: float) -> None:
    backend = sim()
    pan = backend.devices["pan"]
    assert pan.move_to(asked) and pan.clamped == 1
    for _ in range(30):
        backend.step()
    assert pan.position() == pytest.approx(limit) and pan.goal == pytest.approx(limit)
    with pytest.raises(ValueError, match="finite"):
        pan.move_to(math.nan)


def test_the_pan_is_held_where_it_is_when_the_backend_closes() -> None:
    backend = sim()
    pan = backend.devices["pan"]
    pan.move_to(1.0)
    backend.step()
    backend.close()
    held = pan.angle
    for _ in range(10):
        backend.step()
    assert pan.angle == pytest.approx(held, abs=RAD_PER_UNIT) and 0.1 < held < 0.2


# -- the camera on the pan -----------------------------------------------------------------------


@pytest.mark.parametrize("left", [0.6, -0.6])
def test_a_face_off_centre_comes_to_the_centre_when_the_pan_turns_to_it(left: float) -> None:
    backend = sim()
    stand(backend, 2.0, left)
    before = face_x(backend)
    assert before is not None and (before < 200 if left > 0 else before > 440)  # well off the centre
    bearing = math.atan2(left, 2.0)
    backend.devices["pan"].move_to(bearing)
    halfway = None
    for _ in range(5):
        backend.step()
        halfway = halfway or face_x(backend)
    after = face_x(backend)
    assert after is not None and abs(after - 320) < 12
    assert halfway is not None and min(before, after) < halfway < max(before, after)  # the view turned on the way


def test_a_camera_not_on_the_pan_stays_put() -> None:
    profile = tracker()
    camera = profile.interfaces["camera"].model_copy(update={"mounted_on": None})
    fixed = profile.model_copy(update={"interfaces": {**profile.interfaces, "camera": camera}})
    backend = SimBackend(fixed, MUSEUM, HALL, 1, SimClock(10))
    stand(backend, 2.0, 0.6)
    before = face_x(backend)
    backend.devices["pan"].move_to(0.29)
    for _ in range(5):
        backend.step()
    # the same view; the camera's grain moves the detected box by a pixel or two (a turn would be ~200 px)
    assert before is not None and face_x(backend) == pytest.approx(before, abs=4)


def test_the_faces_of_people_standing_one_to_three_metres_away_are_found() -> None:
    """The profile's mount (0.85 m, raised 0.45 rad) has them in view from 1 to 4 m; the chapter's
    detector (15 neighbours) finds them to about 3 m."""
    for distance in (1.0, 1.5, 2.0, 2.5):
        backend = sim()
        stand(backend, distance, 0.0)
        found = face_x(backend)
        assert found is not None and abs(found - 320) < 10, distance
    backend = sim()
    frame_empty = backend.devices["camera"].frame().copy()
    stand(backend, 4.0, 0.0)
    backend.clock.next_tick()
    changed = np.any(backend.devices["camera"].frame() != frame_empty, axis=2)
    rows = np.flatnonzero(changed.any(axis=1))
    eyes = 480 / 2 + backend.devices["camera"].info.focal_px * (math.tan(0.45) - (1.585 - 0.85) / 4.0)
    assert rows.min() < eyes - 15  # at 4 m the head, eyes and brow are in the frame


# -- people who walk a path ----------------------------------------------------------------------


def walk(seed: int, detect: bool) -> tuple[list[float | None], list[tuple[float, float]], list[int]]:
    """The walker crossing the view (with people about): the face's x every fourth tick (when
    ``detect``), the walker's path every tick, and a checksum of each frame looked at."""
    backend = sim([ACROSS], people=4, seed=seed)
    walker = backend.crowd.people[-1]
    faces, path, frames = [], [], []
    for tick in range(1, 81):
        backend.step()
        path.append((walker.x, walker.y))
        if tick % 4 == 0:
            backend.clock.next_tick()
            frame = backend.devices["camera"].frame()
            frames.append(zlib.crc32(frame.tobytes()))
            centre = DETECTOR.centre(frame) if detect else None
            faces.append(None if centre is None else centre[0])
    return faces, path, frames


def test_a_walker_crosses_the_view_from_left_to_right_the_same_way_every_run() -> None:
    faces, path, frames = walk(seed=3, detect=True)
    assert path[9] == (13.0, 11.5)  # standing at the first point until 1.0 s
    assert path[10] == (13.0, pytest.approx(11.45))  # then 0.5 m/s
    assert path[69] == (13.0, pytest.approx(8.5))  # 3 m in 6 s, there at 7.0 s
    assert all(x == 13.0 for x, _ in path)  # nothing sends it elsewhere
    seen = [x for x in faces if x is not None]
    assert len(seen) >= 6 and seen[0] < 270 and seen[-1] > 370  # the face crosses the image
    assert all(b > a for a, b in itertools.pairwise(seen))
    again = walk(seed=3, detect=False)
    assert (again[1], again[2]) == (path, frames)  # same seed, same walk, the same frames byte for byte


def test_walkers_leave_everyone_else_alone_and_never_join_a_group() -> None:
    def others(walks: list[ScriptedWalk]) -> list[tuple[float, float]]:
        backend = sim(walks, people=6, seed=5, gatherings=[(2.0, (13.0, 12.0), 6, 30.0)])
        for _ in range(200):
            backend.step()
        assert all(p.group is None for p in backend.crowd.people if p.route is not None)
        return [(p.x, p.y) for p in backend.crowd.people if p.route is None]

    assert others([ACROSS]) == others([])


def test_a_walk_repeats_rounds_and_pauses_at_each_point() -> None:
    walk = ScriptedWalk(((13.0, 11.0), (13.0, 10.0)), speed=1.0, at=0.0, repeat=2, pause=0.5)
    backend = sim([walk])
    walker = backend.crowd.people[-1]
    ys = []
    for _ in range(40):
        backend.step()
        ys.append(round(walker.y, 6))
    # A B, then back to A and on to B: at B at 1.0 s, standing until 1.5 s, at A at 2.5 s, at B at 4.0 s
    assert ys[9] == 10.0 and ys[10:15] == [10.0] * 5 and ys[15] == pytest.approx(10.1)
    assert ys[24] == 11.0 and ys[39] == 10.0


# -- walks in a mission --------------------------------------------------------------------------


def mission(tmp_path: Path, walks: str, world: str = "world: museum\nstart: hall_centre\n") -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(f"robot: face_tracker\n{world}walks:\n{textwrap.indent(walks, '  ')}until: 3\n")
    path.write_text(path.read_text() + "trees:\n  main: {wait: {duration: 2}}\n")
    return path


@pytest.mark.parametrize(
    ("walks", "expected"),
    [
        ("- {path: [[13.0, 11.5], lobby]}\n", "m.yaml:5:27: error: the map has no place 'lobby'"),
        ("- {path: [[13.0, 11.5], [13.0]]}\n", "m.yaml:5:27: error: a walk's point is a place's name or [x, y]"),
        (
            "- {path: [[13.0, 11.5], [13.0, 30.0]]}\n",
            "m.yaml:5:27: error: a person cannot walk through (13.00, ",
        ),
        ("- {path: [[-3.0, 1.0], [1.0, 1.0]]}\n", "m.yaml:5:13: error: a person cannot walk through (-3.00, 1.00)"),
        ("- {path: [[13.0, 11.5]]}\n", "m.yaml:5:6: error: walks.0.path: list should have at least 2 items"),
        (
            "- {path: [[13.0, 11.5], [13, 9]], speed: 5}\n",
            "m.yaml:5:37: error: walks.0.speed: input should be less than or equal to 3",
        ),
    ],
)
def test_walks_are_checked_with_located_errors(tmp_path: Path, walks: str, expected: str) -> None:
    problems = [str(p).replace(str(tmp_path) + "/", "") for p in check(mission(tmp_path, walks)).problems]
    assert any(p.startswith(expected) for p in problems), problems


def test_walks_need_a_world(tmp_path: Path) -> None:
    path = mission(tmp_path, "- {path: [[1, 1], [2, 2]]}\n", world="")
    assert "m.yaml:2:1: error: walking people need a world to walk in" in [
        str(p).replace(str(tmp_path) + "/", "") for p in check(path).problems
    ]


def test_a_mission_runs_the_tracker_with_a_walker_on_the_simulator(tmp_path: Path) -> None:
    path = mission(tmp_path, "- {path: [[13.0, 11.5], exhibit_d], speed: 0.8, at: 0.5}\n")
    assert check(path).problems == []
    result = run(path, out=tmp_path / "run")
    assert result.outcome == "success", result.reason
    sim_block = result.summary["sim"]
    assert sim_block["people"] == 1 and sim_block["distance_m"] == 0.0 and sim_block["battery_percent"] is None
    assert sim_block["pan"] == {"final_angle": 0.0, "commands": 0, "clamped": 0}


# -- over the emulated servo: the real driver on a pty --------------------------------------------


class Monotonic:
    """The emulated servo's clock: it stands still until the test moves it."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def head(tmp_path: Path) -> Iterator[tuple[PanHeadEmulatorBackend, Monotonic, SimClock]]:
    clock, monotonic = SimClock(10), Monotonic()
    backend = PanHeadEmulatorBackend(
        tracker(),
        MUSEUM,
        HALL,
        1,
        clock,
        link_dir=tmp_path,
        monotonic=monotonic,
        servo_options={"latency_ms": 50.0, "backoff": (0.01, 0.05)},
    )
    try:
        yield backend, monotonic, clock
    finally:
        backend.close()


def advance(backend: PanHeadEmulatorBackend, monotonic: Monotonic, dt: float = 0.1) -> None:
    """Move the servo's clock by ``dt`` and wait for the firmware pass that follows."""
    loops = backend.emulator.loops
    monotonic.now += dt
    assert wait_until(lambda: backend.emulator.loops > loops)


def emulated_face_x(backend: PanHeadEmulatorBackend, clock: SimClock) -> float | None:
    clock.next_tick()
    centre = DETECTOR.centre(backend.devices["camera"].frame())
    return None if centre is None else centre[0]


def test_a_move_on_the_driver_turns_the_simulated_camera_through_the_pty(
    head: tuple[PanHeadEmulatorBackend, Monotonic, SimClock],
) -> None:
    backend, monotonic, clock = head
    pan, camera = backend.devices["pan"], backend.devices["camera"]
    assert isinstance(pan, Pan) and isinstance(camera, Camera) and check_interfaces(backend.devices) == []
    assert type(pan).__name__ == "DynamixelServo" and backend.emulator.first_instructions == ["ping"]
    assert (pan.min_angle, pan.max_angle) == (pytest.approx(-LIMIT), pytest.approx(LIMIT))
    assert (backend.emulator.word(6), backend.emulator.word(8)) == (316, 708)  # the driver set the limits
    with backend.lock:
        x, y = HALL.x + 2.0, HALL.y + 0.6
        backend.crowd.people = [Person(1, x, y, 1.0, (x, y), pause_until=math.inf)]
    before = emulated_face_x(backend, clock)
    assert before is not None and before < 200
    assert pan.move_to(math.atan2(0.6, 2.0))
    # sent, but the shaft has not turned yet (the camera's grain moves the box by a pixel or two)
    assert emulated_face_x(backend, clock) == pytest.approx(before, abs=4)
    advance(backend, monotonic)
    halfway = emulated_face_x(backend, clock)
    assert halfway is not None and before < halfway < 300  # the frame follows the shaft, not the goal
    for _ in range(3):
        advance(backend, monotonic)
    after = emulated_face_x(backend, clock)
    assert after is not None and abs(after - 320) < 12
    assert pan.position() == pytest.approx(backend.emulator.angle)


def test_the_emulated_head_closes_with_the_servo_held_and_the_pty_gone(
    head: tuple[PanHeadEmulatorBackend, Monotonic, SimClock],
) -> None:
    backend, monotonic, _ = head
    backend.servo.move_to(-1.0)
    advance(backend, monotonic)
    backend.close()
    emulator = backend.emulator
    assert backend.servo.held_on_close is True and backend.servo.closed
    assert emulator.torque_enabled and emulator.goal == emulator.position != 512 - 196  # held short of the goal
    assert not Path(emulator.path).exists()
    summary = backend.summary()
    assert summary["pan"]["held_on_close"] is True and summary["servo"]["holds"] >= 2
    backend.close()  # twice is fine


def test_the_emulator_backend_is_what_a_run_opens_for_the_tracker(tmp_path: Path) -> None:
    path = mission(tmp_path, "- {path: [[13.0, 11.5], [13.0, 8.5]], speed: 1.0}\n")
    result = run(path, backend="emulator", until=0.5, out=tmp_path / "run")
    assert result.outcome == "time_limit", result.reason
    assert result.summary["emulator"]["pan"]["held_on_close"] is True
    assert result.summary["emulator"]["board"]["instruction_ping"] == 1


# -- on hardware: the driver on a port, OpenCV on a camera ----------------------------------------


def test_the_hardware_backend_drives_the_servo_and_reads_the_webcam(tmp_path: Path) -> None:
    from botstage.robots.drivers.video_camera import wait_for_frame

    video = tmp_path / "webcam.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (640, 480))
    for level in range(3):
        writer.write(np.full((480, 640, 3), 60 * level, np.uint8))
    writer.release()
    with Ax12Emulator(link_dir=tmp_path) as servo_board:
        request = OpenRequest(tracker(), HALL, SimClock(10))
        given = OptionSources({"port": servo_board.path, "camera": str(video)})
        _, backend = BackendRegistry.default().open("hardware", request, given)
        try:
            assert set(backend.devices) == {"pan", "camera"} and check_interfaces(backend.devices) == []
            frame = wait_for_frame(backend.devices["camera"])
            assert frame is not None and frame.shape == (480, 640, 3)
            assert backend.devices["pan"].move_to(0.3)
            target = 512 + round(0.3 / RAD_PER_UNIT)
            assert servo_board.goal == target
            # there at once (as if it had arrived): the hold then reads the place it stays at, not one
            # it passes on the way, which would depend on the emulator's thread's timing
            servo_board.push(target)
        finally:
            backend.close()
        assert backend.summary()["held_on_close"] is True
        assert servo_board.torque_enabled and servo_board.goal == servo_board.position
        assert not backend.devices["camera"]._thread.is_alive()


def test_a_servo_that_does_not_answer_is_a_clear_error(tmp_path: Path) -> None:
    with Ax12Emulator(link_dir=tmp_path, dxl_id=7) as servo_board:  # set to another ID
        request = OpenRequest(tracker(), HALL, SimClock(10))
        given = OptionSources({"port": servo_board.path, "ready_timeout": 0.3})
        with pytest.raises(BackendError, match=r"no AX-12A answers as ID 1 on .* at 1000000 bps"):
            BackendRegistry.default().open("hardware", request, given)


# -- on a ROS 2 graph ------------------------------------------------------------------------------


def test_the_pan_is_served_as_the_chapters_command_and_a_joint_state() -> None:
    profile = tracker()
    by_key = {route.key: route for route in routes(profile)}
    assert (by_key["pan"].topic, by_key["pan"].channel.type_name) == ("pan_controller/command", "std_msgs/msg/Float64")
    assert (by_key["pan_state"].topic, by_key["pan_state"].rate_hz) == ("joint_states", 20.0)
    clock = SimClock(10)
    backend = SimBackend(profile, MUSEUM, HALL, 0, clock)
    server = RobotServer(backend, Ros2Node("pan_lockstep"), clock, routes(profile), publish_clock=False)
    try:
        server._on_pan(readings.command_message(0.2), None)  # as Zenoh's thread delivers it
        assert backend.devices["pan"].goal == 0.0  # queued: devices are touched by the loop only
        nan = readings.command_message(0.0)
        nan.data = math.nan
        server._on_pan(nan, None)
        for _ in range(3):
            server.take_commands()
            clock.next_tick()
            server.advance()
        state = server.message_now("pan_state")
        types.serialize(state)
        assert list(state.name) == ["pan_joint"] and state.position[0] == pytest.approx(0.2, abs=RAD_PER_UNIT)
        assert (server.counts["pan"], server.counts["pan_rejected"]) == (1, 1)
        assert readings.joint_position_of(state, "pan_joint") == state.position[0]
        with pytest.raises(ValueError, match="without 'tilt_joint'"):
            readings.joint_position_of(state, "tilt_joint")
    finally:
        server.close()


def test_the_ros2_pan_proxy_clamps_its_goals_and_reads_none_when_stale() -> None:
    sent = []

    class Publisher:
        def publish(self, message: object) -> None:
            sent.append(message)

    clock = SimClock(10)
    state = Latest(
        "pan (pan_state)", "/joint_states", lambda m: readings.joint_position_of(m, "pan_joint"), ClockRef(clock), 0.5
    )
    proxy = PanProxy(Publisher(), state, -LIMIT, LIMIT)  # type: ignore[arg-type]
    assert isinstance(proxy, Pan) and proxy.position() is None  # nothing heard yet
    assert proxy.move_to(3.0) and sent[-1].data == pytest.approx(LIMIT)
    state.on_message(readings.joint_state_message("pan_joint", 0.25, 0.0))
    assert proxy.position() == 0.25
    for _ in range(6):
        clock.next_tick()
    assert proxy.position() is None  # 0.6 s old: stale


def test_a_mission_process_turns_a_served_tracker_over_ros2() -> None:
    """`botstage serve robot face_tracker` in its own process; this one opens it on the ros2 backend."""
    from tests.test_ros2_interop import FAILSAFE_S, until
    from tests.test_ros2_robot import ServedRobot

    served = ServedRobot("face_tracker", "--backend", "sim", "--world", "museum", "--start", "hall_centre")
    try:
        assert served.expect_line("serving ") is not None, served.output()
        request = OpenRequest(tracker(), HALL, SimClock(10))
        given = OptionSources({"connect": served.endpoint, "ready_timeout": FAILSAFE_S, "listen": ""})
        _, backend = BackendRegistry.default().open("ros2", request, given)
        try:
            pan, camera = backend.devices["pan"], backend.devices["camera"]
            assert isinstance(pan, Pan) and isinstance(camera, Camera)
            assert pan.max_angle == pytest.approx(LIMIT) and pan.position() == pytest.approx(0.0)
            assert pan.move_to(0.3)
            assert until(lambda: abs((pan.position() or 0.0) - 0.3) < RAD_PER_UNIT), served.output()
            assert camera.frame().shape == (480, 640, 3)
        finally:
            backend.close()
    finally:
        served.stop()
