"""The durable photo outbox behind the upload skill.

- ``store``: photos copied in and fsync'ed, their states in SQLite (survives crashes)
- ``client``: one HTTP upload attempt (httpx) and what its answer means
- ``worker``: sends pending photos with retries, exponential backoff and jitter, on any clock
- ``outbox``: the three behind one object
- ``service``: a run's outboxes, opened on first use (the ``uploads`` interface)
- ``settings``, ``images``: configuration; JPEG/PNG sniffing

Only ``settings`` loads on import: httpx is imported when an outbox first opens.
"""

from botstage.skills.outbox.settings import TOKEN_ENV, OutboxSettings

__all__ = ["TOKEN_ENV", "OutboxSettings"]
