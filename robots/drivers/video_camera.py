"""A real camera behind the Camera interface: OpenCV's ``VideoCapture`` (a USB camera's index,
a device path, a video file or a stream URL).

``VideoCapture.read`` blocks until the next frame (33 ms at 30 fps, seconds for a camera that
hangs), which a tick must never do, so a reader thread keeps the latest frame and ``frame()``
returns it at once: ``None`` before the first one. A camera that stops delivering is reopened
with backoff; a video file that ends is played from the start again when ``loop`` is set (for
tests and demos), else the last frame stays.
"""

from __future__ import annotations

import logging
import threading
import time

import cv2
import numpy as np

from botstage.robots.interfaces import CameraInfo

_log = logging.getLogger("botstage.drivers.camera")


class VideoCaptureCamera:
    def __init__(
        self,
        source: int | str = 0,
        *,
        horizontal_fov: float = 1.085,
        width: int | None = None,
        height: int | None = None,
        loop: bool = False,
        reopen_after: float = 1.0,
    ) -> None:
        self.source = source
        self.loop = loop
        self.reopen_after = reopen_after
        self.frames_read = 0
        self.reopened = 0
        self._latest: np.ndarray | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._capture = self._open(width, height)
        if not self._capture.isOpened():
            raise ConnectionError(f"OpenCV cannot open the camera {source!r}")
        w = int(self._capture.get(cv2.CAP_PROP_FRAME_WIDTH)) or (width or 640)
        h = int(self._capture.get(cv2.CAP_PROP_FRAME_HEIGHT)) or (height or 480)
        self.info = CameraInfo(w, h, horizontal_fov)
        self._width, self._height = width, height
        self._thread = threading.Thread(target=self._read_frames, name=f"camera-{source}", daemon=True)
        self._thread.start()

    def _open(self, width: int | None, height: int | None) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(self.source)
        if width:
            capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        if height:
            capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        return capture

    def frame(self) -> np.ndarray | None:
        """The latest BGR frame (read-only; copy it to draw on it), or None before the first."""
        with self._lock:
            return self._latest

    def _read_frames(self) -> None:
        delay = self.reopen_after
        while not self._stop.is_set():
            ok, image = self._capture.read()
            if ok and image is not None:
                image.setflags(write=False)
                with self._lock:
                    self._latest = image
                self.frames_read += 1
                delay = self.reopen_after
                continue
            if self.loop and self.frames_read and self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0):
                continue  # a video file ended: from the start
            if isinstance(self.source, str) and self.frames_read and not self.loop:
                self._stop.wait(0.1)  # a file that ended keeps its last frame
                continue
            _log.warning("camera %r gave no frame; reopening in %.1f s", self.source, delay)
            if self._stop.wait(delay):
                break
            self._capture.release()
            self._capture = self._open(self._width, self._height)
            self.reopened += 1
            delay = min(delay * 2, 30.0)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self._capture.release()

    def __enter__(self) -> VideoCaptureCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def wait_for_frame(camera: VideoCaptureCamera, timeout: float = 5.0) -> np.ndarray | None:
    """The first frame, waiting up to ``timeout`` s of wall time (for start-up checks, not ticks)."""
    deadline = time.monotonic() + timeout
    while camera.frame() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return camera.frame()
