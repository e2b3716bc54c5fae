"""photo (frames saved whole with their metadata) and display (the layout supervisor)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from botstage.robots.interfaces import CameraInfo, Pose2D
from botstage.robots.sim.devices import SimDisplay
from botstage.skills.display import LAYOUTS, Display
from botstage.skills.files import RunFiles, write_atomically
from botstage.skills.photo import Photo
from tests.test_converse import Harness


class Camera:
    """Frames handed out in turn (None: not yet)."""

    def __init__(self, *frames: Any) -> None:
        self.info = CameraInfo(64, 48, 1.0)
        self.frames = list(frames)

    def frame(self) -> Any:
        return self.frames.pop(0) if len(self.frames) > 1 else self.frames[0]


class Localization:
    def pose(self) -> Pose2D:
        return Pose2D(1.25, -2.5, 0.5)


def picture(seed: int = 0) -> np.ndarray:
    """A smooth picture (JPEG keeps it close), different for each seed."""
    rows, cols = np.mgrid[0:48, 0:64]
    return np.stack([rows * 5, cols * 4, (rows + cols + 20 * seed) % 256], axis=2).astype(np.uint8)


@pytest.fixture
def harness(tmp_path: Path) -> Iterator[Harness]:
    made = Harness({"files": RunFiles(tmp_path), "localization": Localization()})
    yield made
    made.close()


# -- photo -------------------------------------------------------------------------------------


def test_a_photo_is_a_jpeg_with_its_metadata_beside_it(harness: Harness, tmp_path: Path) -> None:
    frame = picture()
    harness.interfaces["camera"] = Camera(frame)
    outcome, _ = harness.run(Photo(), crowd_id=7, caption="hello")
    assert outcome.name == "success", outcome.reason
    assert outcome.outputs["photo"] == "photos/photo-0001.jpg"  # in the run folder
    path = tmp_path / outcome.outputs["photo"]
    decoded = cv2.imread(str(path))
    assert decoded.shape == frame.shape
    assert np.abs(decoded.astype(int) - frame).mean() < 3  # JPEG is lossy, but it is the same picture
    metadata = json.loads(path.with_suffix(".json").read_text())
    assert metadata == outcome.outputs["metadata"]
    assert metadata["pose"] == [1.25, -2.5, 0.5]
    assert (metadata["crowd_id"], metadata["caption"], metadata["width"], metadata["height"]) == (7, "hello", 64, 48)
    assert not list((tmp_path / "photos").glob(".*"))  # no temporary files left


def test_photos_are_numbered_and_never_overwrite_one_already_there(harness: Harness, tmp_path: Path) -> None:
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "photo-0001.jpg").write_bytes(b"from an earlier run")
    harness.interfaces["camera"] = Camera(picture(1))
    names = [Path(harness.run(Photo())[0].outputs["photo"]).name for _ in range(2)]
    assert names == ["photo-0002.jpg", "photo-0003.jpg"]
    assert (tmp_path / "photos" / "photo-0001.jpg").read_bytes() == b"from an earlier run"


def test_it_waits_for_a_first_frame_then_gives_up_with_a_reason(harness: Harness) -> None:
    harness.interfaces["camera"] = Camera(None, None, picture())
    outcome, ticks = harness.run(Photo())
    assert outcome.name == "success" and ticks >= 2
    harness.interfaces["camera"] = Camera(None)
    outcome, ticks = harness.run(Photo())
    assert outcome.name == "failure"
    assert "no frame within 2 s" in outcome.reason
    assert ticks == 20  # 2 s of mission time at 10 Hz


@pytest.mark.parametrize(
    ("frame", "reason"),
    [
        ("not an image", "not an image"),
        (np.zeros((48, 64, 3), dtype=np.float32), "float32 pixels, not 8-bit"),
        (np.zeros((48, 64, 4), dtype=np.uint8), "shape (48, 64, 4)"),
        (np.zeros((0, 64, 3), dtype=np.uint8), "shape (0, 64, 3)"),
    ],
)
def test_a_bad_frame_fails_with_what_is_wrong(harness: Harness, tmp_path: Path, frame: Any, reason: str) -> None:
    harness.interfaces["camera"] = Camera(frame)
    outcome, _ = harness.run(Photo())
    assert outcome.name == "failure"
    assert reason in outcome.reason
    assert not (tmp_path / "photos").exists() or not list((tmp_path / "photos").iterdir())


def test_a_disk_that_refuses_the_write_fails_the_skill_not_the_mission(
    harness: Harness, monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(*_args: Any, **_kwargs: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("botstage.skills.photo.write_atomically", full)
    harness.interfaces["camera"] = Camera(picture())
    outcome, _ = harness.run(Photo())
    assert outcome.name == "failure"
    assert "cannot save photo-0001.jpg" in outcome.reason and "No space left" in outcome.reason


def test_an_interrupted_write_leaves_the_old_file_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "a.json"
    write_atomically(target, b"old")

    def fail(*_args: Any) -> None:
        raise OSError("disk pulled")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk pulled"):
        write_atomically(target, b"new and longer")
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_run_files_refuse_a_folder_outside_the_run(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="outside the run folder"):
        RunFiles(tmp_path / "run").numbered("../elsewhere", "photo", ".jpg")


# -- display -----------------------------------------------------------------------------------


def test_the_supervisor_shows_each_new_layout_once_and_keeps_the_face_on_a_typo(harness: Harness) -> None:
    screen = SimDisplay(harness.clock)
    harness.interfaces["display"] = screen
    run = harness.execution(Display())
    assert run.start({}) is None
    board = run.ctx.blackboard
    script = {3: "Layout_5", 6: "Layout_5", 8: "Layout_9", 10: 42, 12: "", 14: "Layout_2"}
    for tick in range(16):
        if tick in script:
            board.set("layout", script[tick])
        harness.tick()
        assert run.step() is None
    shown = [(round(t, 1), layout) for t, layout, _ in screen.shown]
    assert shown == [(0.0, "Layout_0"), (0.4, "Layout_5"), (1.3, "Layout_0"), (1.5, "Layout_2")]
    assert screen.shown[1][2] == {"meaning": LAYOUTS["Layout_5"]}
    warnings = [line for line in harness.logs if line.startswith("warning")]
    assert len(warnings) == 2 and "'Layout_9'" in warnings[0] and "42" in warnings[1]
    run.cancel()


def test_an_unknown_default_layout_fails_at_once(harness: Harness) -> None:
    harness.interfaces["display"] = SimDisplay(harness.clock)
    outcome, _ = harness.run(Display(), default="Layout_7")
    assert outcome.name == "failure" and "unknown default layout 'Layout_7'" in outcome.reason


# -- a real camera: OpenCV's VideoCapture on a video file ----------------------------------------


def test_a_photo_from_a_real_video_capture(harness: Harness, tmp_path: Path) -> None:
    from botstage.robots.drivers.video_camera import VideoCaptureCamera, wait_for_frame

    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for seed in range(5):
        writer.write(picture(seed))
    writer.release()
    with VideoCaptureCamera(str(video), loop=True) as camera:
        assert (camera.info.width, camera.info.height) == (64, 48)
        first = wait_for_frame(camera)
        assert first is not None and first.shape == (48, 64, 3)
        harness.interfaces["camera"] = camera
        outcome, _ = harness.run(Photo())
    assert outcome.name == "success", outcome.reason
    saved = cv2.imread(str(tmp_path / outcome.outputs["photo"]))
    assert min(np.abs(saved.astype(int) - picture(seed)).mean() for seed in range(5)) < 6  # one of the clip's


def test_a_camera_that_cannot_be_opened_says_which() -> None:
    from botstage.robots.drivers.video_camera import VideoCaptureCamera

    with pytest.raises(ConnectionError, match=r"cannot open the camera '/nonexistent/cam\.avi'"):
        VideoCaptureCamera("/nonexistent/cam.avi")
