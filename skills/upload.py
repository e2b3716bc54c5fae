"""upload: put a photo in the run's outbox and let it go to the gallery in the background.

The photo is copied into a durable outbox (``botstage.skills.outbox``) and the skill returns ``queued``
as soon as it is safely on disk, in a tick or so; a worker then uploads it while the mission goes
on, retrying with backoff if the gallery is down, and never twice. With ``wait: true`` the skill
runs until the gallery has it (``uploaded``), refused it (``rejected``) or ``timeout`` seconds of
mission time passed; a later ``upload`` of the same photo with ``wait: true`` waits for the
earlier one, since a photo's identity is its content hash.

Where it uploads is the skill's parameters (``skill_params: {upload: {endpoint: ...}}``); with
no endpoint the run starts a gallery of its own. The outbox comes from the run's ``uploads``
interface, so every node shares it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.outbox.settings import OutboxSettings

SHOWN_STATES = {"pending": "queued", "uploaded": "uploaded", "rejected": "rejected", "damaged": "damaged"}


class UploadParams(OutboxSettings):
    """Where and how the run's outbox uploads (shared by every node with the same settings)."""


def _open_and_record(
    uploads: Any, settings: OutboxSettings, photo: str, metadata: dict[str, Any], run_folder: Path | None
) -> tuple[Any, Any]:
    """Blocking, in the worker pool: open the outbox (the first time), copy the photo in, fsync."""
    if run_folder is not None and not Path(photo).is_absolute() and (run_folder / photo).is_file():
        photo = str(run_folder / photo)  # what `photo` took in this run
    outbox = uploads.outbox(settings)
    return outbox, outbox.record(photo, metadata)


class Upload(Skill):
    name = "upload"
    description = "Queue a photo for the gallery in a durable outbox (`queued`); with `wait`, until it is `uploaded`."
    inputs = {
        "photo": In(str, doc="path of a JPEG or PNG file (a relative one is looked for in the run folder first)"),
        "metadata": In(dict[str, Any], default={}, doc="JSON values shown beside the photo in the gallery"),
        "wait": In(bool, default=False, doc="run until the gallery has it (false: return once it is queued)"),
        "timeout": In(Seconds, default=60.0, doc="with wait: s of mission time before giving up waiting"),
    }
    outputs = {
        "photo_id": Out(str, doc="the photo's SHA-256: its identity in the outbox and the gallery"),
        "status": Out(str, doc="queued, uploaded, rejected or damaged"),
    }
    outcomes = ("queued", "uploaded", "rejected", "timeout")
    success_outcomes = ("queued", "uploaded")
    Params = UploadParams

    def run(self, ctx: SkillContext, photo: str, metadata: dict[str, Any], wait: bool, timeout: float) -> SkillRun:
        if wait and timeout < 0:
            return Outcome.failure(f"timeout must not be negative, got {timeout}")
        uploads = ctx.interface("uploads")
        files = ctx.interfaces.get("files")
        run_folder = files.folder if files is not None else None
        try:
            outbox, item = yield ctx.submit(_open_and_record, uploads, self.params, photo, metadata, run_folder)
        except Exception as error:  # missing, not an image, metadata not JSON, no endpoint, disk full
            return Outcome.failure(f"cannot queue {photo}: {error}")
        ctx.logger.info(f"queued {item.name} ({item.hash[:12]})")
        deadline = ctx.clock.now() + timeout
        # without wait, the answer is the photo's state when it was recorded (pending: queued), never a
        # race with the worker; a photo the outbox already had may be uploaded or refused by then
        while True:
            status = SHOWN_STATES[item.state]
            if item.state == "uploaded":
                return Outcome("uploaded", "", {"photo_id": item.hash, "status": status})
            if item.state in ("rejected", "damaged"):
                return Outcome("rejected", item.last_error, {"photo_id": item.hash, "status": status})
            if not wait:
                return Outcome("queued", "", {"photo_id": item.hash, "status": status})
            if ctx.clock.now() >= deadline:
                why = f" (last attempt: {item.last_error})" if item.last_error else ""
                return Outcome(
                    "timeout", f"not uploaded within {timeout:g} s{why}", {"photo_id": item.hash, "status": status}
                )
            yield
            item = outbox.status(item.hash)
