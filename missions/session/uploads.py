"""A run's uploads, with the gallery the run starts when a mission names no endpoint.

The runner's whole upload hook: ``run_uploads`` gives the ``uploads`` interface. Nothing opens
or starts until an upload skill records its first photo; then, if its settings name no
endpoint, a gallery starts on a free loopback port serving ``gallery/`` in the run folder
(with the token of ``$BOTSTAGE_GALLERY_TOKEN`` if set), and the outbox opens in ``outbox/``.

The gallery server itself is the web set's (``botstage[web]``): its ``gallery`` run service gives
the function that starts one as the ``gallery_server`` interface, so the core never imports it.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from botstage.robots.clock import Clock
from botstage.skills.outbox.service import Uploads
from botstage.skills.outbox.settings import TOKEN_ENV

# names a mission may list under `counters:` and get from the outbox (when no skill writes them)
COUNTERS = ("photos_queued", "photos_uploaded", "photos_pending", "photos_rejected")


class RunGallery:
    """The gallery a run starts for itself; a scenario can take it down and bring it back (same
    port, same folder), to see that uploads wait and resume without losing or repeating a photo."""

    def __init__(self, folder: Path, start_gallery: Callable[..., Any]) -> None:
        self._start = start_gallery
        self.folder = folder
        self.token = os.environ.get(TOKEN_ENV) or None
        self._running = start_gallery(folder, token=self.token)
        self.port = self._running.port
        self.upload_url = self._running.upload_url

    @property
    def up(self) -> bool:
        return self._running is not None

    def down(self) -> None:
        if self._running is not None:
            self._running.stop()
            self._running = None

    def restart(self) -> None:
        if self._running is None:
            self._running = self._start(self.folder, port=self.port, token=self.token)

    def stop(self) -> None:
        self.down()


GALLERY_SERVER = "gallery_server"  # the interface the web set's `gallery` service gives


def run_uploads(folder: Path, clock: Clock, seed: int, interfaces: dict[str, Any]) -> Uploads:
    """The ``uploads`` interface; its own gallery starts through ``interfaces``' gallery server
    (looked up when the first photo needs it: every service has opened by then)."""

    def local_gallery() -> RunGallery:
        start = interfaces.get(GALLERY_SERVER)
        if start is None:
            raise LookupError(
                "the run's own gallery needs botstage's web set: pip install 'botstage[web]' "
                "(or name an endpoint: skill_params: {upload: {endpoint: URL}})"
            )
        return RunGallery(folder / "gallery", start)

    return Uploads(folder, clock, seed=seed, local_gallery=local_gallery)


def set_gallery(uploads: Uploads, up: bool) -> None:
    """Take the run's own gallery down or bring it back (started now if no photo started it yet)."""
    if uploads.gallery is None:
        uploads.start_local_gallery()
    gallery = uploads.gallery
    if not isinstance(gallery, RunGallery):
        raise TypeError("only the gallery a run starts for itself can be taken down")
    if up:
        gallery.restart()
    else:
        gallery.down()


def fill_counters(counters: dict[str, object], summary: dict[str, object]) -> None:
    """Counters the mission lists that nothing wrote take the outbox's figures."""
    for name in COUNTERS:
        if name in counters and counters[name] is None:
            counters[name] = summary[name]
