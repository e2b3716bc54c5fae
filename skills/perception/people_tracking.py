"""One robot's view of the people around it, in the map frame, kept across skills and frames.

The people tracker reports people in its own frame (x right, z ahead, as the Kinect skeleton
tracker); this service puts them on the map with the robot's pose estimate and the sensor's
mount, tracks them (``PeopleTracks``) and counts readings it had to drop (not finite). It is
updated when a skill asks, at most once per clock time; after a gap longer than ``max_gap``
(nobody asked) the old tracks are forgotten rather than predicted blindly across the gap.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from botstage.robots.clock import Clock
from botstage.robots.interfaces import Pose2D
from botstage.skills.perception.crowd import CrowdTracker
from botstage.skills.perception.tracking import PeopleTracks, TrackParams


@dataclass(frozen=True)
class PeopleFrame:
    time: float
    people: list[tuple[int, float, float]]  # confirmed track id, x, y in the map frame
    dropped: int  # readings of this frame that were not finite


def sensor_to_map(pose: Pose2D, mount: tuple[float, float, float], x: float, z: float) -> tuple[float, float]:
    """A point the sensor sees (x right, z ahead) on the map."""
    mx, my, mtheta = mount
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    sx, sy, heading = pose.x + c * mx - s * my, pose.y + s * mx + c * my, pose.theta + mtheta
    ch, sh = math.cos(heading), math.sin(heading)
    return sx + ch * z + sh * x, sy + sh * z - ch * x


def map_to_sensor(pose: Pose2D, mount: tuple[float, float, float], px: float, py: float) -> tuple[float, float]:
    """The inverse of ``sensor_to_map``: (x right, z ahead) of a map point."""
    mx, my, mtheta = mount
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    sx, sy, heading = pose.x + c * mx - s * my, pose.y + s * mx + c * my, pose.theta + mtheta
    dx, dy = px - sx, py - sy
    ch, sh = math.cos(heading), math.sin(heading)
    return sh * dx - ch * dy, ch * dx + sh * dy


class PeopleTracking:
    def __init__(
        self,
        tracker: Any,
        pose: Callable[[], Pose2D],
        mount: tuple[float, float, float],
        clock: Clock,
        params: TrackParams | None = None,
        max_gap: float = 2.0,
    ) -> None:
        self.tracker = tracker
        self.pose = pose
        self.mount = mount
        self.clock = clock
        self.tracks = PeopleTracks(params or TrackParams())
        self.max_gap = max_gap
        self.crowd_ids: Iterator[int] = itertools.count(1)  # crowd ids of the whole run
        self._crowds: dict[tuple[float, int], CrowdTracker] = {}
        self.dropped = 0
        self._frame: PeopleFrame | None = None

    def crowd_tracker(self, distance: float, min_size: int) -> CrowdTracker:
        """The run's crowd tracker for these rules: a crowd keeps its id from one skill to the next."""
        key = (distance, min_size)
        if key not in self._crowds:
            self._crowds[key] = CrowdTracker(distance, min_size, ids=self.crowd_ids)
        return self._crowds[key]

    def update(self) -> PeopleFrame:
        now = self.clock.now()
        if self._frame is not None and self._frame.time == now:
            return self._frame
        if self.tracks.time is not None and now - self.tracks.time > self.max_gap:
            self.tracks.reset()
        pose = self.pose()
        detections, dropped = [], 0
        for person in self.tracker.people():
            x, z = getattr(person, "x", math.nan), getattr(person, "z", math.nan)
            try:
                x, z = float(x), float(z)
            except (TypeError, ValueError):
                x = z = math.nan
            if not (math.isfinite(x) and math.isfinite(z)):
                dropped += 1
                continue
            mx, my = sensor_to_map(pose, self.mount, x, z)
            sensor_id = getattr(person, "id", None)
            detections.append((mx, my, sensor_id if isinstance(sensor_id, int) and sensor_id >= 0 else None))
        self.dropped += dropped
        tracks = self.tracks.update(now, detections)
        people = [(t.id, *t.position) for t in tracks]
        self._frame = PeopleFrame(now, people, dropped)
        return self._frame
