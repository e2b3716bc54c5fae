"""The outbox's durable record: each photo copied in and fsync'ed, its state in SQLite.

Nothing is acknowledged before it is on disk. ``record`` copies the photo to a temporary file
while hashing it, fsyncs it, renames it to its SHA-256 (``files/<hash>.jpg``), writes the metadata
beside it the same way (``files/<hash>.json``), fsyncs the folder, and only then commits the row
(WAL journal, ``synchronous=FULL``). A crash at any point leaves one of: nothing; a stray
temporary file (removed on open); a photo and its sidecar without a row (adopted on open, so a
photo whose recording was cut short is still uploaded); or the full record.

The content hash is the photo's identity: recording the same photo twice gives the same entry,
and it is the idempotency key the gallery deduplicates on. A damaged database is moved aside
and rebuilt from the sidecars (every photo is queued again; the gallery drops those it has).
A photo whose copy no longer matches its hash is repaired from where it was recorded, if that
still matches, else marked ``damaged`` rather than sent.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import sqlite3
import threading
import uuid
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from botstage.skills.files import fsync_dir
from botstage.skills.outbox.images import HEAD_BYTES, sniff

PENDING = "pending"
UPLOADED = "uploaded"
REJECTED = "rejected"  # the gallery refused the photo itself (not an image, too large): never retried
DAMAGED = "damaged"  # the outbox's copy is damaged and the original is gone or changed
STATES = (PENDING, UPLOADED, REJECTED, DAMAGED)

DB_NAME = "outbox.sqlite"
_CHUNK = 1 << 20
_SCHEMA = """
CREATE TABLE IF NOT EXISTS photos (
    hash TEXT PRIMARY KEY,
    file TEXT NOT NULL,
    name TEXT NOT NULL,
    source TEXT NOT NULL,
    size INTEGER NOT NULL,
    metadata TEXT NOT NULL,
    state TEXT NOT NULL,
    attempts INTEGER NOT NULL DEFAULT 0,
    last_error TEXT NOT NULL DEFAULT '',
    recorded_at TEXT NOT NULL,
    uploaded_at TEXT
)
"""


class OutboxError(Exception):
    """A photo cannot be recorded (missing, not an image, metadata not JSON); nothing was kept."""


@dataclass(frozen=True, slots=True)
class Item:
    """One photo in the outbox."""

    hash: str
    file: Path  # the outbox's own copy
    name: str  # the original file name, sent to the gallery
    source: str  # where it was recorded from
    size: int
    metadata: dict[str, Any] = field(hash=False)
    state: str = PENDING
    attempts: int = 0
    last_error: str = ""


def _write_durably(path: Path, data: bytes, tmp_folder: Path) -> None:
    tmp = tmp_folder / f"{uuid.uuid4().hex}.part"
    with tmp.open("wb") as out:
        out.write(data)
        out.flush()
        os.fsync(out.fileno())
    os.replace(tmp, path)


def _now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")  # for people reading the outbox, never for logic


def _hash_file(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        while chunk := f.read(_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


class OutboxStore:
    """The photos and their states in one folder; safe to use from several threads.

    ``states`` is an in-memory copy of every photo's state, so asking where a photo is never
    waits for a commit (a tick must not block on an fsync).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.files = self.folder / "files"
        self.tmp = self.folder / "tmp"
        self.notes: list[str] = []  # what opening found and repaired, for the run's summary
        self._lock = threading.RLock()
        self._items: dict[str, Item] = {}  # recording order
        self.files.mkdir(parents=True, exist_ok=True)
        self.tmp.mkdir(exist_ok=True)
        for stray in self.tmp.iterdir():  # partial copies a crash left behind
            stray.unlink(missing_ok=True)
        self._db = self._open_db()
        self._load()
        self._adopt_orphans()

    # -- opening ----------------------------------------------------------------------------

    def _connect(self, path: Path) -> sqlite3.Connection:
        db = sqlite3.connect(path, check_same_thread=False, isolation_level=None)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.execute(_SCHEMA)
        return db

    def _open_db(self) -> sqlite3.Connection:
        path = self.folder / DB_NAME
        try:
            db = self._connect(path)
            if db.execute("PRAGMA quick_check").fetchone()[0] != "ok":
                db.close()
                raise sqlite3.DatabaseError("quick_check failed")
            return db
        except sqlite3.DatabaseError as error:
            n = 1
            while (aside := path.with_name(f"{DB_NAME}.damaged-{n}")).exists():
                n += 1
            for suffix in ("", "-wal", "-shm"):
                part = path.with_name(DB_NAME + suffix)
                if part.exists():
                    os.replace(part, aside.with_name(aside.name + suffix))
            fsync_dir(self.folder)
            self.notes.append(
                f"the outbox database was damaged ({error}): moved to {aside.name}, rebuilt from the photo files "
                "(all queued again; the gallery drops those it already has)"
            )
            return self._connect(path)

    def _load(self) -> None:
        rows = self._db.execute(
            "SELECT hash, file, name, source, size, metadata, state, attempts, last_error FROM photos ORDER BY rowid"
        )
        for h, file, name, source, size, metadata, state, attempts, last_error in rows:
            meta = json.loads(metadata)
            self._items[h] = Item(h, self.files / file, name, source, size, meta, state, attempts, last_error)

    def _adopt_orphans(self) -> None:
        """Photos on disk without a row: a crash after the copy, or a rebuilt database."""
        adopted = 0
        for sidecar in sorted(self.files.glob("*.json")):
            h = sidecar.stem
            if h in self._items:
                continue
            try:
                info = json.loads(sidecar.read_text(encoding="utf-8"))
                photo = self.files / info["file"]
                if _hash_file(photo) != h:
                    raise ValueError("the photo does not match its hash")
                self._insert(Item(h, photo, info["name"], info["source"], info["size"], info["metadata"]))
                adopted += 1
            except (OSError, ValueError, KeyError, TypeError) as error:
                self.notes.append(f"left out {sidecar.name}: {error}")
        if adopted:
            self.notes.append(f"{adopted} photo(s) found on disk without a record were queued")

    # -- recording --------------------------------------------------------------------------

    def record(self, source: str | Path, metadata: Mapping[str, Any] | None = None) -> tuple[Item, bool]:
        """Copy a photo in durably and queue it; ``(item, False)`` if it was already recorded."""
        source = Path(source)
        try:
            meta = json.loads(json.dumps(dict(metadata or {}), allow_nan=False))
        except (TypeError, ValueError) as error:
            raise OutboxError(f"metadata must be plain JSON: {error}") from None
        try:
            with source.open("rb") as f:
                head = f.read(HEAD_BYTES)
                ext = sniff(head)
                if ext is None:
                    raise OutboxError(f"{source} is not a JPEG or PNG image")
                tmp = self.tmp / f"{uuid.uuid4().hex}.part"
                digest, size = hashlib.sha256(head), len(head)
                try:
                    with tmp.open("wb") as out:
                        out.write(head)
                        while chunk := f.read(_CHUNK):
                            digest.update(chunk)
                            out.write(chunk)
                            size += len(chunk)
                        out.flush()
                        os.fsync(out.fileno())
                except BaseException:
                    tmp.unlink(missing_ok=True)
                    raise
        except FileNotFoundError:
            raise OutboxError(f"no such photo: {source}") from None
        except IsADirectoryError:
            raise OutboxError(f"{source} is a folder, not a photo") from None
        h = digest.hexdigest()
        with self._lock:
            existing = self._items.get(h)
        if existing is not None:
            tmp.unlink(missing_ok=True)
            return existing, False
        photo = self.files / f"{h}{ext}"
        os.replace(tmp, photo)
        item = Item(h, photo, source.name, str(source.resolve()), size, meta)
        sidecar = {"file": photo.name, "name": item.name, "source": item.source, "size": size, "metadata": meta}
        _write_durably(self.files / f"{h}.json", json.dumps(sidecar).encode(), self.tmp)
        fsync_dir(self.files)
        with self._lock:
            if h in self._items:  # recorded meanwhile by another thread: same content, same files
                return self._items[h], False
            self._insert(item)
        return item, True

    def _insert(self, item: Item) -> None:
        with self._lock:
            self._db.execute(
                "INSERT OR IGNORE INTO photos (hash, file, name, source, size, metadata, state, recorded_at) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (item.hash, item.file.name, item.name, item.source, item.size)
                + (json.dumps(item.metadata), PENDING, _now_iso()),
            )
            self._items[item.hash] = item

    # -- reading ----------------------------------------------------------------------------

    def get(self, h: str) -> Item | None:
        return self._items.get(h)

    def items(self) -> list[Item]:
        with self._lock:
            return list(self._items.values())

    def pending(self) -> Iterator[Item]:
        """Pending photos in recording order (a snapshot: safe while others record)."""
        return (item for item in self.items() if item.state == PENDING)

    def counts(self) -> dict[str, int]:
        counts = dict.fromkeys(STATES, 0)
        for item in self.items():
            counts[item.state] += 1
        return counts

    def read_verified(self, item: Item) -> bytes | str:
        """The photo's bytes if they still match its hash; else why not (after trying to repair)."""
        try:
            data = item.file.read_bytes()
            if hashlib.sha256(data).hexdigest() == item.hash:
                return data
            problem = "the outbox's copy does not match its hash"
        except OSError as error:
            problem = f"the outbox's copy cannot be read ({error.strerror or error})"
        try:  # the original may still be where it was recorded from
            data = Path(item.source).read_bytes()
        except OSError:
            return f"{problem}, and the original is gone"
        if hashlib.sha256(data).hexdigest() != item.hash:
            return f"{problem}, and the original has changed"
        _write_durably(item.file, data, self.tmp)
        fsync_dir(self.files)
        self.notes.append(f"repaired {item.file.name} from {item.source}")
        return data

    # -- state changes ----------------------------------------------------------------------

    def _update(self, h: str, sql: str, args: tuple[Any, ...], **changes: Any) -> Item:
        with self._lock:
            self._db.execute(sql, (*args, h))
            item = self._items[h] = dataclasses.replace(self._items[h], **changes)
            return item

    def mark_uploaded(self, h: str) -> Item:
        item = self._items[h]
        return self._update(
            h,
            "UPDATE photos SET state=?, attempts=?, last_error='', uploaded_at=? WHERE hash=?",
            (UPLOADED, item.attempts + 1, _now_iso()),
            state=UPLOADED,
            attempts=item.attempts + 1,
            last_error="",
        )

    def mark_failed_attempt(self, h: str, error: str) -> Item:
        item = self._items[h]
        return self._update(
            h,
            "UPDATE photos SET attempts=?, last_error=? WHERE hash=?",
            (item.attempts + 1, error),
            attempts=item.attempts + 1,
            last_error=error,
        )

    def mark_final(self, h: str, state: str, reason: str) -> Item:
        """A photo that will never be sent: rejected by the gallery, or damaged."""
        assert state in (REJECTED, DAMAGED)
        item = self._items[h]
        return self._update(
            h,
            "UPDATE photos SET state=?, attempts=?, last_error=? WHERE hash=?",
            (state, item.attempts + 1, reason),
            state=state,
            attempts=item.attempts + 1,
            last_error=reason,
        )

    def close(self) -> None:
        with self._lock, contextlib.suppress(sqlite3.Error):
            self._db.close()
