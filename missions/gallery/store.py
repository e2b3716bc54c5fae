"""The gallery's photos on disk, one per content hash, with their metadata in SQLite.

The hash is the identity: a second upload of the same bytes (an outbox resending after its
answer was lost) finds the first and adds nothing, so a photo appears once however often it is
sent. Files are written to a temporary name, fsync'ed and renamed (the same bytes under the
same name: harmless when two uploads of one photo race), then the row is committed (WAL,
``synchronous=FULL``). The row is what makes a photo visible: a crash before it leaves a file
that the next upload of that photo simply replaces.
"""

from __future__ import annotations

import json
import os
import sqlite3
import threading
import uuid
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from botstage.skills.outbox.store import fsync_dir

_SCHEMA = """
CREATE TABLE IF NOT EXISTS photos (
    hash TEXT PRIMARY KEY,
    file TEXT NOT NULL,
    name TEXT NOT NULL,
    size INTEGER NOT NULL,
    metadata TEXT NOT NULL,
    received_at TEXT NOT NULL
)
"""


@dataclass(frozen=True, slots=True)
class Photo:
    hash: str
    file: str
    name: str
    size: int
    metadata: dict[str, Any]
    received_at: str

    def public(self) -> dict[str, Any]:
        """What the JSON list shows of a photo."""
        return {
            "hash": self.hash,
            "name": self.name,
            "size": self.size,
            "metadata": self.metadata,
            "received_at": self.received_at,
            "url": f"/photos/{self.hash}",
            "thumbnail": f"/thumbs/{self.hash}",
        }


def _write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{uuid.uuid4().hex}.part")
    try:
        with tmp.open("wb") as out:
            out.write(data)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class GalleryStore:
    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.photos = self.folder / "photos"
        self.thumbs = self.folder / "thumbs"
        self.photos.mkdir(parents=True, exist_ok=True)
        self.thumbs.mkdir(exist_ok=True)
        for stray in (*self.photos.glob(".*.part"), *self.thumbs.glob(".*.part")):
            stray.unlink(missing_ok=True)
        self._db = sqlite3.connect(self.folder / "gallery.sqlite", check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.execute(_SCHEMA)
        self._lock = threading.Lock()

    def add(
        self, photo_hash: str, data: bytes, ext: str, thumb: bytes, name: str, metadata: dict[str, Any]
    ) -> tuple[Photo, bool]:
        """Store a checked photo; ``(photo, False)`` when the gallery already had these bytes."""
        existing = self.get(photo_hash)
        if existing is not None:
            return existing, False
        _write(self.photos / f"{photo_hash}{ext}", data)
        _write(self.thumbs / f"{photo_hash}.jpg", thumb)
        fsync_dir(self.photos)
        fsync_dir(self.thumbs)
        received = datetime.now(UTC).isoformat(timespec="milliseconds")
        with self._lock:
            cursor = self._db.execute(
                "INSERT OR IGNORE INTO photos (hash, file, name, size, metadata, received_at) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (photo_hash, f"{photo_hash}{ext}", name, len(data), json.dumps(metadata), received),
            )
            created = cursor.rowcount == 1
        photo = self.get(photo_hash)
        assert photo is not None
        return photo, created

    def get(self, photo_hash: str) -> Photo | None:
        with self._lock:
            row = self._db.execute(
                "SELECT hash, file, name, size, metadata, received_at FROM photos WHERE hash = ?", (photo_hash,)
            ).fetchone()
        return None if row is None else Photo(*row[:4], json.loads(row[4]), row[5])

    def list(self) -> list[Photo]:
        """Newest first."""
        with self._lock:
            rows = self._db.execute(
                "SELECT hash, file, name, size, metadata, received_at FROM photos ORDER BY rowid DESC"
            ).fetchall()
        return [Photo(*row[:4], json.loads(row[4]), row[5]) for row in rows]

    def count(self) -> int:
        with self._lock:
            return self._db.execute("SELECT COUNT(*) FROM photos").fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()
