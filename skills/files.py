"""Files a skill leaves behind: written whole or not at all, into the run's folder.

A crash or a pulled plug mid-write must not leave half a photo that an uploader, a report or a
person then trusts. ``write_atomically`` writes a temporary file beside the target, fsyncs it,
renames it over the target and fsyncs the folder, so the name only ever points at complete bytes.

``RunFiles`` is the ``files`` interface the runner hands to skills: the run folder, and names
in it that no other write of the run has taken.
"""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path


def fsync_dir(folder: Path) -> None:
    """Make a rename or a new file in ``folder`` durable (the directory entry itself)."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_atomically(path: Path, data: bytes, *, sync_folder: bool = True) -> None:
    """``path`` holds ``data`` entirely, or keeps what it held before; never a part of it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(data)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    if sync_folder:
        fsync_dir(path.parent)


class RunFiles:
    """The run's folder, as skills see it (``ctx.interface("files")``)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder).resolve()
        self._taken: dict[str, int] = {}
        self._lock = threading.Lock()

    def numbered(self, subfolder: str, stem: str, suffix: str) -> Path:
        """A new path ``subfolder/stem-0001suffix``, ``-0002``, …: never one that exists or was given."""
        target = (self.folder / subfolder).resolve()
        if not target.is_relative_to(self.folder):
            raise ValueError(f"{subfolder!r} is outside the run folder")
        with self._lock:
            key = str(target / stem)
            number = self._taken.get(key, 0)
            while True:
                number += 1
                path = target / f"{stem}-{number:04d}{suffix}"
                if not path.exists():
                    self._taken[key] = number
                    return path
