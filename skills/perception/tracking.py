"""People tracked across frames in the map frame: a constant-velocity Kalman filter each
(filterpy), matched to detections by the Hungarian method with a distance gate.

Why not trust the sensor's ids: a camera detector has none, and a skeleton tracker's ids are
lost when someone is occluded for a moment; the filter keeps one id per person through short
gaps and steadies positions the sensor reports with centimetres of noise. A sensor id that
matched a track before makes that pairing cheaper, so the two agree where the sensor is right.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from filterpy.kalman import KalmanFilter


@dataclass(frozen=True)
class TrackParams:
    measurement_noise: float = 0.03  # m, one sensor reading's standard deviation
    acceleration_noise: float = 0.5  # m/s², how briskly people change pace
    gate: float = 0.6  # m: a detection farther than this from a track's prediction is not that person
    confirm_hits: int = 3  # detections before a track counts (one-frame ghosts never do)
    max_coast: float = 1.0  # s without a detection before a track is dropped
    same_id_bonus: float = 0.2  # m taken off the distance when the sensor's id matches the track's last


@dataclass
class Track:
    id: int
    kf: KalmanFilter
    hits: int = 1
    last_seen: float = 0.0
    sensor_id: int | None = None

    @property
    def position(self) -> tuple[float, float]:
        return float(self.kf.x[0, 0]), float(self.kf.x[1, 0])


@dataclass
class PeopleTracks:
    """Tracks of people in one frame of reference (the map); ``update`` once a sensor frame."""

    params: TrackParams = field(default_factory=TrackParams)
    tracks: list[Track] = field(default_factory=list)
    time: float | None = None
    next_id: int = 1

    def update(self, time: float, detections: Iterable[tuple[float, float, int | None]]) -> list[Track]:
        """Predict to ``time``, match ``detections`` (x, y, sensor id or None), start and drop
        tracks; returns the confirmed tracks."""
        dt = 0.0 if self.time is None else max(0.0, time - self.time)
        self.time = time
        if dt > 0:
            transition, noise = self._motion(dt)
            for track in self.tracks:
                track.kf.predict(F=transition, Q=noise)
        found = [d for d in detections if math.isfinite(d[0]) and math.isfinite(d[1])]
        matched_tracks: set[int] = set()
        matched_found: set[int] = set()
        if self.tracks and found:
            predicted = np.array([t.position for t in self.tracks])
            seen = np.array([(x, y) for x, y, _ in found])
            distance = np.hypot(predicted[:, None, 0] - seen[None, :, 0], predicted[:, None, 1] - seen[None, :, 1])
            same_id = np.array([[sid is not None and sid == t.sensor_id for _, _, sid in found] for t in self.tracks])
            from scipy.optimize import linear_sum_assignment  # on first use: scipy's import costs every command

            rows, cols = linear_sum_assignment(distance - self.params.same_id_bonus * same_id)
            for i, j in zip(rows, cols, strict=True):
                track, (x, y, sensor_id) = self.tracks[i], found[j]
                if distance[i, j] > self.params.gate:
                    continue
                track.kf.update(np.array([[x], [y]]))
                track.hits += 1
                track.last_seen = time
                track.sensor_id = sensor_id
                matched_tracks.add(i)
                matched_found.add(j)
        self.tracks = [
            t for i, t in enumerate(self.tracks) if i in matched_tracks or time - t.last_seen <= self.params.max_coast
        ]
        for j, (x, y, sensor_id) in enumerate(found):
            if j not in matched_found:
                self.tracks.append(Track(self.next_id, self._filter(x, y), 1, time, sensor_id))
                self.next_id += 1
        return self.confirmed()

    def confirmed(self) -> list[Track]:
        return [t for t in self.tracks if t.hits >= self.params.confirm_hits]

    def reset(self) -> None:
        """Forget every track (ids keep counting up: an id is never given to someone else)."""
        self.tracks = []
        self.time = None

    def _filter(self, x: float, y: float) -> KalmanFilter:
        from filterpy.kalman import KalmanFilter  # on first use: filterpy imports scipy.stats

        kf = KalmanFilter(dim_x=4, dim_z=2)  # x, y, vx, vy
        kf.x = np.array([[x], [y], [0.0], [0.0]])
        kf.H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
        kf.R = np.eye(2) * self.params.measurement_noise**2
        kf.P = np.diag([self.params.measurement_noise**2] * 2 + [1.0, 1.0])
        return kf

    def _motion(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Constant velocity over ``dt``, with white-noise acceleration (per axis:
        [[dt^4/4, dt^3/2], [dt^3/2, dt^2]] times its variance)."""
        transition = np.array([[1.0, 0.0, dt, 0.0], [0.0, 1.0, 0.0, dt], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        q = self.params.acceleration_noise**2
        a, b, c = dt**4 / 4 * q, dt**3 / 2 * q, dt**2 * q
        noise = np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])
        return transition, noise
