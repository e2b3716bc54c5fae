"""The face tracker of the book's chapter 2: find the face, and turn the pan servo towards it.

**The detector** (``face_tracker_pkg``'s ``detectAndDraw``, OpenCV's face sample): the frame in
grey, its histogram equalised, OpenCV's Haar frontal-face cascade (the one the chapter's
``haarcascade_frontalface_alt.xml`` comes from; OpenCV ships it) with scale factor 1.1, 15
neighbours and faces of 30x30 pixels at least; a box counts only with a width/height ratio within
0.75-1.3. The chapter publishes every face's centroid; here the largest face is the one tracked
(decision: the nearest person; the chapter's controller takes each centroid in turn, so with two
faces it would turn back and forth between them).

**The controller** (``face_tracker_control``, ``servo_param.yaml``): a dead band
``screenmaxx / 2 ± center_offset`` (640 and 50: 270-370 px); a face left of it turns the pan
``step_distancex`` (0.01 rad) left per frame, right of it as much right, within ``servomin`` and
``servomaxx`` (±0.5 rad). Its quirks, fixed:

- at the limits it changed its position and did not send it: past a limit the position kept
  growing, unsent, frame after frame, and a face seen on the other side then had to undo all of
  that before the servo moved at all. Here the position is clamped to the limits and sent;
- its branches were ``x < 270``, ``x > 370`` and ``270 < x < 370``, so a face at exactly 270 or 370
  fell in none (harmless only because that branch did nothing). Here the dead band is closed.

Beyond the chapter: a proportional step (``gain`` rad per pixel of the face's offset from the
centre, at most ``max_step`` a frame), which re-centres a face far off faster than 0.01 rad a
frame can, as an option beside the fixed step (measured against it on the simulated head by
``python -m tests.bench facetracker``; ``skills/track_face.py`` runs both).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from botstage.skills.perception.camera_people import CASCADE, load_cascade


@dataclass(frozen=True, slots=True)
class DetectorParams:
    """The chapter's detectMultiScale arguments and its aspect-ratio check."""

    scale_factor: float = 1.1
    min_neighbours: int = 15
    min_size: int = 30
    min_aspect: float = 0.75
    max_aspect: float = 1.3


class FaceDetector:
    """The chapter's face detector on BGR frames: the tracked face's centre, or None."""

    def __init__(self, params: DetectorParams | None = None, cascade_path: Path = CASCADE) -> None:
        self.params = params or DetectorParams()
        self.cascade = load_cascade(cascade_path)

    def faces(self, frame: np.ndarray) -> list[tuple[int, int, int, int]]:
        """Every face box (x, y, w, h) the chapter would take, largest first."""
        p = self.params
        grey = cv2.equalizeHist(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        boxes: Any = self.cascade.detectMultiScale(
            grey, scaleFactor=p.scale_factor, minNeighbors=p.min_neighbours, minSize=(p.min_size, p.min_size)
        )
        kept = [tuple(int(v) for v in box) for box in boxes if p.min_aspect < box[2] / box[3] < p.max_aspect]
        return sorted(kept, key=lambda box: -box[2] * box[3])  # type: ignore[return-value]

    def centre(self, frame: np.ndarray) -> tuple[float, float] | None:
        """The centre (x, y in pixels) of the tracked face: the largest."""
        faces = self.faces(frame)
        if not faces:
            return None
        x, y, w, h = faces[0]
        return x + w / 2, y + h / 2


@dataclass
class PanController:
    """The chapter's pan control, its quirks fixed; ``gain`` > 0 makes the step proportional."""

    screen_width: int = 640
    centre_offset: int = 50
    step: float = 0.01  # rad a frame (step_distancex)
    low: float = -0.5  # rad (servomin)
    high: float = 0.5  # rad (servomaxx)
    gain: float = 0.0  # rad per pixel of offset: 0 is the chapter's fixed step
    max_step: float = 0.1  # rad a frame, for the proportional step
    position: float = 0.0

    def update(self, face_x: float | None) -> float:
        """The pan position (rad, positive to the left) to send after a frame with the face at ``face_x``."""
        if face_x is None:
            return self.position
        middle = self.screen_width / 2
        offset = face_x - middle  # positive: the face is right of the centre
        if abs(offset) <= self.centre_offset:
            return self.position  # in the dead band, its edges included
        # proportional to the offset from the centre, not from the band's edge: aimed at the edge,
        # the steps shrink towards nothing and the face creeps up to the band and sits on its edge
        move = min(self.max_step, self.gain * abs(offset)) if self.gain > 0 else self.step
        self.position += -move if offset > 0 else move  # a face on the left turns the camera left
        self.position = max(self.low, min(self.high, self.position))
        return self.position
