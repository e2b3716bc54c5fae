"""People from a camera alone: OpenCV's Haar frontal-face cascade, distance from the box's height
through the pinhole model, so a robot with only a camera can detect crowds.

A detected face box of height ``h`` pixels at focal length ``f`` pixels is ``f * face / h`` metres
ahead (``face``: the physical height the cascade's box spans on a face, 0.22 m by default:
measured on the simulator's 15 cm-wide faces, 0.20-0.24 m from 1.5 to 4 m; the box takes in
forehead and chin with a margin), and ``(u - cx) * z / f`` to the right.

Detection costs tens of milliseconds a frame, so it runs on its own thread, one frame behind,
as a detector node would: ``people()`` returns the last finished detection and starts the next
on the newest frame. On a simulated clock it waits for the detection in flight first, so a run
is the same however fast the machine is.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from botstage.robots.interfaces import TrackedPerson

CASCADE = Path(getattr(getattr(cv2, "data", None), "haarcascades", "")) / "haarcascade_frontalface_default.xml"
FACE_HEIGHT = 0.22  # m spanned by the cascade's box on a face


def load_cascade(path: Path = CASCADE) -> cv2.CascadeClassifier:
    cascade = cv2.CascadeClassifier(str(path))
    if cascade.empty():
        raise RuntimeError(f"cannot load the face cascade {path} (OpenCV {cv2.__version__}: its Haar data is missing)")
    return cascade


def faces_to_people(
    boxes: np.ndarray | list[Any], width: int, focal_px: float, face_height: float = FACE_HEIGHT
) -> list[TrackedPerson]:
    """Face boxes (x, y, w, h in pixels) to people in the camera frame (x right, z ahead)."""
    people = []
    for left, _top, box_width, box_height in boxes:
        if box_height <= 0:
            continue
        z = focal_px * face_height / float(box_height)
        u = left + box_width / 2
        people.append(TrackedPerson(-1, float((u - width / 2) * z / focal_px), float(z)))
    return people


def detect_faces(cascade: cv2.CascadeClassifier, frame: np.ndarray, min_px: int = 12) -> np.ndarray:
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    boxes = cascade.detectMultiScale(grey, scaleFactor=1.1, minNeighbors=3, minSize=(min_px, min_px))
    return np.asarray(boxes, dtype=float).reshape(-1, 4)


class CameraPeopleTracker:
    """A PeopleTracker over a Camera (see the module). Ids are -1: the camera knows nobody; the
    people tracks give them ids."""

    def __init__(
        self,
        camera: Any,
        *,
        simulated: bool,
        face_height: float = FACE_HEIGHT,
        range_max: float = 4.5,
        cascade: cv2.CascadeClassifier | None = None,
    ) -> None:
        self.camera = camera
        self.simulated = simulated
        self.face_height = face_height
        self.range_max = range_max
        self.cascade = cascade if cascade is not None else load_cascade()
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="botstage-faces")
        self._pending: Future[list[TrackedPerson]] | None = None
        self._last: list[TrackedPerson] = []

    def _detect(self, frame: np.ndarray) -> list[TrackedPerson]:
        info = self.camera.info
        people = faces_to_people(detect_faces(self.cascade, frame), info.width, info.focal_px, self.face_height)
        return [p for p in people if p.z <= self.range_max]

    def people(self) -> list[TrackedPerson]:
        if self._pending is not None and (self.simulated or self._pending.done()):
            self._last = self._pending.result()
            self._pending = None
        if self._pending is None:
            frame = self.camera.frame()
            if frame is not None:
                self._pending = self._pool.submit(self._detect, frame.copy())
        return list(self._last)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)
