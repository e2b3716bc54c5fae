"""The outbox: a durable queue of photos and the worker that uploads them, behind one object.

``record`` returns once the photo is safely on disk (call it through ``ctx.submit``: it copies
and fsyncs); the upload happens later, in the background. Opening an outbox on a folder that a
crashed process left resumes its pending photos. ``status`` answers from memory at once, so a
skill can poll it every tick.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from botstage.skills.outbox.settings import OutboxSettings
from botstage.skills.outbox.store import PENDING, UPLOADED, Item, OutboxStore
from botstage.skills.outbox.worker import Backoff, UploadWorker


class Outbox:
    def __init__(
        self,
        folder: str | Path,
        endpoint: str,
        settings: OutboxSettings | None = None,
        *,
        now: Callable[[], float] = time.monotonic,
        background: bool = False,
        seed: int = 0,
        token: str | None = None,
        on_change: Callable[[Item], None] | None = None,
    ) -> None:
        """``now`` is the clock the backoff counts in; ``background`` pumps on a thread (real time
        only); otherwise the owner calls ``pump()`` and ``settle()`` (once per tick on the sim clock).
        ``token`` defaults to the environment variable the settings name; ``on_change`` hears every
        answer applied (on the pumping thread)."""
        from botstage.skills.outbox.client import GalleryClient  # httpx loads only when an outbox opens

        self.settings = settings or OutboxSettings()
        self.endpoint = endpoint
        self.store = OutboxStore(folder)
        token = token if token is not None else os.environ.get(self.settings.token_env) or None
        self.client = GalleryClient(
            endpoint,
            token,
            timeout=self.settings.request_timeout,
            connections=self.settings.concurrency,
            token_env=self.settings.token_env,
        )
        self.recorded = 0  # photos newly recorded by this process
        self.worker = UploadWorker(
            self.store,
            self.client,
            now,
            concurrency=self.settings.concurrency,
            backoff=Backoff(self.settings.backoff_initial, self.settings.backoff_max),
            seed=seed,
            on_change=on_change,
        )
        self.resumed = sum(1 for _ in self.store.pending())  # left pending by an earlier process
        if background:
            self.worker.start()

    @property
    def folder(self) -> Path:
        return self.store.folder

    def record(self, photo: str | Path, metadata: Mapping[str, Any] | None = None) -> Item:
        """Put a photo in the outbox durably (blocking: copy, fsync, commit); it is uploaded later."""
        item, created = self.store.record(photo, metadata)
        if created:
            self.recorded += 1
            self.worker.notify()
        return item

    def status(self, photo_hash: str) -> Item | None:
        return self.store.get(photo_hash)

    def pump(self) -> None:
        self.worker.pump()

    def settle(self, timeout: float | None = None) -> None:
        self.worker.settle(timeout)

    def step(self) -> None:
        """One simulated tick's worth: start what is due, wait for it, apply the answers."""
        self.worker.pump()
        self.worker.settle()

    def idle(self) -> bool:
        """Nothing to send and nothing in flight: stepping it does nothing until a photo is recorded."""
        return self.worker.in_flight == 0 and self.counts()[PENDING] == 0

    def counts(self) -> dict[str, int]:
        """Photos in the outbox by state (all of them, this run's and earlier ones')."""
        return self.store.counts()

    def summary(self) -> dict[str, Any]:
        """What summary.json reports: this process's work and what the outbox holds now."""
        stats = self.worker.stats
        counts = self.counts()
        return {
            "photos_queued": self.recorded,
            "photos_uploaded": stats["uploaded"],
            "photos_pending": counts[PENDING],
            "photos_rejected": stats["rejected"],
            "photos_damaged": stats["damaged"],
            "already_in_gallery": stats["duplicates"],
            "attempts": stats["attempts"],
            "retries": stats["retries"],
            "resumed_from_earlier_runs": self.resumed,
            "outbox_totals": counts,
            "notes": list(self.store.notes),
        }

    def uploaded(self) -> int:
        return self.counts()[UPLOADED]

    def close(self, grace: float = 0.0) -> None:
        """Stop, after a last look for what is due; attempts still in flight after ``grace`` s
        leave their photos pending (the next process to open the outbox sends them)."""
        self.worker.stop()
        if grace > 0:
            self.worker.pump()
        self.worker.close(grace)
        self.client.close()
        self.store.close()

    def abandon(self) -> None:
        """Stop as a crash would: no answer is applied any more, whatever is in flight."""
        self.worker.close(0.0)
        self.client.close()
        self.store.close()

    def __enter__(self) -> Outbox:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
