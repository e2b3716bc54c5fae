"""A run's uploads: the outboxes its upload skills use, opened the first time one is needed.

The run puts an ``Uploads`` among the skills' interfaces (``ctx.interface("uploads")``) and
drives it: on a simulated clock it calls ``after_tick()`` once per tick (each outbox starts what
is due and waits for it, so answers land at the same tick every run); on a real-time clock each
outbox pumps on a thread of its own. Nodes whose settings name the same folder and endpoint
share one outbox. ``summary()`` is the ``upload`` block of summary.json.

When the settings give no endpoint, ``local_gallery`` (supplied by the run) starts a gallery for
the run and gives its URL; without one, such a skill fails with a reason.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from botstage.robots.clock import Clock
from botstage.skills.outbox.settings import OutboxSettings


class LocalGallery(Protocol):
    upload_url: str

    def stop(self) -> None: ...


class Uploads:
    def __init__(
        self,
        folder: str | Path,
        clock: Clock,
        *,
        seed: int = 0,
        local_gallery: Callable[[], LocalGallery] | None = None,
    ) -> None:
        self.folder = Path(folder)
        self.clock = clock
        self.seed = seed
        self._start_gallery = local_gallery
        self.gallery: LocalGallery | None = None
        self._outboxes: dict[tuple[Path, str], Any] = {}
        self._lock = threading.Lock()

    @property
    def used(self) -> bool:
        return bool(self._outboxes)

    def outbox(self, settings: OutboxSettings) -> Any:
        """The outbox for these settings, opened (and resumed) on first use. Blocking: opens files."""
        from botstage.skills.outbox.outbox import Outbox

        with self._lock:
            endpoint = settings.endpoint or self._local_endpoint()
            folder = (Path(settings.outbox) if settings.outbox else self.folder / "outbox").resolve()
            found = self._outboxes.get((folder, endpoint))
            if found is not None:
                return found
            for other_folder, other_endpoint in self._outboxes:
                if other_folder == folder:
                    raise ValueError(f"outbox {folder} already uploads to {other_endpoint}: give each endpoint its own")
            opened = Outbox(
                folder,
                endpoint,
                settings,
                now=self.clock.now,
                background=not self.clock.simulated,
                seed=self.seed,
            )
            self._outboxes[(folder, endpoint)] = opened
            return opened

    def _local_endpoint(self) -> str:
        return self.start_local_gallery().upload_url

    def start_local_gallery(self) -> LocalGallery:
        """The run's own gallery, started the first time it is needed."""
        if self.gallery is None:
            if self._start_gallery is None:
                raise LookupError("no gallery endpoint is configured (skill_params: {upload: {endpoint: URL}})")
            self.gallery = self._start_gallery()
        return self.gallery

    def after_tick(self) -> None:
        """On the simulated clock: each outbox starts what is due, and its answers are applied now."""
        if not self.clock.simulated:
            return
        with self._lock:
            outboxes = list(self._outboxes.values())
        for outbox in outboxes:
            outbox.step()

    def resting(self) -> bool:
        """Whether ``after_tick`` has nothing to do: off the simulated clock, or no outbox with photos to send."""
        if not self.clock.simulated:
            return True
        with self._lock:
            outboxes = list(self._outboxes.values())
        return all(outbox.idle() for outbox in outboxes)

    def summary(self) -> dict[str, Any]:
        """Counts summed over the run's outboxes, then each outbox's own figures."""
        from botstage.skills.outbox.client import redact

        with self._lock:
            outboxes = list(self._outboxes.items())
        each = []
        for (folder, endpoint), outbox in outboxes:
            local = self.gallery is not None and endpoint == self.gallery.upload_url
            base = self.folder.resolve()
            shown_folder = folder.relative_to(base) if folder.is_relative_to(base) else folder
            each.append(
                {
                    "folder": str(shown_folder),
                    "endpoint": "the run's own gallery (gallery/)" if local else redact(endpoint),
                    **outbox.summary(),
                }
            )
        total: dict[str, Any] = {}
        for key in ("photos_queued", "photos_uploaded", "photos_pending", "photos_rejected", "photos_damaged"):
            total[key] = sum(o[key] for o in each)
        return {**total, "outboxes": each}

    def close(self, grace: float = 5.0) -> None:
        """Close every outbox (in-flight attempts get ``grace`` s of wall time), then the gallery."""
        with self._lock:
            outboxes = list(self._outboxes.values())
        for outbox in outboxes:
            outbox.close(grace)
        if self.gallery is not None:
            self.gallery.stop()
