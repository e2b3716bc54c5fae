"""A run's uploads, with the gallery the run starts when a mission names no endpoint.

The runner's whole upload hook: ``run_uploads`` gives the ``uploads`` interface. Nothing opens
or starts until an upload skill records its first photo; then, if its settings name no
endpoint, a gallery starts on a free loopback port serving ``gallery/`` in the run folder
(with the token of ``$BOTSTAGE_GALLERY_TOKEN`` if set), and the outbox opens in ``outbox/``.
"""

from __future__ import annotations

import os
from pathlib import Path

from robots.clock import Clock
from skills.outbox.service import Uploads
from skills.outbox.settings import TOKEN_ENV

# names a mission may list under `counters:` and get from the outbox (when no skill writes them)
COUNTERS = ("photos_queued", "photos_uploaded", "photos_pending", "photos_rejected")


def run_uploads(folder: Path, clock: Clock, seed: int) -> Uploads:
    def local_gallery():  # imported here: FastAPI and uvicorn load only for a run that uploads
        from missions.gallery.server import start_gallery

        return start_gallery(folder / "gallery", token=os.environ.get(TOKEN_ENV) or None)

    return Uploads(folder, clock, seed=seed, local_gallery=local_gallery)


def fill_counters(counters: dict[str, object], summary: dict[str, object]) -> None:
    """Counters the mission lists that nothing wrote take the outbox's figures."""
    for name in COUNTERS:
        if name in counters and counters[name] is None:
            counters[name] = summary[name]
