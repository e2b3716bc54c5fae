"""detect_crowd and the perception it stands on: grouping, people tracks, the map transform."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, load_profile
from botstage.skills.detect_crowd import DetectCrowd
from botstage.skills.perception.camera_people import CASCADE, faces_to_people
from botstage.skills.perception.crowd import CrowdTracker, group
from botstage.skills.perception.people_tracking import map_to_sensor, sensor_to_map
from botstage.skills.perception.tracking import PeopleTracks
from tests.bench.navsim import NavSim


def place(sim: NavSim, spots: list[tuple[float, float]]) -> None:
    """Put the simulated people where the test wants them, standing still."""
    crowd = sim.sim.crowd
    crowd.next_group_at = math.inf
    for person, (x, y) in zip(crowd.people, spots, strict=True):
        person.x, person.y, person.pause_until, person.goal = x, y, math.inf, (x, y)


# -- grouping ---------------------------------------------------------------------------------


def test_single_linkage_chains_people_within_the_distance() -> None:
    chain = np.array([[0.0, 0.0], [1.4, 0.0], [2.8, 0.0]])  # ends 2.8 m apart, each 1.4 m from the next
    assert group([1, 2, 3], chain) == [[0, 1, 2]]
    assert group([1, 2], np.array([[0.0, 0.0], [1.51, 0.0]])) == []  # farther than 1.5 m: no crowd
    assert group([1], np.array([[0.0, 0.0]])) == []  # one person is not a crowd
    two = group([1, 2, 3, 4], np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0], [10.5, 0.5]]))
    assert sorted(map(sorted, two)) == [[0, 1], [2, 3]]


def test_crowd_keeps_its_id_as_people_join_and_leave() -> None:
    tracker = CrowdTracker()
    first = tracker.update([(1, 0.0, 0.0), (2, 1.0, 0.0)])
    joined = tracker.update([(1, 0.0, 0.0), (2, 1.0, 0.0), (3, 1.5, 1.0)])
    left = tracker.update([(2, 1.0, 0.0), (3, 1.5, 1.0)])
    assert first[0].id == joined[0].id == left[0].id
    assert joined[0].size == 3 and joined[0].centre == pytest.approx((2.5 / 3, 1.0 / 3))
    assert tracker.update([(2, 1.0, 0.0)]) == []
    assert tracker.update([(4, 5.0, 5.0), (5, 5.5, 5.0)])[0].id != first[0].id  # a new crowd, a new id


# -- people tracks ----------------------------------------------------------------------------


def test_tracks_keep_ids_through_noise_and_a_short_gap_and_smooth_the_position() -> None:
    rng = np.random.default_rng(3)
    truth = [(1.0, 2.0), (1.8, 2.2), (4.0, -1.0)]
    tracks = PeopleTracks()
    ids = None
    for k in range(60):
        t = k / 30
        seen = truth[:2] if 20 <= k < 35 else truth  # the third person is hidden for half a second
        detections = [(x + rng.normal(0, 0.03), y + rng.normal(0, 0.03), None) for x, y in seen]
        confirmed = tracks.update(t, detections)
        if k == 10:
            ids = sorted(c.id for c in confirmed)
    assert ids is not None and len(ids) == 3
    final = {c.id: c.position for c in tracks.confirmed()}
    assert sorted(final) == ids  # nobody got a new id after the gap
    for position in final.values():
        nearest = min(math.hypot(position[0] - x, position[1] - y) for x, y in truth)
        assert nearest < 0.02  # steadier than one reading's 3 cm


def test_tracks_drop_non_finite_detections_and_one_frame_ghosts_never_confirm() -> None:
    tracks = PeopleTracks()
    assert tracks.update(0.0, [(math.nan, 1.0, 1), (1.0, math.inf, 2), (0.0, 0.0, 3)]) == []
    tracks.update(0.1, [(0.0, 0.0, 3)])
    assert [t.sensor_id for t in tracks.update(0.2, [(0.0, 0.0, 3)])] == [3]
    assert len(tracks.tracks) == 1  # the NaN readings made no tracks


def test_sensor_and_map_frames_are_inverse() -> None:
    pose, mount = Pose2D(3.0, -2.0, 0.7), (0.1, 0.0, 0.0)
    for x, z in ((0.0, 2.0), (-1.0, 1.5), (0.5, 3.9)):
        mx, my = sensor_to_map(pose, mount, x, z)
        assert map_to_sensor(pose, mount, mx, my) == pytest.approx((x, z))
    # straight ahead of a robot facing +y is +y on the map; x is to the right (-x on the map)
    assert sensor_to_map(Pose2D(0.0, 0.0, math.pi / 2), (0.0, 0.0, 0.0), 1.0, 2.0) == pytest.approx((1.0, 2.0))


# -- the skill on the simulator ------------------------------------------------------------------

START = (11.0, 10.0, 0.0)  # hall centre, facing +x


def test_finds_a_crowd_ahead_with_its_centre_of_mass_on_the_map() -> None:
    sim = NavSim("museum", "peoplebot", START, seed=4, people=4)
    spots = [(13.2, 10.0), (13.6, 10.6), (13.9, 9.7), (14.4, 10.2)]
    place(sim, spots)
    outcome = sim.run(DetectCrowd(), duration=5.0)
    assert outcome.name == "crowd_found", outcome.reason
    cx, cy = np.mean(spots, axis=0)
    assert math.hypot(outcome.outputs["centre"][0] - cx, outcome.outputs["centre"][1] - cy) < 0.05
    assert outcome.outputs["size"] == 4 and len(outcome.outputs["members"]) == 4
    again = sim.run(DetectCrowd(), duration=5.0)
    assert again.outputs["crowd_id"] == outcome.outputs["crowd_id"]  # the same crowd, the same id
    assert again.outputs["members"] == outcome.outputs["members"]


def test_no_crowd_when_nobody_is_in_view_and_timeout_when_it_does_not_last() -> None:
    sim = NavSim("museum", "peoplebot", START, seed=4, people=2)
    place(sim, [(6.0, 10.0), (6.5, 10.0)])  # behind the robot: the Kinect cannot see them
    assert sim.run(DetectCrowd(), duration=3.0).name == "no_crowd"
    place(sim, [(13.0, 10.0), (13.8, 10.0)])
    outcome = sim.run(DetectCrowd(), duration=0.5, confirm=1.0)  # seen, but not for a second yet
    assert outcome.name == "timeout", outcome.reason


def test_two_people_apart_are_not_a_crowd() -> None:
    sim = NavSim("museum", "peoplebot", START, seed=4, people=2)
    place(sim, [(13.0, 9.0), (13.0, 11.0)])  # 2 m apart
    assert sim.run(DetectCrowd(), duration=2.0).name == "no_crowd"


@dataclass
class Reading:
    id: int
    x: float
    z: float


class GarbledTracker:
    """A tracker driver that lets NaN through (TrackedPerson would refuse them)."""

    def people(self) -> list[Reading]:
        return [Reading(1, math.nan, 2.0), Reading(2, 0.0, 2.0), Reading(3, 0.6, 2.2), Reading(4, 0.1, math.inf)]


def test_nan_positions_are_dropped_and_counted_not_raised() -> None:
    sim = NavSim("museum", "peoplebot", START, seed=4)
    tracking = sim.services.interfaces.get("people_tracking")
    assert tracking is not None
    tracking.tracker = GarbledTracker()
    outcome = sim.run(DetectCrowd(), duration=3.0)
    assert outcome.name == "crowd_found" and outcome.outputs["size"] == 2
    assert "tracker readings dropped" in outcome.reason
    assert tracking.dropped >= 2 * 10  # two a frame, every frame


def test_bad_inputs_and_robots_without_a_tracker_fail_with_a_reason() -> None:
    sim = NavSim("museum", "peoplebot", START, seed=4)
    negative = sim.run(DetectCrowd(), duration=-1.0)
    assert negative.reason == "input 'duration': input should be greater than or equal to 0"
    nan = sim.run(DetectCrowd(), distance=math.nan)
    assert nan.name == "failure" and "finite" in nan.reason, nan.reason
    chefbot = NavSim("restaurant", "chefbot", "kitchen")
    outcome = chefbot.run(DetectCrowd())
    assert outcome.name == "failure" and "no people tracker" in outcome.reason


# -- a robot with only a camera -----------------------------------------------------------------


def camera_only_peoplebot() -> Profile:
    profile, problems, _ = load_profile("robots/profiles/peoplebot.yaml")
    assert profile is not None, problems
    interfaces = {k: v for k, v in profile.interfaces.items() if k != "people"}
    return profile.model_copy(update={"interfaces": interfaces})


def test_faces_to_people_uses_the_pinhole_model() -> None:
    # a 0.22 m box 50 px high at f = 500 px is 2.2 m ahead; 100 px right of the centre is 0.44 m right
    (person,) = faces_to_people([(395, 100, 50, 50)], 640, 500.0, face_height=0.22)
    assert (person.x, person.z) == pytest.approx((0.44, 2.2))
    assert faces_to_people([(0, 0, 0, 0)], 640, 500.0) == []


@pytest.mark.skipif(not CASCADE.exists(), reason="OpenCV without its Haar cascades (opencv-python-headless<5 has them)")
def test_a_camera_only_robot_finds_a_crowd_by_faces() -> None:
    sim = NavSim("museum", camera_only_peoplebot(), START, seed=4, people=3)
    spots = [(13.4, 9.3), (13.7, 10.1), (13.5, 10.9)]  # side by side: no face hides another
    place(sim, spots)
    outcome = sim.run(DetectCrowd(), duration=5.0)
    assert outcome.name == "crowd_found", outcome.reason
    assert outcome.outputs["size"] == 3
    cx, cy = np.mean(spots, axis=0)
    # distance from a face box's height: within a few per cent at 2-3 m
    assert math.hypot(outcome.outputs["centre"][0] - cx, outcome.outputs["centre"][1] - cy) < 0.25
    sim.services.close()
