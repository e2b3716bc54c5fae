"""The face tracker (the book's chapter 2) on the simulated head, each figure beside a baseline
measured in the same run. Run with `python -m tests.bench facetracker`.

The head is ``robots/profiles/face_tracker.yaml`` in the simulator: the webcam (640x480, 0.87 rad
across, 30 fps) rides on the AX-12A pan joint (1.17 rad/s) at the museum hall's centre, and a
visitor walks across the hall 2 m in front of it. The tracker is the ``track_face`` skill itself,
stepped on the sim clock a frame a tick (every frame is analysed). Where the face is comes from the
simulator's truth (the person's place, the camera's pose and the pan's exact angle through the
pinhole model), not from the detector: the error is what the image shows, detector misses
included. Seeded: the same figures every run but for the timings.

- **detection**: frames per second of the chapter's detector (grey, equalised, scale 1.1, 15
  neighbours, 30x30 px at least, aspect 0.75-1.3) on 640x480 frames of a walk across the view,
  beside OpenCV's plain ``detectMultiScale`` with its defaults on the same grey frames (scale 1.1, 3
  neighbours, no smallest size, no equalisation, no aspect check) with the same cascade: what the
  chapter's parameters cost or save, and what they buy (hits on frames that show a face, boxes
  that are not the face); and the chapter's without its histogram equalisation, which is where
  its cost goes. Target: the webcam's 30 fps.
- **walk**: the face's pixel error from the image centre (mean and p95 of |x - 320|) while the
  visitor crosses the tracker's reach (their bearing within the controller's ±0.5 rad) at 0.5 and
  1 m/s, the chapter's fixed step against the proportional step; and the share of those frames
  with the face in the dead band (270-370 px).
- **recentre**: a visitor stands still with the face 60 px from the image's edge (left, then
  right) when the tracker starts: the time from its start (loading the cascade and the first
  frame's detection included: two frames) until the face is in the dead band, and how often it
  leaves the band again in the 4 s watched (overshoot), fixed against proportional.

Each figure is printed as one JSON line.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from botstage.robots.backend import ScriptedWalk
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import CameraInfo
from botstage.robots.places import robot_place
from botstage.robots.sim.backend import SimBackend
from botstage.skills.base import SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.perception.face_tracking import FaceDetector
from botstage.skills.testing import DictBoard
from botstage.skills.track_face import TrackFace
from botstage.skills.workers import Workers
from tests.bench.bench_serial import percentile

RATE_HZ = 30.0  # the webcam's frame rate: a frame a tick
SEED = 1
AHEAD = 2.0  # m from the camera to the walker's line
HEAD = (11.0, 10.0)  # the museum hall's centre, facing +x
TARGET_FPS = 30.0
MODES = ("fixed", "proportional")


@dataclass
class Head:
    """The simulated face tracker with people in front of it, stepped a tick at a time."""

    walks: list[ScriptedWalk]
    backend: SimBackend = field(init=False)
    clock: SimClock = field(init=False)

    def __post_init__(self) -> None:
        profile, grid, pose = robot_place("face_tracker", "museum", "hall_centre")
        self.clock = SimClock(RATE_HZ)
        self.backend = SimBackend(profile, grid, pose, SEED, self.clock, walks=self.walks)
        self.camera = self.backend.devices["camera"]
        self.pan = self.backend.devices["pan"]

    def tick(self) -> None:
        self.clock.next_tick()
        self.backend.step()

    def face_x(self) -> float | None:
        """Where the first person's face is in the image now (the truth), or None behind the camera."""
        person = self.backend.crowd.people[0]
        x, y, heading = self.camera.view.camera_pose(self.backend.world, self.pan.angle)
        dx, dy = person.x - x, person.y - y
        forward = dx * math.cos(heading) + dy * math.sin(heading)
        right = dx * math.sin(heading) - dy * math.cos(heading)
        if forward <= 0.1:
            return None
        return self.camera.info.width / 2 + self.camera.view.focal * right / forward

    def bearing(self) -> float:
        """The first person's bearing from the head (rad, positive left), whatever the pan does."""
        person = self.backend.crowd.people[0]
        return math.atan2(person.y - HEAD[1], person.x - HEAD[0])


def run_tracker(
    head: Head, mode: str, seconds: float, each_tick: Callable[[Head], None], lost_after: float = 1.0
) -> dict[str, Any]:
    """``track_face`` on the head for ``seconds`` of sim time; ``each_tick`` looks after every tick."""
    skill = TrackFace({"mode": mode})
    workers = Workers()
    ctx = SkillContext(
        clock=head.clock,
        params=skill.params,
        logger=SkillLogger("track_face"),
        blackboard=DictBoard(),
        workers=workers,
        interfaces={"camera": head.camera, "pan": head.pan},
    )
    execution = SkillExecution(skill, ctx)
    outcome = execution.start({"duration": seconds, "lost_after": lost_after})
    try:
        while outcome is None:
            workers.drain()
            head.tick()
            outcome = execution.step()
            each_tick(head)
    finally:
        execution.cancel()
        workers.shutdown()
    assert outcome.name == "success", outcome.reason
    return dict(outcome.outputs)


# -- detection ----------------------------------------------------------------------------------


def _walk_frames(count: int) -> tuple[list[np.ndarray], list[float | None]]:
    """``count`` frames of a visitor crossing the view (pan at 0), with where their face truly is."""
    head = Head([ScriptedWalk(((13.0, 11.2), (13.0, 8.8)), speed=1.0)])
    ticks = round(2.4 / 1.0 * RATE_HZ)
    frames: list[np.ndarray] = []
    truth: list[float | None] = []
    for n in range(ticks):
        head.tick()
        if n % max(1, ticks // count) == 0 and len(frames) < count:
            frames.append(head.camera.frame())
            x = head.face_x()
            truth.append(x if x is not None and 0 <= x < head.camera.info.width else None)
    return frames, truth


def bench_detection(count: int, repeats: int) -> dict[str, Any]:
    frames, truth = _walk_frames(count)
    detector = FaceDetector()
    cascade = detector.cascade

    p = detector.params

    def chapter(frame: np.ndarray) -> list[tuple[int, int, int, int]]:
        return detector.faces(frame)

    def not_equalised(frame: np.ndarray) -> list[tuple[int, int, int, int]]:
        grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        boxes: Any = cascade.detectMultiScale(
            grey, scaleFactor=p.scale_factor, minNeighbors=p.min_neighbours, minSize=(p.min_size, p.min_size)
        )
        return [tuple(int(v) for v in box) for box in boxes]  # type: ignore[misc]

    def defaults(frame: np.ndarray) -> list[tuple[int, int, int, int]]:
        boxes: Any = cascade.detectMultiScale(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        return [tuple(int(v) for v in box) for box in boxes]  # type: ignore[misc]

    detectors = {"chapter": chapter, "not_equalised": not_equalised, "defaults": defaults}
    best = dict.fromkeys(detectors, math.inf)
    per_frame: dict[str, list[float]] = {name: [] for name in detectors}
    for _ in range(repeats):  # interleaved, so each sees the same load
        for name, detect in detectors.items():
            times = []
            for frame in frames:
                began = time.perf_counter()
                detect(frame)
                times.append(time.perf_counter() - began)
            if sum(times) < best[name]:
                best[name], per_frame[name] = sum(times), times
    quality = {name: _quality(detect, frames, truth) for name, detect in detectors.items()}
    fps = {name: len(frames) / best[name] for name in best}
    return {
        "bench": "facetracker_detection",
        "frames": len(frames),
        "frames_with_a_face": sum(x is not None for x in truth),
        "chapter_fps": round(fps["chapter"], 1),
        "chapter_ms_p50": round(statistics.median(per_frame["chapter"]) * 1000, 1),
        "chapter_ms_p95": round(percentile(per_frame["chapter"], 95) * 1000, 1),
        "opencv_defaults_fps": round(fps["defaults"], 1),
        "opencv_defaults_ms_p50": round(statistics.median(per_frame["defaults"]) * 1000, 1),
        "ratio_chapter_vs_defaults": round(fps["chapter"] / fps["defaults"], 2),
        "chapter_not_equalised_fps": round(fps["not_equalised"], 1),
        "chapter_hits": quality["chapter"][0],
        "chapter_false_boxes": quality["chapter"][1],
        "chapter_not_equalised_hits": quality["not_equalised"][0],
        "opencv_defaults_hits": quality["defaults"][0],
        "opencv_defaults_false_boxes": quality["defaults"][1],
        "target_fps": TARGET_FPS,
        "meets_target": fps["chapter"] >= TARGET_FPS,
    }


def _quality(
    detect: Callable[[np.ndarray], list[tuple[int, int, int, int]]], frames: list[np.ndarray], truth: list[float | None]
) -> tuple[int, int]:
    """Frames whose face a box covers, and boxes that cover no face."""
    hits = false = 0
    for frame, x in zip(frames, truth, strict=True):
        boxes = detect(frame)
        covering = [b for b in boxes if x is not None and b[0] <= x <= b[0] + b[2]]
        hits += bool(covering)
        false += len(boxes) - len(covering)
    return hits, false


# -- the walk -----------------------------------------------------------------------------------


def bench_walk(speeds: tuple[float, ...]) -> dict[str, Any]:
    rows: dict[str, Any] = {"bench": "facetracker_walk", "ahead_m": AHEAD}
    reach = 0.5  # rad: the controller's limits: a face further round cannot be centred
    side = AHEAD * math.tan(reach + 0.04)  # start and end just outside the reach
    for speed in speeds:
        for mode in MODES:
            # the visitor stands 2 s at the right end of the reach (the tracker finds them), then crosses
            head = Head([ScriptedWalk(((13.0, HEAD[1] - side), (13.0, HEAD[1] + side)), speed=speed, at=2.0)])
            head.pan.move_to(-reach)  # looking at them already: the error measures following, not finding
            while head.pan.moving:
                head.tick()
            errors: list[float] = []
            centred: list[bool] = []

            def look(head: Head, errors: list[float] = errors, centred: list[bool] = centred) -> None:
                if head.clock.now() > 2.0 and abs(head.bearing()) <= reach:
                    x = head.face_x()  # beyond the image when the tracker has fallen behind: still an error
                    error = abs(x - head.camera.info.width / 2) if x is not None else math.inf
                    errors.append(error)
                    centred.append(error <= 50)

            outputs = run_tracker(head, mode, 2.0 + 2 * side / speed + 0.5, look)
            key = f"{mode}_{speed:g}mps"
            rows[f"{key}_error_mean_px"] = round(statistics.fmean(errors), 1)
            rows[f"{key}_error_p95_px"] = round(percentile(errors, 95), 1)
            rows[f"{key}_in_dead_band"] = round(sum(centred) / len(centred), 3)
            rows[f"{key}_frames_with_a_detection"] = round(outputs["detections"] / outputs["frames"], 3)
        fixed, proportional = (rows[f"{m}_{speed:g}mps_error_mean_px"] for m in MODES)
        rows[f"ratio_mean_error_proportional_vs_fixed_{speed:g}mps"] = round(proportional / fixed, 2)
    return rows


# -- re-centring --------------------------------------------------------------------------------


def bench_recentre(sides: tuple[str, ...] = ("left", "right"), seconds: float = 4.0) -> dict[str, Any]:
    rows: dict[str, Any] = {"bench": "facetracker_recentre", "edge_px": 60, "watched_s": seconds}
    for side in sides:
        sign = 1.0 if side == "left" else -1.0
        for mode in MODES:
            angle = sign * math.atan((320 - 60) / _focal())  # the face 60 px from that edge
            spot = (HEAD[0] + AHEAD * math.cos(angle), HEAD[1] + AHEAD * math.sin(angle))
            head = Head([ScriptedWalk((spot, spot), speed=1.0, at=1e6)])  # standing there throughout
            inside: list[float] = []
            leaves: list[float] = []

            def look(head: Head, inside: list[float] = inside, leaves: list[float] = leaves) -> None:
                x = head.face_x()
                centred = x is not None and abs(x - head.camera.info.width / 2) <= 50
                if centred and not inside:
                    inside.append(head.clock.now())
                elif inside and not centred:
                    leaves.append(head.clock.now())

            run_tracker(head, mode, seconds, look, lost_after=10.0)  # no sweep: the face is there
            key = f"{mode}_{side}"
            rows[f"{key}_s"] = round(inside[0], 3) if inside else None
            rows[f"{key}_frames"] = round(inside[0] * RATE_HZ) if inside else None
            rows[f"{key}_band_exits"] = len(leaves)  # overshoots: out of the band again once in it
    fixed = statistics.fmean(rows[f"fixed_{s}_s"] for s in sides)
    proportional = statistics.fmean(rows[f"proportional_{s}_s"] for s in sides)
    rows["ratio_proportional_vs_fixed"] = round(proportional / fixed, 2)
    return rows


def _focal() -> float:
    """The webcam's focal length in pixels, from the profile."""
    profile, _grid, _pose = robot_place("face_tracker", "museum", "hall_centre")
    camera = profile.interfaces["camera"]
    return CameraInfo(camera.width or 640, camera.height or 480, camera.field_of_view or 1.0).focal_px


def missed(results: list[dict[str, Any]]) -> list[str]:
    return [r["bench"] for r in results if r.get("meets_target") is False]


def main(quick: bool = False) -> list[dict[str, Any]]:
    results: list[dict[str, Any]] = []
    for measure in (
        lambda: bench_detection(6 if quick else 48, 1 if quick else 3),
        lambda: bench_walk((1.0,) if quick else (0.5, 1.0)),
        lambda: bench_recentre(("left",), 2.0) if quick else bench_recentre(),
    ):
        result = measure()
        results.append(result)
        print(json.dumps(result), flush=True)
    return results
