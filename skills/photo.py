"""photo: take a picture with the robot's camera and keep it in the run folder (the paper's Capture).

The frame comes from the Camera interface (the simulator's rendered view, or a real camera),
is encoded as JPEG and written with its metadata (mission time, the robot's pose, the crowd it
was taken of) as ``photos/photo-0001.jpg`` and ``photo-0001.json``, each written atomically:
a crash leaves either the whole photo or none, never half a JPEG that ``upload`` would send.
The JPEG is written first and the metadata last, so a photo whose sidecar exists is complete.
Encoding and the fsyncs run in the worker pool, so the tick never waits on the disk.

Hand ``photo`` and ``metadata`` to ``upload``; the photo machine around it (StartCamera,
PhotoReady, the countdown) is the mission's (``missions/lib/photo.yaml``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.files import write_atomically


class PhotoParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    quality: int = Field(90, ge=10, le=100, description="JPEG quality")
    folder: str = Field("photos", description="folder in the run folder the photos go to")
    max_wait: float = Field(2.0, gt=0, description="s of mission time to wait for a first frame")


def _pose(ctx: SkillContext) -> list[float] | None:
    """Where the robot thinks it is: the localiser's estimate, else odometry, else unknown."""
    try:
        if "localization" in ctx.interfaces:
            pose = ctx.interfaces["localization"].pose()
        elif "odometry" in ctx.interfaces:
            pose = ctx.interfaces["odometry"].read().pose
        else:
            return None
    except Exception:  # a pose that cannot be read does not stop the photo
        return None
    return [round(pose.x, 3), round(pose.y, 3), round(pose.theta, 4)]


def _save(frame: np.ndarray, jpeg: Path, metadata: dict[str, Any], quality: int) -> int:
    """Blocking, in the worker pool: encode, then write the JPEG and its sidecar atomically."""
    import cv2  # OpenCV loads only for a run that takes photos

    ok, encoded = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError("OpenCV could not encode the frame as JPEG")
    data = encoded.tobytes()
    write_atomically(jpeg, data, sync_folder=False)
    write_atomically(jpeg.with_suffix(".json"), (json.dumps(metadata, indent=2) + "\n").encode())
    return len(data)


def check_frame(frame: Any) -> np.ndarray:
    """The frame as an 8-bit BGR (or grey) image, or ValueError saying what is wrong with it."""
    if not isinstance(frame, np.ndarray):
        raise ValueError(f"the camera gave {type(frame).__name__}, not an image")
    if frame.dtype != np.uint8:
        raise ValueError(f"the camera gave {frame.dtype} pixels, not 8-bit")
    if frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] not in (1, 3)) or min(frame.shape[:2]) < 1:
        raise ValueError(f"the camera gave an array of shape {frame.shape}, not an image")
    return frame


class Photo(Skill):
    name = "photo"
    description = "Take a picture with the camera and save it with its metadata in the run folder (JPEG)."
    inputs = {
        "crowd_id": In(int, default=0, doc="the crowd it is a picture of (0: none), kept in the metadata"),
        "caption": In(str, default="", doc="a line shown beside the photo in the gallery"),
    }
    outputs = {
        "photo": Out(str, doc="path of the JPEG file, relative to the run folder (`upload` takes it as it is)"),
        "metadata": Out(dict[str, Any], doc="time, pose, crowd id and size: hand it to `upload` with the photo"),
    }
    Params = PhotoParams

    def run(self, ctx: SkillContext, crowd_id: int, caption: str) -> SkillRun:
        params: PhotoParams = self.params  # type: ignore[assignment]
        camera = ctx.interface("camera")
        files = ctx.interface("files")
        deadline = ctx.clock.now() + params.max_wait
        frame = camera.frame()
        while frame is None:  # a real camera may not have delivered its first frame yet
            if ctx.clock.now() >= deadline:
                return Outcome.failure(f"the camera gave no frame within {params.max_wait:g} s")
            yield
            frame = camera.frame()
        try:
            frame = np.array(check_frame(frame))  # a copy: the camera may reuse its buffer
        except ValueError as error:
            return Outcome.failure(str(error))
        t = ctx.clock.now()
        jpeg = files.numbered(params.folder, "photo", ".jpg")
        metadata: dict[str, Any] = {
            "file": jpeg.name,
            "t": round(t, 3),
            "pose": _pose(ctx),
            "crowd_id": crowd_id,
            "width": int(frame.shape[1]),
            "height": int(frame.shape[0]),
        }
        if caption:
            metadata["caption"] = caption
        try:
            size = yield ctx.submit(_save, frame, jpeg, metadata, params.quality)
        except OSError as error:  # disk full, folder not writable
            return Outcome.failure(f"cannot save {jpeg.name}: {error}")
        except ValueError as error:
            return Outcome.failure(str(error))
        where = "" if metadata["pose"] is None else " at ({:.2f}, {:.2f})".format(*metadata["pose"][:2])
        ctx.logger.info(f"took {jpeg.name} ({size / 1024:.0f} KiB){where}")
        # relative: the trace of a run is the same wherever its folder is
        return Outcome.success(photo=str(jpeg.relative_to(files.folder)), metadata=metadata)
